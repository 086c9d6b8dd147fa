"""The calibration of a print's time dependence: a synthetic take of a known Prony kernel
and softening is recovered, an elastic print's gives no relaxation, frame-by-frame
prediction (finray predict --calibration) follows the batch one, and the phases of a take."""

import json
from dataclasses import replace

import numpy as np
import pytest

from finray.emulator.motion import GripperMotion
from finray.sim2real.calibration import (
    PARAMS,
    CalibratedStream,
    CalibrationError,
    History,
    Priors,
    coverage,
    fit_calibration,
    predictive,
    read_calibration,
    time_point_fit,
)
from finray.sim2real.phases import take_phases
from finray.viscoelastic import relax

#: a print of two Prony terms at the calibration's fixed times (0.5 and 5 s)
TRUE = {"fractions": (0.12, 0.08), "times_s": (0.5, 5.0), "softening": 0.15}
#: one term between them, at a time the calibration does not have
OFF_GRID = {"fractions": (0.2,), "times_s": (0.8,), "softening": 0.15}
FPS = 30.0


def takes(law: dict | None, seed: int):
    """Three takes of the paper's motion at 5, 12 and 20 N: the network's elastic force
    mu (its error growing with the force), its spread s, the sensor's log y of a print
    of ``law`` (None: elastic), and the frames' history."""
    rng = np.random.default_rng(seed)
    m = GripperMotion(push_mm=1.0, speed_mm_s=1.0, hold_s=1.0, starts_s=(1.0, 5.5), duration_s=10.0)
    t = np.arange(0, 10.0, 1 / FPS)
    fe = np.concatenate([a * m.push(t) ** 1.5 for a in (5.0, 12.0, 20.0)])
    tt, seg = np.tile(t, 3), np.repeat([0, 1, 2], len(t))
    s = 0.02 + 0.02 * fe * rng.uniform(0.5, 1.5, len(fe))
    mu = fe + s * rng.standard_normal(len(fe))
    f = (
        fe
        if law is None
        else relax(tt, fe, [law["fractions"]], [law["times_s"]], [law["softening"]], seg)[0]
    )
    return mu, s, f + 0.03 * rng.standard_normal(len(fe)), History(tt, seg)


def calibrate(mu, s, y, history):
    priors = Priors()
    point = time_point_fit(mu, y, history, priors)
    start = (point["relax_fast"], point["relax_slow"], point["softening"])
    h = replace(history, base_N=point["rest_N"], start=start)
    return fit_calibration(mu, s, y, priors, log=lambda m: None, history=h), h


@pytest.fixture(scope="module")
def fitted():
    mu, s, y, history = takes(TRUE, 0)
    cal, h = calibrate(mu, s, y, history)
    return cal, h, (mu, s, y)


def test_recovers_a_known_relaxation_and_softening(fitted):
    """The kernel's fractions at its times and the softening within +-0.03, the chain
    converged, and the intervals cover ~90 % of new takes' frames."""
    cal, h, _ = fitted
    q = cal["summary"]
    assert tuple(cal["priors"]["relax_times_s"]) == TRUE["times_s"]
    assert q["relax_fast"]["median"] == pytest.approx(TRUE["fractions"][0], abs=0.03)
    assert q["relax_slow"]["median"] == pytest.approx(TRUE["fractions"][1], abs=0.03)
    assert q["softening"]["median"] == pytest.approx(TRUE["softening"], abs=0.03)
    assert cal["diagnostics"]["ok"] and set(cal["diagnostics"]["tau_steps"]) == set(PARAMS[2:])
    mu, s, y, history = takes(TRUE, 1)
    band = predictive(cal, mu, s, 0.9, history=history)
    assert 0.85 <= coverage(y, band) <= 0.95
    # read static, the same frames' intervals miss the relaxed ones
    assert coverage(y, predictive(cal, mu, s, 0.9)) < 0.8


def relaxation_function(fractions, times_s, t):
    """G(t) = 1 - sum_i g_i (1 - exp(-t / tau_i)) of a Prony series."""
    g, tau = np.asarray(fractions)[:, None], np.asarray(times_s)[:, None]
    return 1 - np.sum(g * (1 - np.exp(-t / tau)), axis=0)


def test_a_kernel_off_the_fixed_times_is_met_over_the_hold():
    """One term at 0.8 s (between the calibration's 0.5 and 5 s): the fitted relaxation
    function is the true one within 0.04 over the first 2 s (the 1 s hold and as long
    again), and the intervals cover 85-95 % of new takes' frames. The softening is not
    asserted: off the fixed times the slow term takes part of it (0.03-0.04 fitted of
    0.15, the slow fraction 0.06 of none; studies/print_time/README.md)."""
    mu, s, y, history = takes(OFF_GRID, 4)
    cal, _ = calibrate(mu, s, y, history)
    q, t = cal["summary"], np.linspace(0, 2.0, 21)
    fitted = relaxation_function(
        [q["relax_fast"]["median"], q["relax_slow"]["median"]], cal["priors"]["relax_times_s"], t
    )
    true = relaxation_function(OFF_GRID["fractions"], OFF_GRID["times_s"], t)
    assert np.abs(fitted - true).max() < 0.04
    mu, s, y, history = takes(OFF_GRID, 7)
    assert 0.85 <= coverage(y, predictive(cal, mu, s, 0.9, history=history)) <= 0.95


def test_the_bilinear_law_is_the_print_law():
    """History.law (the fit's basis histories) is finray.viscoelastic.relax itself."""
    mu, _, _, history = takes(None, 5)
    h = replace(history, base_N=0.3)
    rows = np.array([[0.1, 0.05], [0.0, 0.3], [0.25, 0.0]])
    soft = np.array([0.2, 0.0, 0.4])
    got = h.law(mu, rows, soft, (0.5, 5.0))
    want = 0.3 + relax(h.t_s, mu - 0.3, rows, np.tile([0.5, 5.0], (3, 1)), soft, h.segments)
    np.testing.assert_allclose(got, want, rtol=1e-12, atol=1e-12)


def test_an_elastic_print_gives_no_relaxation():
    mu, s, y, history = takes(None, 2)
    cal, _ = calibrate(mu, s, y, history)
    q = cal["summary"]
    assert q["relax"]["q95"] < 0.03 and q["softening"]["q95"] < 0.03


def test_frame_by_frame_follows_the_batch_prediction(fitted, tmp_path):
    """finray predict applies the calibration causally, one frame at a time: its medians
    are the batch ones (to the posterior draws' noise); a frame time not after the last
    starts a new history, as a new video."""
    cal, h, (mu, s, y) = fitted
    path = tmp_path / "calibration.json"
    path.write_text(json.dumps(cal))
    cal = read_calibration(path)
    n = 300  # the first take
    batch = predictive(cal, mu[:n], s[:n], 0.9, history=History(h.t_s[:n], h.segments[:n]))
    stream = CalibratedStream(cal)
    med = np.array([stream.step(t, m, v)["median"] for t, m, v in zip(h.t_s[:n], mu[:n], s[:n])])
    assert np.abs(med - batch["median"]).max() < 0.05
    again = [stream.step(t, m, v)["median"] for t, m, v in zip(h.t_s[:n], mu[:n], s[:n])]
    assert np.abs(np.array(again) - batch["median"]).max() < 0.05


def test_a_static_calibration_reads_as_before(tmp_path):
    """A calibration of the static model's six parameters (written before the print's
    law) reads with the law elastic; a law out of its range is refused in one line."""
    rng = np.random.default_rng(3)
    cal = {"posterior": {"samples": (rng.normal(0, 0.01, (50, 6)) + [1, 0, -2, -3, 0, 3]).tolist()}}
    path = tmp_path / "old.json"
    path.write_text(json.dumps(cal))
    stream = CalibratedStream(read_calibration(path))
    assert not stream.timed
    assert stream.step(0.0, 2.0, 0.01)["median"] == pytest.approx(2.0, abs=0.05)
    bad = np.column_stack(
        [np.asarray(cal["posterior"]["samples"]), np.full((50, 3), [0.6, 0.5, 0])]
    )
    path.write_text(json.dumps({"posterior": {"samples": bad.tolist()}}))
    with pytest.raises(CalibrationError, match="relaxed fractions"):
        read_calibration(path)
    # a calibration of another layout (one free relaxation time) is refused, not misread
    named = {
        "posterior": {
            "names": [*PARAMS[:6], "relax", "log_tau_s", "softening"],
            "samples": np.abs(bad * 0.1).tolist(),
        }
    }
    path.write_text(json.dumps(named))
    with pytest.raises(CalibrationError, match="run finray calibrate again"):
        read_calibration(path)


def test_history_needs_each_take_in_time_order():
    with pytest.raises(CalibrationError, match="not increasing"):
        History(np.array([0.0, 0.2, 0.1]), np.array(["a", "a", "a"]))
    History(np.array([0.0, 0.2, 0.1]), np.array(["a", "a", "b"]))  # a new take starts again


def test_the_phases_of_a_take():
    m = GripperMotion(
        push_mm=10.0, speed_mm_s=10.0, hold_s=1.0, starts_s=(1.0, 5.5), duration_s=10.0
    )
    t = np.arange(0, 10.0, 1 / FPS)
    ph = take_phases(m.push(t))

    def at(s):
        return ph[int(round(s * FPS))]

    assert [at(s) for s in (0.5, 1.5, 2.5, 3.5, 4.5, 6.0, 7.0, 9.5)] == [
        "rest",
        "loading",
        "hold",
        "unloading",
        "rest",
        "second cycle",
        "second cycle",
        "rest",
    ]
