"""The rig prior from the FEA: what a printed finger's gain against the simulation may be.

With no context frames a rig's gain is unknown (:class:`finray.sim2real.calibration.RigPrior`).
A print differs from the nominal model in its modulus, its wall thickness and its grip,
each within a published range (``evaluate.sim2real.rig_prior``; never from ``lab:``).
The modulus scales the force at a given push exactly (a hyperelastic finger pushed a
given distance: stresses and forces scale with the modulus). The walls and the friction
do not, so the FEA measures them: training scenes are simulated again with thicker walls
and with more friction (:func:`variants`), and each variant's force against the nominal
scene's over the push is its gain (:func:`force_gain`). :func:`rig_prior` draws
printed fingers from the ranges (log-uniform modulus, uniform walls and friction, a
scene at random), adds the log-gains (the effects taken as independent) and returns
their mean and standard deviation: the prior's log-normal gain.
"""

from __future__ import annotations

import numpy as np
import pandas as pd


def variants(spec: dict) -> dict[str, dict]:
    """The FEA variants of the nominal finger (name -> ``as_built``-like dict): walls
    thicker by the half and the whole of ``thickness_delta_mm``'s upper end (mm), and the
    friction at the low end, the middle and the high end of ``friction``."""
    t_hi = float(spec["thickness_delta_mm"][1])
    lo, hi = (float(v) for v in spec["friction"])
    out = {f"t{t:g}": {"thickness_delta_mm": t} for t in (t_hi / 2, t_hi) if t > 0}
    out |= {f"mu{m:g}": {"friction": m} for m in (lo, (lo + hi) / 2, hi)}
    return out


def force_gain(nominal: pd.DataFrame, variant: pd.DataFrame) -> float:
    """Least-squares gain of a variant's force against the nominal scene's, over the push
    (``displacement_mm``, ``fx_N``): the loaded frames weigh most."""
    fv = np.interp(nominal["displacement_mm"], variant["displacement_mm"], variant["fx_N"])
    fn = nominal["fx_N"].to_numpy()
    den = float(np.sum(fn * fn))
    if den <= 0:
        raise ValueError("the nominal scene has no force to compare against")
    return float(np.sum(fv * fn) / den)


def _log_gain_curve(points: dict[float, float], x: np.ndarray) -> np.ndarray:
    """Piecewise-linear log-gain at ``x`` through ``points`` (value -> log-gain)."""
    xs = np.array(sorted(points))
    return np.interp(x, xs, [points[v] for v in xs])


def rig_prior(gains: dict[str, dict[str, float]], spec: dict, nominal_friction: float) -> dict:
    """The prior's log-gain mean and sd from each scene's variant gains (scene -> variant
    name -> gain, as :func:`variants` names them) and the ranges of ``spec``
    (``youngs_modulus_scale``, ``thickness_delta_mm``, ``friction``; ``draws``,
    ``seed``). Walls thinner than nominal mirror the thicker ones' log-gain."""
    rng = np.random.default_rng(int(spec.get("seed", 0)))
    n = int(spec.get("draws", 100000))
    e_lo, e_hi = (float(v) for v in spec["youngs_modulus_scale"])
    t_lo, t_hi = (float(v) for v in spec["thickness_delta_mm"])
    m_lo, m_hi = (float(v) for v in spec["friction"])
    scenes = sorted(gains)
    if not scenes:
        raise ValueError("the rig prior needs at least one scene's variant gains")
    names = variants(spec)
    log_e = rng.uniform(np.log(e_lo), np.log(e_hi), n)
    dt = rng.uniform(t_lo, t_hi, n)
    mu = rng.uniform(m_lo, m_hi, n)
    which = rng.integers(len(scenes), size=n)
    total = log_e.copy()
    per_scene = {}
    for i, scene in enumerate(scenes):
        g = gains[scene]
        t_pts = {0.0: 0.0} | {
            v["thickness_delta_mm"]: float(np.log(g[k]))
            for k, v in names.items()
            if "thickness_delta_mm" in v
        }
        t_pts |= {-t: -lg for t, lg in list(t_pts.items()) if t > 0}
        m_pts = {v["friction"]: float(np.log(g[k])) for k, v in names.items() if "friction" in v}
        m_pts.setdefault(float(nominal_friction), 0.0)
        sel = which == i
        total[sel] += _log_gain_curve(t_pts, dt[sel]) + _log_gain_curve(m_pts, mu[sel])
        per_scene[scene] = {
            "log_gain_walls": {f"{k:g}": v for k, v in sorted(t_pts.items())},
            "log_gain_friction": {f"{k:g}": v for k, v in sorted(m_pts.items())},
        }
    return {
        "gain_log_mean": float(total.mean()),
        "gain_log_sd": float(total.std()),
        "gain_q5": float(np.exp(np.percentile(total, 5))),
        "gain_q95": float(np.exp(np.percentile(total, 95))),
        "draws": n,
        "ranges": {
            "youngs_modulus_scale": [e_lo, e_hi],
            "thickness_delta_mm": [t_lo, t_hi],
            "friction": [m_lo, m_hi],
        },
        "nominal_friction": float(nominal_friction),
        "gains": gains,
        "scenes": per_scene,
    }
