"""Image operations shared by simulated renders and real camera images:
segmentation, exact area-weighted crop + resize.

Nothing here knows about the mesh: the finger mask comes from the image alone
(threshold + morphology), so the same code runs on camera frames.
"""
from __future__ import annotations

import numpy as np


def to_gray(image: np.ndarray) -> np.ndarray:
    """Luminance in [0, 1] (float64) of an (H, W) or (H, W, 3|4) image (uint8 or float in [0, 1])."""
    img = np.asarray(image)
    scale = 255.0 if img.dtype == np.uint8 else 1.0
    img = img.astype(np.float64) / scale
    if img.ndim == 3:
        # ITU-R BT.709 luma, the weights of skimage.color.rgb2gray
        img = img[..., :3] @ np.array([0.2125, 0.7154, 0.0721])
    return img


THRESHOLDS = ("isodata", "otsu")


def segment(image: np.ndarray, threshold: str | float = "isodata", foreground: str = "bright",
            min_object_frac: float = 1e-3, max_hole_frac: float = 2e-4,
            keep_largest: bool = True) -> np.ndarray:
    """Finger mask (H, W) bool of a camera image.

    1. grey level (BT.709 luma), 2. global threshold: Ridler-Calvard's
    (``"isodata"``: midway between the two classes' means, which on an
    anti-aliased image cuts at half coverage), Otsu's (``"otsu"``) or a fixed grey
    level in [0, 1]; ``foreground`` says whether the finger is brighter or darker
    than the background, 3. morphology: drop bright specks smaller than
    ``min_object_frac`` of the image, fill holes smaller than ``max_hole_frac``
    (the finger's cavities are much larger and stay open), keep the largest
    connected component (the finger) if ``keep_largest``.
    """
    from skimage import filters, measure, morphology

    g = to_gray(image)
    if isinstance(threshold, str):
        if threshold not in THRESHOLDS:
            raise ValueError(f"threshold must be one of {THRESHOLDS} or a number, not {threshold!r}")
        if g.min() == g.max():
            t = g.min()
        elif threshold == "isodata":
            t = filters.threshold_isodata(g)
        else:
            t = filters.threshold_otsu(g)
    else:
        t = float(threshold)
    if foreground == "bright":
        mask = g > t
    elif foreground == "dark":
        mask = g < t
    else:
        raise ValueError(f"foreground must be 'bright' or 'dark', not {foreground!r}")
    n = mask.size
    min_obj = int(round(min_object_frac * n))
    if min_obj > 0:
        mask = morphology.remove_small_objects(mask, max_size=min_obj)
    max_hole = int(round(max_hole_frac * n))
    if max_hole > 0:
        mask = morphology.remove_small_holes(mask, max_size=max_hole)
    if keep_largest and mask.any():
        lab = measure.label(mask, connectivity=2)
        counts = np.bincount(lab.ravel())
        counts[0] = 0
        mask = lab == int(np.argmax(counts))
    return mask


def _axis_weights(n_src: int, lo: float, hi: float, n_dst: int) -> np.ndarray:
    """(n_dst, n_src) weights: fraction of each destination cell (on [lo, hi] split in
    n_dst) covered by source pixel i (on [i, i + 1]); parts outside the source are
    dropped (they count as 0)."""
    edges = lo + (hi - lo) * np.arange(n_dst + 1) / n_dst
    a = np.maximum(edges[:-1, None], np.arange(n_src)[None, :])
    b = np.minimum(edges[1:, None], np.arange(1, n_src + 1)[None, :])
    return np.clip(b - a, 0.0, None) / ((hi - lo) / n_dst)


def area_resample(image: np.ndarray, box_px: tuple[float, float, float, float],
                  out_shape: tuple[int, int]) -> np.ndarray:
    """Crop ``box_px = (col0, row0, col1, row1)`` (pixel edges, floats allowed) and
    resize to ``out_shape = (H, W)`` by exact area averaging (each output pixel is
    the mean of the input over its footprint; outside the image counts as 0).

    Works on (H, W) and (H, W, C) arrays; returns float64. Area averages compose:
    resampling twice over nested grids equals resampling once.
    """
    img = np.asarray(image, dtype=np.float64)
    c0, r0, c1, r1 = box_px
    if not (c1 > c0 and r1 > r0):
        raise ValueError(f"empty crop box {box_px}")
    wy = _axis_weights(img.shape[0], r0, r1, out_shape[0])
    wx = _axis_weights(img.shape[1], c0, c1, out_shape[1])
    if img.ndim == 2:
        return wy @ img @ wx.T
    return np.einsum("ij,jkc,lk->ilc", wy, img, wx, optimize=True)
