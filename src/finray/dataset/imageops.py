"""Image operations shared by simulated renders and real camera images:
segmentation, exact area-weighted crop + resize.

Nothing here knows about the mesh: the finger mask comes from the image alone
(threshold + morphology), so the same code runs on camera frames.
"""

from __future__ import annotations

import numba as nb
import numpy as np

from ..errors import EmptyMaskError
from ..schema import schema_default


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

_LUMA = np.array([0.2125, 0.7154, 0.0721])


@nb.njit(cache=True)
def _histogram(g: np.ndarray, lo: float, scale: float, nbins: int) -> np.ndarray:
    """Counts of ``min(int((g - lo) * scale), nbins - 1)`` (``np.bincount``'s, 5x faster)."""
    counts = np.zeros(nbins, np.int64)
    for v in g.ravel():
        k = int((np.float64(v) - lo) * scale)
        counts[min(k, nbins - 1)] += 1
    return counts


@nb.njit(cache=True)
def _label_sizes(lab: np.ndarray, n: int) -> np.ndarray:
    """Pixels per label 0..n (``np.bincount``'s, 5x faster)."""
    counts = np.zeros(n + 1, np.int64)
    for v in lab.ravel():
        counts[v] += 1
    return counts


def threshold_isodata(g: np.ndarray, nbins: int = 256) -> float:
    """Ridler-Calvard (isodata) grey level of ``g`` from one ``bincount``: a bin centre
    ``t`` with ``0 <= (mean below + mean above) / 2 - t < bin width`` (``nbins`` equal
    bins between the minimum and the maximum, as :func:`skimage.filters.threshold_isodata`
    on a float image). Where several bins qualify, skimage takes the lowest; on a video
    frame of a small finger over a dark background that is a level inside the
    background's compression noise, which then becomes the "finger". Here: the lowest
    of those that separate the two classes within 1 % as well as the best one
    (between-class variance, Otsu's criterion), which is skimage's level wherever one
    bin qualifies or the candidates are neighbours on one edge."""
    g = np.ascontiguousarray(g)
    if g.dtype not in (np.float32, np.float64):
        g = g.astype(np.float64)
    lo, hi = float(g.min()), float(g.max())
    if lo == hi:
        return lo
    counts = _histogram(g, lo, nbins / (hi - lo), nbins).astype(np.float64)
    centres = lo + (np.arange(nbins) + 0.5) * ((hi - lo) / nbins)
    below = np.cumsum(counts)
    cum = np.cumsum(counts * centres)
    with np.errstate(invalid="ignore", divide="ignore"):  # empty sides: NaN, never chosen
        mean_low = cum[:-1] / below[:-1]
        mean_high = (cum[-1] - cum[:-1]) / (below[-1] - below[:-1])
    d = (mean_low + mean_high) / 2.0 - centres[:-1]
    ok = np.flatnonzero((d >= 0) & (d < centres[1] - centres[0]))
    if len(ok) > 1:
        w_low = below[ok] / below[-1]
        between = w_low * (1.0 - w_low) * (mean_high[ok] - mean_low[ok]) ** 2
        ok = ok[between >= 0.99 * between.max()]
    return float(centres[ok[0]])


def _drop_small(mask: np.ndarray, max_size: int, value: bool, structure: np.ndarray) -> int:
    """Set the connected components of ``mask == (not value)`` with at most ``max_size``
    pixels to ``value``, in place (:func:`skimage.morphology.remove_small_objects` /
    ``remove_small_holes`` with ``max_size``); returns how many components are left."""
    from scipy import ndimage as ndi

    lab, n = ndi.label(mask if not value else ~mask, structure)
    if n == 0 or max_size <= 0:
        return n
    small = _label_sizes(lab, n) <= max_size
    small[0] = False
    if small.any():
        mask[small[lab]] = value
    return n - int(small.sum())


_LUMA_8BIT = (_LUMA / 255.0).astype(np.float32)


@nb.njit(cache=True)
def _luma_u8(img: np.ndarray, stride: int, w: np.ndarray) -> np.ndarray:
    """Luma (float32) of every ``stride``-th row and column of an 8-bit colour image."""
    out = np.empty(
        ((img.shape[0] + stride - 1) // stride, (img.shape[1] + stride - 1) // stride), np.float32
    )
    for i in range(out.shape[0]):
        for j in range(out.shape[1]):
            out[i, j] = (
                np.float32(img[i * stride, j * stride, 0]) * w[0]
                + np.float32(img[i * stride, j * stride, 1]) * w[1]
                + np.float32(img[i * stride, j * stride, 2]) * w[2]
            )
    return out


def _luma(img: np.ndarray, stride: int = 1) -> np.ndarray:
    """Grey level in [0, 1] of every ``stride``-th row and column of an image (uint8
    colour: float32; else :func:`to_gray`)."""
    if img.dtype == np.uint8 and img.ndim == 3 and img.shape[2] >= 3:
        # 8-bit colour (cameras, renders): luma in float32, one compiled pass (the
        # rounding, ~1e-7, never moves a pixel across a threshold between 8-bit levels)
        return _luma_u8(img, stride, _LUMA_8BIT)
    return to_gray(img[::stride, ::stride])


def segment(
    image: np.ndarray,
    threshold: str | float = schema_default("dataset.threshold"),
    foreground: str = schema_default("dataset.foreground"),
    min_object_frac: float = schema_default("dataset.min_object_frac"),
    max_hole_frac: float = schema_default("dataset.max_hole_frac"),
    keep_largest: bool = schema_default("dataset.keep_largest"),
    roi_stride: int = 1,
    stats: dict | None = None,
) -> np.ndarray:
    """Finger mask (H, W) bool of a camera image.

    1. grey level (BT.709 luma), 2. global threshold: Ridler-Calvard's
    (``"isodata"``: midway between the two classes' means, which on an
    anti-aliased image cuts at half coverage), Otsu's (``"otsu"``) or a fixed grey
    level in [0, 1]; ``foreground`` says whether the finger is brighter or darker
    than the background, 3. morphology:
    drop specks (4-connected) of at most ``min_object_frac`` of the image, fill
    holes (4-connected) of at most ``max_hole_frac`` (the finger's cavities are much
    larger and stay open), keep the largest 8-connected component (the finger) if
    ``keep_largest``.

    ``roi_stride`` > 1 (the predictor, on camera frames where the finger covers a small
    part): the threshold's histogram and the foreground's bounding box come from every
    ``roi_stride``-th row and column, and steps 1-3 run at full resolution inside that
    box plus ``roi_stride`` px only. The threshold may move by a fraction of a grey
    level (a few edge pixels); foreground beyond the box, reachable only through a
    strip thinner than ``roi_stride`` px, is lost (the finger has none). 1: the whole
    image (the dataset stage).

    The morphology runs inside the foreground's bounding box plus a margin wide
    enough that any background touching the margin is larger than a hole: the
    result is that of the whole image (skimage's ``remove_small_objects``,
    ``remove_small_holes`` and ``label``), at a fraction of the cost.

    ``stats``: a dict that receives ``candidate_frac``, the fraction of the image (of
    its ``roi_stride`` grid) on the finger's side of the threshold before the
    morphology (the mask's confidence: :mod:`finray.recording.finder`).
    """
    img = np.asarray(image)
    if foreground not in ("bright", "dark"):
        raise ValueError(f"foreground must be 'bright' or 'dark', not {foreground!r}")
    if isinstance(threshold, str) and threshold not in THRESHOLDS:
        raise ValueError(f"threshold must be one of {THRESHOLDS} or a number, not {threshold!r}")
    stride = max(1, int(roi_stride))
    g = _luma(img, stride)
    if isinstance(threshold, str):
        if g.min() == g.max():
            t = g.min()
        elif threshold == "isodata":
            t = threshold_isodata(g)
        else:
            from skimage import filters

            t = filters.threshold_otsu(g)
    else:
        t = float(threshold)
    fg = g > t if foreground == "bright" else g < t
    if stats is not None:
        stats["candidate_frac"] = float(np.count_nonzero(fg)) / fg.size
    if stride == 1:
        return clean_mask(fg, min_object_frac, max_hole_frac, keep_largest)
    mask = np.zeros(img.shape[:2], bool)
    rows, cols = np.flatnonzero(fg.any(axis=1)), np.flatnonzero(fg.any(axis=0))
    if len(rows) == 0:
        return mask
    r0, r1 = max((rows[0] - 1) * stride, 0), (rows[-1] + 2) * stride
    c0, c1 = max((cols[0] - 1) * stride, 0), (cols[-1] + 2) * stride
    gb = _luma(img[r0:r1, c0:c1])
    mask[r0:r1, c0:c1] = gb > t if foreground == "bright" else gb < t
    return clean_mask(mask, min_object_frac, max_hole_frac, keep_largest)


def clean_mask(
    mask: np.ndarray,
    min_object_frac: float = schema_default("dataset.min_object_frac"),
    max_hole_frac: float = schema_default("dataset.max_hole_frac"),
    keep_largest: bool = schema_default("dataset.keep_largest"),
) -> np.ndarray:
    """The morphology of :func:`segment` on a thresholded mask (H, W) bool, in place
    (and returned): drop specks (4-connected) of at most ``min_object_frac`` of the
    image, fill holes (4-connected) of at most ``max_hole_frac``, keep the largest
    8-connected component if ``keep_largest``; the work is done inside the
    foreground's bounding box plus a margin (see :func:`segment`)."""
    from scipy import ndimage as ndi

    rows = np.flatnonzero(mask.any(axis=1))
    if len(rows) == 0:
        return mask
    cols = np.flatnonzero(mask.any(axis=0))
    n = mask.size
    min_obj = int(round(min_object_frac * n))
    max_hole = int(round(max_hole_frac * n))
    # margin: a background component reaching outside the box holds a whole margin
    # strip (>= margin x the box's shorter side pixels), so it is no hole
    side = min(rows[-1] - rows[0] + 1, cols[-1] - cols[0] + 1)
    m = max(1, -(-(max_hole + 1) // side))
    r0, r1 = max(rows[0] - m, 0), min(rows[-1] + 1 + m, mask.shape[0])
    c0, c1 = max(cols[0] - m, 0), min(cols[-1] + 1 + m, mask.shape[1])
    box = mask[r0:r1, c0:c1]  # a view: edits land in mask
    four = ndi.generate_binary_structure(2, 1)
    n_parts = _drop_small(box, min_obj, False, four)
    if max_hole > 0:
        _drop_small(box, max_hole, True, four)
    # one 4-connected part left: filled holes touch it, it is the largest component
    if keep_largest and n_parts > 1:
        lab, n8 = ndi.label(box, ndi.generate_binary_structure(2, 2))
        counts = _label_sizes(lab, n8)
        counts[0] = 0
        box[...] = lab == int(np.argmax(counts))
    return mask


def _axis_weights(n_src: int, lo: float, hi: float, n_dst: int) -> np.ndarray:
    """(n_dst, n_src) weights: fraction of each destination cell (on [lo, hi] split in
    n_dst) covered by source pixel i (on [i, i + 1]); parts outside the source are
    dropped (they count as 0). Only the few pixels under each cell are evaluated."""
    edges = lo + (hi - lo) * np.arange(n_dst + 1) / n_dst
    first = np.floor(edges[:-1]).astype(np.intp)
    span = int(np.max(np.ceil(edges[1:]).astype(np.intp) - first))
    idx = first[:, None] + np.arange(max(span, 1))[None, :]  # pixels under each cell
    a = np.maximum(edges[:-1, None], idx)
    b = np.minimum(edges[1:, None], idx + 1)
    w = np.clip(b - a, 0.0, None) / ((hi - lo) / n_dst)
    inside = (idx >= 0) & (idx < n_src)
    out = np.zeros((n_dst, n_src))
    out[np.nonzero(inside)[0], idx[inside]] = w[inside]
    return out


def _nonzero_span(w: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Per row of ``w`` (n_dst, n_src), the first and one past the last non-zero column."""
    nz = w != 0
    has = nz.any(axis=1)
    lo = np.where(has, nz.argmax(axis=1), 0)
    hi = np.where(has, w.shape[1] - nz[:, ::-1].argmax(axis=1), 0)
    return lo.astype(np.int64), hi.astype(np.int64)


@nb.njit(cache=True)
def _sparse_products(sub, wy, y_lo, y_hi, wx, x_lo, x_hi) -> np.ndarray:
    """``wy @ sub @ wx.T`` (float64) over the non-zero spans of the weights' rows only."""
    out = np.zeros((wy.shape[0], wx.shape[0]))
    for i in range(wy.shape[0]):
        for r in range(y_lo[i], y_hi[i]):
            a = wy[i, r]
            for j in range(wx.shape[0]):
                acc = 0.0
                for c in range(x_lo[j], x_hi[j]):
                    acc += sub[r, c] * wx[j, c]
                out[i, j] += a * acc
    return out


def area_resample(
    image: np.ndarray,
    box_px: tuple[float, float, float, float],
    out_shape: tuple[int, int],
    fast: bool = False,
) -> np.ndarray:
    """Crop ``box_px = (col0, row0, col1, row1)`` (pixel edges, floats allowed) and
    resize to ``out_shape = (H, W)`` by exact area averaging (each output pixel is
    the mean of the input over its footprint; outside the image counts as 0).

    Works on (H, W) and (H, W, C) arrays; returns float64. ``fast`` (2-D only; the
    predictor): only the source pixels under the box, and under each output pixel only
    those its weights cover (a compiled loop, one thread: a multithreaded BLAS spent 15x
    longer on these small products on a busy 2-core machine); the same averages up to
    ~1e-12; the dataset stage keeps the dense products. Area averages compose: resampling twice over
    nested grids equals resampling once.
    """
    img = np.asarray(image)
    c0, r0, c1, r1 = box_px
    if not (c1 > c0 and r1 > r0):
        raise ValueError(f"empty crop box {box_px}")
    if fast and img.ndim == 2:
        # only the source pixels under the box; columns first (the smaller product)
        i0, i1 = max(int(np.floor(r0)), 0), min(int(np.ceil(r1)), img.shape[0])
        j0, j1 = max(int(np.floor(c0)), 0), min(int(np.ceil(c1)), img.shape[1])
        if i1 <= i0 or j1 <= j0:
            return np.zeros(out_shape)
        wy = _axis_weights(i1 - i0, r0 - i0, r1 - i0, out_shape[0])
        wx = _axis_weights(j1 - j0, c0 - j0, c1 - j0, out_shape[1])
        return _sparse_products(
            np.ascontiguousarray(img[i0:i1, j0:j1]), wy, *_nonzero_span(wy), wx, *_nonzero_span(wx)
        )
    img = img.astype(np.float64, copy=False)
    wy = _axis_weights(img.shape[0], r0, r1, out_shape[0])
    wx = _axis_weights(img.shape[1], c0, c1, out_shape[1])
    if img.ndim == 2:
        return wy @ img @ wx.T
    return np.einsum("ij,jkc,lk->ilc", wy, img, wx, optimize=True)


def base_anchored_box(
    mask: np.ndarray,
    base_width_mm: float,
    crop_x_mm: tuple[float, float],
    crop_y_mm: tuple[float, float],
    base_rows: int = 1,
    base_band: float = 0.0,
) -> tuple[float, float, float, float]:
    """The training window ``(col0, row0, col1, row1)`` in pixel edges, anchored on the
    finger itself: the lowest row of ``mask`` is the clamped base, its width is
    ``base_width_mm``, which fixes the scale (px/mm); the window ``crop_x_mm`` x
    ``crop_y_mm`` (mm from the base's left edge and bottom) is cut around it. Any
    image size and position works (the predictor and lab recordings use it).

    ``base_rows`` > 1: the base is the widest of the lowest ``base_rows`` rows (the
    lowest such), so that a ragged bottom row (a compressed video's colour blocks at
    the clamp) does not set the scale; 1 (the predictor, renders): the lowest row.
    ``base_band``: at least this fraction of the mask's height in rows (a camera that is
    rolled or looks down sees the base's bottom edge slanted over several rows)."""
    rows = np.flatnonzero(mask.any(axis=1))
    if len(rows) == 0:
        raise EmptyMaskError("no finger found in the image (empty segmentation)")
    bottom = rows[-1]
    base_rows = max(int(base_rows), int(np.ceil(base_band * (rows[-1] - rows[0] + 1))))
    if base_rows > 1:
        low = mask[max(bottom - base_rows + 1, 0) : bottom + 1]
        has = low.any(axis=1)
        first = np.where(has, low.argmax(axis=1), 0)
        last = np.where(has, low.shape[1] - low[:, ::-1].argmax(axis=1), 0)
        width = last - first
        bottom = bottom - int(np.argmax(width[::-1]))  # the lowest of the widest
    cols = np.flatnonzero(mask[bottom])
    left, right = cols[0], cols[-1] + 1  # pixel edges of the base
    ppm = (right - left) / base_width_mm
    base_edge = bottom + 1
    return (
        left + crop_x_mm[0] * ppm,
        base_edge - crop_y_mm[1] * ppm,
        left + crop_x_mm[1] * ppm,
        base_edge - crop_y_mm[0] * ppm,
    )


def silhouette_input(mask: np.ndarray, box_px, out_shape: tuple[int, int]) -> np.ndarray:
    """The network input (H, W) uint8 of a mask: the soft silhouette of the window
    ``box_px`` area-averaged to ``out_shape``, x255 rounded (as in the training
    shards' ``input_HxW``)."""
    soft = area_resample(mask, box_px, out_shape, fast=True)
    return np.rint(np.clip(soft, 0, 1) * 255.0).astype(np.uint8)
