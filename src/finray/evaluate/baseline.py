"""Classical baseline: ridge regression from the front-edge deflection profile to force.

The finger's front face is the left edge of the silhouette (the object pushes in +x).
Its position in each row of the network's input is read off the same segmented,
area-averaged silhouette the network sees, to sub-pixel precision:

    e[r] = sum_c (1 - max_{c' <= c} x[r, c'])   (px of background left of the finger)

A linear ridge model on the standardised profile, its penalty chosen by
cross-validation over whole scenes, maps the profile to the force (N). Across
objects at one height the force-displacement curves are close, so this simple model
already does well on clean images: the comparison shows what the CNN adds.
"""

from __future__ import annotations

from dataclasses import dataclass
from pathlib import Path

import numpy as np


def front_edge_profile(images: np.ndarray) -> np.ndarray:
    """Front-edge position per row (px from the left border), images (N, H, W) in [0, 1]."""
    x = np.asarray(images, dtype=np.float32)
    if x.ndim == 4:
        x = x[:, 0]
    return (1.0 - np.maximum.accumulate(np.clip(x, 0.0, 1.0), axis=2)).sum(axis=2)


@dataclass
class RidgeBaseline:
    """Linear ridge model on standardised features; force in N."""

    mean: np.ndarray
    scale: np.ndarray
    coef: np.ndarray
    intercept: float
    alpha: float

    def predict(self, features: np.ndarray) -> np.ndarray:
        return ((features - self.mean) / self.scale) @ self.coef + self.intercept

    def predict_images(self, images: np.ndarray) -> np.ndarray:
        return self.predict(front_edge_profile(images))

    def save(self, path: str | Path) -> None:
        np.savez(
            path,
            mean=self.mean,
            scale=self.scale,
            coef=self.coef,
            intercept=self.intercept,
            alpha=self.alpha,
        )

    @classmethod
    def load(cls, path: str | Path) -> "RidgeBaseline":
        with np.load(path) as f:
            return cls(f["mean"], f["scale"], f["coef"], float(f["intercept"]), float(f["alpha"]))


def _solve(z: np.ndarray, y: np.ndarray, alpha: float) -> tuple[np.ndarray, float]:
    """Ridge on standardised features z (N, P): coefficients and intercept."""
    ym = y.mean()
    zm = z.mean(0)
    zc = z - zm
    coef = np.linalg.solve(zc.T @ zc + alpha * np.eye(z.shape[1]), zc.T @ (y - ym))
    return coef, float(ym - zm @ coef)


def fit_ridge(
    features: np.ndarray,
    force_N: np.ndarray,
    groups: np.ndarray,
    alphas=(1e-2, 1e-1, 1.0, 10.0, 100.0, 1e3, 1e4),
    n_folds: int = 5,
    seed: int = 0,
) -> tuple[RidgeBaseline, dict]:
    """Fit with the penalty of least cross-validated MSE (folds of whole scenes,
    ``groups``: one label per frame); returns the model and the CV errors (N^2)."""
    f = np.asarray(features, dtype=np.float64)
    y = np.asarray(force_N, dtype=np.float64).ravel()
    mean = f.mean(0)
    scale = f.std(0)
    scale[scale < 1e-9] = 1.0  # rows the finger never reaches: constant features
    z = (f - mean) / scale
    ids = np.unique(groups)
    fold_of = dict(
        zip(
            np.random.default_rng(seed).permutation(ids),
            np.arange(len(ids)) % max(2, min(n_folds, len(ids))),
        )
    )
    fold = np.array([fold_of[g] for g in groups])
    cv = {}
    for a in alphas:
        err = []
        for k in np.unique(fold):
            tr, te = fold != k, fold == k
            coef, b = _solve(z[tr], y[tr], a)
            err.append(((z[te] @ coef + b - y[te]) ** 2).sum())
        cv[float(a)] = float(np.sum(err) / len(y))
    best = min(cv, key=cv.get)
    coef, b = _solve(z, y, best)
    return RidgeBaseline(mean, scale, coef, b, best), {"cv_mse_N2": cv, "alpha": best}
