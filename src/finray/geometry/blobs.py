"""Seeded smooth random polygons ("blobs") for studies beyond the paper's objects (mm).

A blob is a star-shaped closed curve around its reference point (the origin),

    r(theta) = R (1 + sum_k a_k cos(k theta + phi_k)),  k = 2 .. harmonics + 1,

with amplitudes a_k = s u_k / sqrt(k) (u_k uniform in [0, 1], phases uniform) and a
roughness s = amplitude v^2 per blob (v uniform in [0, 1]: leaning to the smooth side, so
that convex blobs stay common): smooth ones stay convex, rough ones get concave lobes (a harmonic k bends
the curve inwards once a_k > 1 / (k^2 + 2)). At the default amplitude 0.4, ~60 % are
concave, ~25 % with a solidity (area / convex hull area) below 0.95. The radius never
falls below 40 % of R, so the curve is simple (one radius per angle). The curve is scaled
so that its largest extent (Feret diameter) is ``diameter_mm``. Everything follows from
the seed: the same seed gives the same outline on every machine (numpy's PCG64).
"""

from __future__ import annotations

import numpy as np

from .finger import GeometryError
from ..schema import schema_default

#: smallest radius as a fraction of the mean one (keeps the curve star-shaped and simple)
MIN_RADIUS_FRAC = 0.4
#: largest ``amplitude`` accepted (beyond it the clipping to MIN_RADIUS_FRAC dominates)
MAX_AMPLITUDE = 0.6
_FINE = 1024  # samples of the analytic curve before resampling by arc length


def blob_name(seed: int) -> str:
    """The generated object's name: ``blob_s017`` for seed 17."""
    return f"blob_s{seed:03d}"


def blob_diameter(seed: int, size_mm) -> float:
    """The blob's Feret diameter (mm), drawn from ``size_mm`` = [min, max] by its seed
    (a stream of its own, so that the size does not shift the shape), to 0.01 mm."""
    lo, hi = size_mm
    u = np.random.default_rng([seed, 1]).uniform()
    return round(float(lo + (hi - lo) * u), 2)


def _check(seed, diameter_mm, harmonics, amplitude, key):
    if not isinstance(seed, (int, np.integer)) or isinstance(seed, bool) or seed < 0:
        raise GeometryError(f"{key}.seed", f"must be an integer >= 0, got {seed!r}")
    if not np.isfinite(diameter_mm) or diameter_mm <= 0:
        raise GeometryError(f"{key}.diameter_mm", f"must be > 0 mm, got {diameter_mm}")
    if not isinstance(harmonics, (int, np.integer)) or not 1 <= harmonics <= 16:
        raise GeometryError(f"{key}.harmonics", f"must be an integer in [1, 16], got {harmonics!r}")
    if not 0 <= amplitude <= MAX_AMPLITUDE:
        raise GeometryError(f"{key}.amplitude", f"must be in [0, {MAX_AMPLITUDE}], got {amplitude}")


def blob_outline(
    seed: int,
    diameter_mm: float,
    harmonics: int = schema_default("generated.harmonics"),
    amplitude: float = schema_default("generated.amplitude"),
    max_chord_mm: float = 0.5,
    key: str = "object",
) -> np.ndarray:
    """Counter-clockwise vertices (K, 2) of the blob, first != last, in mm around the
    origin; chords of at most ``max_chord_mm`` (evenly spaced in arc length).
    :class:`GeometryError` (one line, naming ``key``) on bad parameters."""
    _check(seed, diameter_mm, harmonics, amplitude, key)
    if not max_chord_mm > 0:
        raise GeometryError(f"{key}.max_chord_mm", f"must be > 0 mm, got {max_chord_mm}")
    rng = np.random.default_rng([seed, 0])
    k = np.arange(2, harmonics + 2)
    s = amplitude * rng.uniform() ** 2
    a = s * rng.uniform(size=harmonics) / np.sqrt(k)
    phi = rng.uniform(0.0, 2 * np.pi, size=harmonics)
    th = 2 * np.pi * np.arange(_FINE) / _FINE
    wave = (a[:, None] * np.cos(k[:, None] * th + phi[:, None])).sum(0)
    low = wave.min()
    if low < MIN_RADIUS_FRAC - 1:  # too deep a dent: scale the waves back
        wave *= (MIN_RADIUS_FRAC - 1) / low
    r = 1.0 + wave
    pts = np.column_stack([r * np.cos(th), r * np.sin(th)])
    pts *= diameter_mm / _width(pts)
    # resample by arc length: chords <= max_chord_mm, at least 32 vertices
    closed = np.vstack([pts, pts[:1]])
    arc = np.concatenate([[0.0], np.cumsum(np.linalg.norm(np.diff(closed, axis=0), axis=1))])
    n = max(32, int(np.ceil(arc[-1] / (0.99 * max_chord_mm))))  # (margin: the rescaling)
    t = arc[-1] * np.arange(n) / n
    out = np.column_stack([np.interp(t, arc, closed[:, 0]), np.interp(t, arc, closed[:, 1])])
    return out * (diameter_mm / feret_diameter(out))  # of the vertices that are meshed


def feret_diameter(pts: np.ndarray) -> float:
    """Largest distance between two of the points (mm), over their convex hull."""
    import shapely

    hull = np.asarray(shapely.convex_hull(shapely.multipoints(pts)).exterior.coords)
    return float(np.sqrt(((hull[:, None, :] - hull[None, :, :]) ** 2).sum(-1)).max())


def _width(pts: np.ndarray, directions: int = 64) -> float:
    """Approximate largest extent (mm, at most ~3e-4 low): projections on ``directions``
    directions; sizes the chords before the exact scaling."""
    th = np.pi * np.arange(directions) / directions
    return float(np.ptp(pts @ np.stack([np.cos(th), np.sin(th)]), axis=0).max())


def generated_objects(gen: dict) -> dict[str, dict]:
    """Object specs (name -> spec, config ``objects`` form) of the config's ``generated``
    section: ``count`` blobs with seeds ``seed`` .. ``seed + count - 1``."""
    lo, hi = gen["size_mm"]
    if not 0 < lo <= hi:
        raise GeometryError(
            "generated.size_mm", f"must be [min, max] with 0 < min <= max, got {[lo, hi]}"
        )
    out = {}
    for s in range(gen["seed"], gen["seed"] + gen["count"]):
        out[blob_name(s)] = {
            "type": "blob",
            "seed": s,
            "diameter_mm": blob_diameter(s, (lo, hi)),
            "harmonics": gen["harmonics"],
            "amplitude": gen["amplitude"],
            "angle_deg": 0.0,
            "split": gen["split"],
            "materials": list(gen["materials"]),
        }
    return out
