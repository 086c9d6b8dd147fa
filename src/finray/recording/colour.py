"""Colour segmentation of the finger in camera frames (the paper's Fig. 11).

A colour range selects the finger's pixels; the object and the clamp, of other
colours (or grey), fall outside. Spaces: ``"hsv"`` (hue in degrees, wrapping when
``lo`` > ``hi``; saturation and value in [0, 1]), ``"hcv"`` (the same with the chroma
max - min of R, G, B in [0, 1] in place of the saturation: linear in how much of a
pixel the finger covers, so a threshold midway cuts edges at half coverage) or
``"lab"`` (CIE Lab: L in [0, 100], a and b in about [-128, 127]).
Then the dataset stage's morphology (:func:`~finray.dataset.imageops.clean_mask`:
drop specks, fill small holes, keep the largest component).

Speed: the finger is found on every ``stride``-th row and column (16x fewer pixels at
4), and the full-resolution threshold and morphology run only inside that
component's box (plus a margin), so the mask is exact at full resolution at a
fraction of a whole frame's cost.

Learned colour (no ``finger_colour`` in take.json): on the first frames (every
``stride``-th row and column), the pixels of more chroma than Otsu's threshold of the
chroma (clipped to [0.08, 0.5]: between the grey background's and the finger's) give
a hue histogram (5-degree bins); each peak (>= 2 % of those pixels) spans the hues
around it down to 10 % of its height, and the peak whose largest blob in the first
frame is the largest is the finger's: an ``"hcv"`` range, chroma from Otsu's
threshold up, value >= 0.1. Give ``finger_colour`` when something else in
view is more colourful and larger than the finger.
"""

from __future__ import annotations

from dataclasses import asdict, dataclass

import numpy as np
from scipy import ndimage as ndi

from ..dataset.imageops import clean_mask

#: The colour spaces a range may be given in.
SPACES = ("hsv", "hcv", "lab")
#: Named colours: hue ranges (deg) with saturation >= 0.35 and value >= 0.2.
NAMED_HUES = {
    "red": (345.0, 15.0),
    "orange": (15.0, 45.0),
    "yellow": (45.0, 70.0),
    "green": (75.0, 165.0),
    "cyan": (165.0, 200.0),
    "blue": (200.0, 260.0),
    "purple": (260.0, 300.0),
    "magenta": (300.0, 345.0),
}


@dataclass(frozen=True)
class ColourRange:
    """Pixels with ``lo <= colour <= hi`` per channel in ``space`` ("hsv" or "lab")."""

    space: str
    lo: tuple[float, float, float]
    hi: tuple[float, float, float]
    source: str = "given"

    def __post_init__(self):
        if self.space not in SPACES:
            raise ValueError(f"colour space {self.space!r} is not one of {', '.join(SPACES)}")
        for name, v in (("lo", self.lo), ("hi", self.hi)):
            if len(v) != 3 or not np.isfinite(np.asarray(v, dtype=np.float64)).all():
                raise ValueError(f"{name} must be three finite numbers, got {list(v)}")
        # hue wraps through 0 (lo above hi: red); the other channels are ranges
        first = 0 if self.space == "lab" else 1
        for i in range(first, 3):
            if self.lo[i] > self.hi[i]:
                raise ValueError(f"lo {list(self.lo)} is above hi {list(self.hi)} in channel {i}")

    @classmethod
    def from_take(cls, spec) -> "ColourRange":
        """From take.json's ``finger_colour``: a name of :data:`NAMED_HUES` or
        ``{"space", "lo", "hi"}``."""
        if isinstance(spec, str):
            h0, h1 = NAMED_HUES[spec]
            return cls("hsv", (h0, 0.35, 0.2), (h1, 1.0, 1.0), f"named: {spec}")
        return cls(spec["space"], tuple(map(float, spec["lo"])), tuple(map(float, spec["hi"])))

    def to_dict(self) -> dict:
        d = asdict(self)
        d["lo"], d["hi"] = list(self.lo), list(self.hi)
        return d

    def describe(self) -> str:
        if self.space in ("hsv", "hcv"):
            what = "saturation" if self.space == "hsv" else "chroma"
            return (
                f"hue {self.lo[0]:g}-{self.hi[0]:g} deg, {what} {self.lo[1]:.2f}-"
                f"{self.hi[1]:.2f}, value {self.lo[2]:.2f}-{self.hi[2]:.2f}"
            )
        return f"Lab {list(self.lo)} to {list(self.hi)}"

    def contains(self, rgb: np.ndarray) -> np.ndarray:
        """(H, W) bool of an (H, W, 3) uint8 image."""
        if self.space == "lab":
            from skimage.color import rgb2lab

            c = rgb2lab(rgb)
            lo, hi = np.asarray(self.lo), np.asarray(self.hi)
            return np.all((c >= lo) & (c <= hi), axis=-1)
        h, s, v = hsv(rgb, chroma=self.space == "hcv")
        ok = (s >= self.lo[1]) & (s <= self.hi[1]) & (v >= self.lo[2]) & (v <= self.hi[2])
        h0, h1 = self.lo[0] % 360.0, self.hi[0] % 360.0
        if h0 <= h1:
            ok &= (h >= h0) & (h <= h1)
        else:  # wraps through 0 (red)
            ok &= (h >= h0) | (h <= h1)
        return ok


def hsv(rgb: np.ndarray, chroma: bool = False) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Hue (deg, [0, 360)), saturation (or, if ``chroma``, the chroma max - min) and
    value ([0, 1]) of an (..., 3) uint8 image, float32 (skimage's ``rgb2hsv`` in
    float64 is ~4x slower)."""
    x = rgb.astype(np.float32)
    r, g, b = x[..., 0], x[..., 1], x[..., 2]
    mx = np.maximum(np.maximum(r, g), b)
    mn = np.minimum(np.minimum(r, g), b)
    d = mx - mn
    dd = np.maximum(d, 1e-6)
    h = (
        np.where(
            mx == r,
            np.mod((g - b) / dd, 6.0),
            np.where(mx == g, (b - r) / dd + 2.0, (r - g) / dd + 4.0),
        )
        * 60.0
    )
    s = d / 255.0 if chroma else d / np.maximum(mx, 1e-6)
    return h, s, mx / 255.0


def _largest_blob(mask: np.ndarray) -> tuple[np.ndarray | None, int]:
    """The largest 8-connected component of ``mask`` dilated by one pixel (so that
    pieces a pixel apart, thin ribs at low resolution, stay one blob): its
    (rows, cols) slices and its size in pixels (0: none)."""
    grown = ndi.binary_dilation(mask, np.ones((3, 3), bool))
    lab, n = ndi.label(grown, np.ones((3, 3), bool))
    if n == 0:
        return None, 0
    sizes = np.bincount(lab.ravel(), weights=mask.ravel())
    sizes[0] = 0
    k = int(np.argmax(sizes))
    return ndi.find_objects((lab == k).astype(np.int32))[0], int(sizes[k])


def learn_colour(frames: list[np.ndarray], stride: int = 4) -> ColourRange | None:
    """The finger's HSV range learned from the first frames (see the module's text);
    None when nothing in them is coloured."""
    from skimage.filters import threshold_otsu

    subs = [f[::stride, ::stride] for f in frames]
    h, s, v = (
        np.concatenate([c.ravel() for c in p]) for p in zip(*(hsv(f, chroma=True) for f in subs))
    )
    if s.max() - s.min() < 1e-3:
        return None
    s_min = float(np.clip(threshold_otsu(s), 0.08, 0.5))
    coloured = (s >= s_min) & (v >= 0.1)
    if coloured.sum() < 10:
        return None
    hist = np.bincount((h[coloured] // 5).astype(int) % 72, minlength=72).astype(float)
    hist = (np.roll(hist, 1) + 2 * hist + np.roll(hist, -1)) / 4  # circular smoothing
    peaks = [
        k
        for k in range(72)
        if hist[k] >= max(hist[k - 1], hist[(k + 1) % 72]) and hist[k] >= 0.02 * coloured.sum()
    ]
    best, best_size = None, 0
    for k in peaks:
        lo = hi = k
        while hist[(lo - 1) % 72] >= 0.1 * hist[k] and (k - lo) < 8:
            lo -= 1
        while hist[(hi + 1) % 72] >= 0.1 * hist[k] and (hi - k) < 8:
            hi += 1
        cand = ColourRange(
            "hcv", ((lo * 5) % 360, s_min, 0.1), (((hi + 1) * 5) % 360, 1.0, 1.0), "learned"
        )
        _, size = _largest_blob(cand.contains(subs[0]))
        if size > best_size:
            best, best_size = cand, size
    return best


def segment_finger(
    rgb: np.ndarray,
    colour: ColourRange,
    stride: int = 4,
    min_object_frac: float = 1e-3,
    max_hole_frac: float = 2e-4,
    margin_px: int = 8,
    stats: dict | None = None,
) -> np.ndarray | None:
    """Finger mask (H, W) bool of a frame, or None when no pixel has the finger's colour.

    The largest blob of the colour on the ``stride``-subsampled frame gives the box;
    inside it (plus ``margin_px`` and a stride), the colour range at full resolution
    and :func:`~finray.dataset.imageops.clean_mask` with sizes as fractions of the whole
    frame (specks up to ``min_object_frac`` dropped, holes up to ``max_hole_frac``
    filled). ``stats``: a dict that receives ``candidate_frac``, the fraction of the
    ``stride`` grid's pixels of the finger's colour (the mask's confidence:
    :mod:`finray.recording.finder`)."""
    H, W = rgb.shape[:2]
    small = colour.contains(rgb[::stride, ::stride])
    if stats is not None:
        stats["candidate_frac"] = float(np.count_nonzero(small)) / small.size
    sl, size = _largest_blob(small)
    if sl is None:
        return None
    pad = margin_px + stride
    r0, r1 = max(sl[0].start * stride - pad, 0), min(sl[0].stop * stride + pad, H)
    c0, c1 = max(sl[1].start * stride - pad, 0), min(sl[1].stop * stride + pad, W)
    box = colour.contains(rgb[r0:r1, c0:c1])
    n_box = box.size
    clean_mask(box, min_object_frac * H * W / n_box, max_hole_frac * H * W / n_box, True)
    if not box.any():
        return None
    mask = np.zeros((H, W), bool)
    mask[r0:r1, c0:c1] = box
    return mask
