"""Error metrics of the paper and ours (forces in N, stresses as log-stress maps).

Force: MSE (N^2, the paper's metric), RMSE (N), NRMSE (% of the largest |true force|
of the set, so that sets of different force scales compare), R^2; of fx (along the
push, the headline), and of fy and the magnitude for a two-output model. Stress: MSE of the
log-stress inside the finger mask and SSIM (scikit-image) of the maps. Contact height:
RMSE and MAE (mm) over the frames pushed harder than a threshold.
"""

from __future__ import annotations

import numpy as np


def force_metrics(true_N, pred_N) -> dict:
    """MSE (N^2), RMSE (N), NRMSE (% of max |true|) and R^2 of force predictions."""
    t = np.asarray(true_N, dtype=float).ravel()
    p = np.asarray(pred_N, dtype=float).ravel()
    if t.shape != p.shape or t.size == 0:
        raise ValueError(f"need two equal, non-empty sets of forces, got {t.shape} and {p.shape}")
    err = p - t
    mse = float(np.mean(err**2))
    scale = float(np.max(np.abs(t)))
    ss_tot = float(np.sum((t - t.mean()) ** 2))
    return {
        "n": int(t.size),
        "mse_N2": mse,
        "rmse_N": float(np.sqrt(mse)),
        "nrmse_pct": float(100 * np.sqrt(mse) / scale) if scale > 0 else float("nan"),
        "r2": float(1 - np.sum(err**2) / ss_tot) if ss_tot > 0 else float("nan"),
        "max_abs_error_N": float(np.max(np.abs(err))),
        "max_true_N": scale,
    }


def force_vector_metrics(fx_true, fy_true, fx_pred, fy_pred) -> dict:
    """Metrics of the across-the-push component (``fy_*``) and of the magnitude
    ``|F| = sqrt(fx^2 + fy^2)`` (``mag_*``): MSE (N^2), RMSE (N), NRMSE (% of the
    largest |true| of the set), R^2, as :func:`force_metrics`."""
    fy = force_metrics(fy_true, fy_pred)
    mag = force_metrics(np.hypot(fx_true, fy_true), np.hypot(fx_pred, fy_pred))
    keys = ("mse_N2", "rmse_N", "nrmse_pct", "r2", "max_true_N")
    return {**{f"fy_{k}": fy[k] for k in keys}, **{f"mag_{k}": mag[k] for k in keys}}


#: N: contact heights are scored on frames pushed harder than this (at rest, and just
#: touching, the contact height is barely defined and barely matters)
CONTACT_MIN_FORCE_N = 0.5


def contact_metrics(true_mm, pred_mm, fx_N, min_force_N: float = CONTACT_MIN_FORCE_N) -> dict:
    """Contact-height errors over the frames with a true height and ``|fx_N| >
    min_force_N`` (N): ``rmse_mm``, ``mae_mm`` (NaN where there are none) and ``n``, the
    frames counted. Heights in mm (the finger's frame), one per frame."""
    t, p, f = (np.asarray(a, dtype=float).ravel() for a in (true_mm, pred_mm, fx_N))
    if not (t.shape == p.shape == f.shape):
        raise ValueError(
            f"need one height and one force per frame, got {t.shape}, {p.shape}, {f.shape}"
        )
    keep = np.isfinite(t) & (np.abs(f) > min_force_N)
    err = p[keep] - t[keep]
    n = int(keep.sum())
    return {
        "n": n,
        "rmse_mm": float(np.sqrt(np.mean(err**2))) if n else float("nan"),
        "mae_mm": float(np.mean(np.abs(err))) if n else float("nan"),
    }


def stress_metrics(true_maps, pred_maps, masks) -> dict:
    """Log-stress MSE inside the masks and mean SSIM over maps (N, H, W)."""
    from skimage.metrics import structural_similarity

    t = np.asarray(true_maps, dtype=float)
    p = np.asarray(pred_maps, dtype=float)
    m = np.asarray(masks, dtype=bool)
    if t.ndim == 2:
        t, p, m = t[None], p[None], m[None]
    if not (t.shape == p.shape == m.shape):
        raise ValueError(f"shapes differ: {t.shape}, {p.shape}, {m.shape}")
    inside = m.sum()
    mse = float(((t - p) ** 2)[m].mean()) if inside else float("nan")
    rng = float(max(t.max() - t.min(), 1e-12))
    ssim = [structural_similarity(a, b, data_range=rng) for a, b in zip(t, p)]
    return {"stress_mse_log": mse, "ssim": float(np.mean(ssim)), "n_maps": int(len(t))}
