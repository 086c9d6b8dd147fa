"""The rig prior's gain from the FEA (finray.sim2real.rig_prior): variants, force gains,
and the prior's log-gain mean and sd against their closed forms."""

import numpy as np
import pandas as pd
import pytest

from finray.sim2real.rig_prior import force_gain, rig_prior, variants

SPEC = {
    "youngs_modulus_scale": [0.5, 1.0],
    "thickness_delta_mm": [0.0, 0.2],
    "friction": [0.3, 0.6],
    "draws": 400000,
    "seed": 1,
}


def test_variants_span_the_ranges():
    v = variants(SPEC)
    assert list(v) == ["t0.1", "t0.2", "mu0.3", "mu0.45", "mu0.6"]
    assert [x.get("thickness_delta_mm", x.get("friction")) for x in v.values()] == pytest.approx(
        [0.1, 0.2, 0.3, 0.45, 0.6]
    )


def test_force_gain_is_the_least_squares_ratio_over_the_push():
    nominal = pd.DataFrame({"displacement_mm": np.arange(0, 10.5, 0.5)})
    nominal["fx_N"] = 0.05 * nominal["displacement_mm"] ** 2
    # the variant's frames on another grid: interpolated onto the nominal's
    variant = pd.DataFrame({"displacement_mm": np.arange(0, 10.25, 0.25)})
    variant["fx_N"] = 1.3 * 0.05 * variant["displacement_mm"] ** 2
    assert force_gain(nominal, variant) == pytest.approx(1.3, rel=1e-3)
    with pytest.raises(ValueError, match="no force"):
        force_gain(nominal.assign(fx_N=0.0), variant)


def test_prior_matches_the_closed_form_of_linear_effects():
    """Log-gains linear in the walls (2/mm) and the friction (0.5 per unit, zero at the
    nominal 0.15): the mean and sd of log E + 2 dt + 0.5 (mu - 0.15) with log E uniform on
    [log 0.5, 0], dt on [0, 0.2], mu on [0.3, 0.6]."""
    g = {f"t{t:g}": np.exp(2 * t) for t in (0.1, 0.2)} | {
        f"mu{m:g}": np.exp(0.5 * (m - 0.15)) for m in (0.3, 0.45, 0.6)
    }
    prior = rig_prior({"a_h20": g, "b_h30": g}, SPEC, nominal_friction=0.15)
    a = np.log(0.5)
    mean = a / 2 + 2 * 0.1 + 0.5 * (0.45 - 0.15)
    sd = np.sqrt(a**2 / 12 + (2 * 0.2) ** 2 / 12 + (0.5 * 0.3) ** 2 / 12)
    assert prior["gain_log_mean"] == pytest.approx(mean, abs=2e-3)
    assert prior["gain_log_sd"] == pytest.approx(sd, rel=1e-2)
    assert prior["gain_q5"] < np.exp(mean) < prior["gain_q95"]
    # thinner walls mirror thicker ones
    sym = rig_prior({"a_h20": g}, SPEC | {"thickness_delta_mm": [-0.2, 0.2]}, nominal_friction=0.15)
    assert sym["gain_log_mean"] == pytest.approx(a / 2 + 0.5 * 0.3, abs=2e-3)
    with pytest.raises(ValueError, match="at least one scene"):
        rig_prior({}, SPEC, 0.15)
