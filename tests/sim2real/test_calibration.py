"""The emcee force calibration: recovery of known parameters, predictive intervals,
its convergence diagnostics, cross-fitting labels and one-line errors."""

import json

import numpy as np
import pandas as pd
import pytest

from finray.sim2real.calibration import (
    PARAMS,
    CalibrationError,
    Priors,
    RigPrior,
    Sampler,
    coverage,
    fit_calibration,
    fold_units,
    log_posterior,
    predictive,
    read_calibration,
)

FREE = Priors(gain_log_sd=0.5, offset_sd_N=1.0)  # gain and offset sampled
TRUE = {"gain": 1.3, "offset_N": 0.2, "sigma_N": 0.08, "rho": 0.04, "kappa": 1.5}


def synthetic(n, seed):
    """Frames of the sensor model with TRUE: network mean mu (N), spread s (N), sensor y."""
    rng = np.random.default_rng(seed)
    mu = 4 * np.abs(rng.normal(0, 1, n))
    s = np.exp(rng.uniform(np.log(0.005), np.log(0.5), n))
    t = TRUE
    sd = np.sqrt(
        t["sigma_N"] ** 2 + (t["rho"] * t["gain"] * mu) ** 2 + (t["kappa"] * t["gain"] * s) ** 2
    )
    return mu, s, t["gain"] * mu + t["offset_N"] + sd * rng.standard_normal(n)


@pytest.fixture(scope="module")
def fitted():
    # one seeded draw: each 95 % interval misses its true value in 1 draw of 20 on average
    # (over seeds 10-29 the maximum-likelihood kappa averages 1.48 +- 0.08: unbiased)
    mu, s, y = synthetic(600, 4)
    return fit_calibration(mu, s, y, FREE, log=lambda m: None)


def test_recovers_known_gain_offset_and_noise(fitted):
    """Each true value lies inside its 95 % credible interval."""
    for name, value in TRUE.items():
        q = fitted["summary"][name]
        assert q["q2.5"] < value < q["q97.5"], (name, value, q)


@pytest.mark.slow
def test_heavy_tailed_noise_gives_few_degrees_of_freedom():
    """Student-t(3) noise of known scale: the posterior puts nu far below a normal law's
    (its 97.5 % quantile under 20, the prior's mean), gain and scale inside their 95 %
    intervals."""
    rng = np.random.default_rng(7)
    mu, s = 4 * np.abs(rng.normal(0, 1, 600)), np.full(600, 1e-3)
    y = 1.1 * mu - 0.1 + 0.05 * rng.standard_t(3, 600)
    # 20 autocorrelation times, not the default 50: the default chain runs to its
    # 20,000-step cap on this noise (50 CPU-s), its sigma's lower tail mixing slowly,
    # and gives the same nu and gain quantiles as this one's 1,000 steps
    q = fit_calibration(
        mu,
        s,
        y,
        Priors(gain_log_sd=0.5, offset_sd_N=1.0, rho=(1e-4, 1.0)),
        Sampler(min_tau_multiple=20.0),
        log=lambda m: None,
    )["summary"]
    assert 2 <= q["nu"]["median"] < 6 and q["nu"]["q97.5"] < 20
    assert q["gain"]["q2.5"] < 1.1 < q["gain"]["q97.5"]
    assert q["sigma_N"]["q2.5"] < 0.05 < q["sigma_N"]["q97.5"]


def test_diagnostics_are_written_and_hold(fitted):
    d = fitted["diagnostics"]
    assert set(d["tau_steps"]) == set(PARAMS[:6])  # the static model: the law fixed
    assert d["steps"] >= 50 * max(d["tau_steps"].values())
    assert 0.2 <= d["acceptance_fraction"]["mean"] <= 0.5
    assert d["ok"] is True
    assert np.asarray(fitted["posterior"]["samples"]).shape == (d["n_samples"], len(PARAMS))


def test_predictive_interval_covers_new_frames(fitted):
    """Fresh frames of the same model fall inside the 90 % interval about 90 % of the time."""
    mu, s, y = synthetic(4000, 2)
    band = predictive(fitted, mu, s, 0.9)
    assert 0.87 <= coverage(y, band) <= 0.93
    assert np.all(band["lo"] <= band["median"]) and np.all(band["median"] <= band["hi"])


@pytest.mark.slow
def test_rig_prior_covers_rigs_of_unknown_gain(fitted):
    """Rigs whose gain and offset differ from the calibrated one's by draws of the rig
    prior: the intervals without it cover far too few of their frames, with it about
    90 %; a zero prior leaves the intervals as they were."""
    prior = RigPrior(gain_log_sd=0.2, offset_sd_N=0.1)
    rng = np.random.default_rng(5)
    ys, mus, ss = [], [], []
    for _ in range(60):  # 60 rigs of 200 frames
        mu, s, y = synthetic(200, int(rng.integers(1 << 30)))
        g, b = (
            np.exp(prior.gain_log_sd * rng.standard_normal()),
            prior.offset_sd_N * rng.standard_normal(),
        )
        ys.append(g * (y - TRUE["offset_N"]) + TRUE["offset_N"] + b)
        mus.append(mu), ss.append(s)
    y, mu, s = (np.concatenate(a) for a in (ys, mus, ss))
    assert coverage(y, predictive(fitted, mu, s, 0.9)) < 0.6
    assert 0.85 <= coverage(y, predictive(fitted, mu, s, 0.9, rig=prior)) <= 0.95
    same = predictive(fitted, mu[:50], s[:50], 0.9, seed=3)
    zero = predictive(fitted, mu[:50], s[:50], 0.9, seed=3, rig=RigPrior())
    np.testing.assert_array_equal(same["hi"], zero["hi"])


def test_log_posterior_is_minus_infinity_outside_the_priors():
    mu, s, y = synthetic(20, 3)
    p = FREE
    inside = [1.0, 0.0, np.log(0.1), np.log(0.05), 0.0, np.log(10.0), 0.0, 0.0, 0.0]
    rows = np.array(
        [
            inside,
            [-1.0, *inside[1:]],  # negative gain
            [*inside[:2], np.log(p.sigma_N[1]) + 1, *inside[3:]],  # sigma above its bound
            [*inside[:4], np.log(p.kappa[0]) - 1, *inside[5:]],  # kappa below its bound
            [*inside[:5], np.log(p.nu[0]) - 0.1, *inside[6:]],
        ]
    )  # nu below its bound
    lp = log_posterior(rows, mu, s, y, p)
    assert np.isfinite(lp[0]) and np.all(np.isneginf(lp[1:]))


def test_too_few_frames_is_an_error():
    with pytest.raises(CalibrationError, match="too few frames"):
        fit_calibration([1.0] * 5, [0.1] * 5, [1.0] * 5)


def test_fold_units():
    t = pd.DataFrame({"take": ["a"] * 4 + ["b"] * 4, "t_s": [0, 1, 2, 3] * 2})
    take, half = fold_units(t, "both")
    assert list(take) == list(t["take"])
    assert list(half) == ["1st half"] * 2 + ["2nd half"] * 2 + ["1st half"] * 2 + ["2nd half"] * 2
    assert len(fold_units(t, "take")) == 1 and len(fold_units(t, "half")) == 1
    assert [list(u) for u in fold_units(t[t["take"] == "a"], "take")] == [
        list(half[:4])
    ]  # one take: halves
    with pytest.raises(ValueError, match="object, take, half, both"):
        fold_units(t, "objects")
    with pytest.raises(ValueError, match="an 'object' column"):
        fold_units(t, "object")
    # object folds: each object out with all its takes; one object: as "take"
    t = t.assign(object=["cyl"] * 4 + ["cube"] * 4)
    [obj] = fold_units(t, "object")
    assert list(obj) == list(t["object"])
    one = t.assign(object="cyl")
    assert [list(u) for u in fold_units(one, "object")] == [list(t["take"])]
    assert [list(u) for u in fold_units(one[one["take"] == "a"], "object")] == [list(half[:4])]


def test_read_calibration_errors(tmp_path):
    with pytest.raises(CalibrationError, match="no calibration at"):
        read_calibration(tmp_path / "missing.json")
    bad = tmp_path / "bad.json"
    bad.write_text("{not json")
    with pytest.raises(CalibrationError, match="is not JSON"):
        read_calibration(bad)
    bad.write_text(json.dumps({"posterior": {"samples": [[1, 2]]}}))
    with pytest.raises(CalibrationError, match="no posterior samples"):
        read_calibration(bad)


def test_gain_and_offset_of_prior_sd_zero_are_fixed():
    """A model already fitted to the sensor: gain and offset held at 1 and 0 N, the noise
    terms sampled alone (sigma inside its 95 % interval), their intervals covering ~90 %
    of fresh frames; the corner plot shows the free parameters only."""
    import matplotlib.pyplot as plt

    from finray.sim2real.calibration import corner_figure, fixed_params

    rng = np.random.default_rng(11)
    mu = 4 * np.abs(rng.normal(0, 1, 1600))
    s = np.full(1600, 1e-3)
    y = mu + 0.1 * rng.standard_normal(1600)
    priors = Priors(rho=(1e-4, 1.0))  # by default gain and offset are fixed
    # the print's law (two fractions, softening) is fixed where frames have no history
    law = {6: 0.0, 7: 0.0, 8: 0.0}
    assert fixed_params(priors) == {0: 1.0, 1: 0.0, **law} and fixed_params(FREE) == law
    assert fixed_params(FREE, timed=True) == {}
    cal = fit_calibration(mu[:600], s[:600], y[:600], priors, log=lambda m: None)
    samples = np.asarray(cal["posterior"]["samples"])
    assert np.all(samples[:, 0] == 1.0) and np.all(samples[:, 1] == 0.0)
    assert cal["fixed"] == {
        "gain": 1.0,
        "offset_N": 0.0,
        "relax_fast": 0.0,
        "relax_slow": 0.0,
        "softening": 0.0,
    }
    assert set(cal["diagnostics"]["tau_steps"]) == set(PARAMS[2:6]) and cal["diagnostics"]["ok"]
    assert cal["summary"]["sigma_N"]["q2.5"] < 0.1 < cal["summary"]["sigma_N"]["q97.5"]
    assert 0.87 <= coverage(y[600:], predictive(cal, mu[600:], s[600:], 0.9)) <= 0.93
    fig = corner_figure(cal)
    assert len(fig.axes) == 4 * 4
    plt.close(fig)
