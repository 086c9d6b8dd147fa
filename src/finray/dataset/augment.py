"""Seeded, replayable corruptions of network inputs: salt-and-pepper noise and
occlusion by a disc.

As in kornia, the random parameters are drawn first (:func:`sample_augment`,
from a seed) and applied separately (:func:`apply_augment`), so a sample is
replayed exactly from its :class:`AugmentParams`, or from its seed.

Salt-and-pepper: exactly ``round(density * H * W)`` distinct pixels, drawn
uniformly, are hit; half of them (rounded down) become pepper (0), the rest
salt (1). The density is thus exact, not only on average.

Occlusion: a disc of ``d`` whole pixels across, ``d / W`` drawn uniformly among
the whole-pixel diameters whose fraction of the image width ``W`` lies in the
level's range (low 10-30 %, medium 40-80 %, high 80-100 % by default), placed
uniformly with the whole disc inside the image. A pixel is occluded when its
centre lies within ``d / 2`` of the disc's centre, which makes the disc exactly
``d`` pixels wide and tall. Occluded pixels take ``occluder_value`` (0: the
occluder looks like background after segmentation).
"""

from __future__ import annotations

import math
import zlib
from dataclasses import dataclass, field

import numpy as np

from ..schema import schema_default


def noise_levels(levels: dict) -> dict[str, float]:
    """A config's ``dataset.noise_levels`` as level -> salt-and-pepper density."""
    return {str(k): float(v) for k, v in dict(levels).items()}


def occlusion_levels(levels: dict) -> dict[str, tuple[float, float]]:
    """A config's ``dataset.occlusion_levels`` as level -> disc diameter range."""
    return {str(k): (float(v[0]), float(v[1])) for k, v in dict(levels).items()}


#: Salt-and-pepper density (fraction of pixels hit) per noise level (the schema's).
NOISE_LEVELS: dict[str, float] = schema_default("dataset.noise_levels", noise_levels)
#: Occluding disc diameter as a fraction of the image width, [min, max], per level
#: (the schema's).
OCCLUSION_LEVELS: dict[str, tuple[float, float]] = schema_default(
    "dataset.occlusion_levels", occlusion_levels
)


@dataclass(frozen=True)
class AugmentParams:
    """Everything needed to replay one corruption of one (H, W) image."""

    shape: tuple[int, int]
    noise_level: str = "none"
    density: float = 0.0
    salt: np.ndarray = field(default_factory=lambda: np.zeros(0, np.int64))  # flat indices
    pepper: np.ndarray = field(default_factory=lambda: np.zeros(0, np.int64))
    occlusion_level: str = "none"
    disc_diameter_px: int = 0
    disc_centre_px: tuple[float, float] = (0.0, 0.0)  # (row, col), pixel centres at integers
    seed: int | None = None

    def disc_mask(self) -> np.ndarray:
        """(H, W) bool: the occluded pixels."""
        h, w = self.shape
        if self.disc_diameter_px <= 0:
            return np.zeros(self.shape, dtype=bool)
        rr, cc = np.ogrid[:h, :w]
        rc, ccen = self.disc_centre_px
        r = 0.5 * self.disc_diameter_px
        return (rr - rc) ** 2 + (cc - ccen) ** 2 <= r * r

    def to_dict(self) -> dict:
        """JSON-serialisable form (for logs and manifests)."""
        return {
            "shape": list(self.shape),
            "noise_level": self.noise_level,
            "density": self.density,
            "salt": self.salt.tolist(),
            "pepper": self.pepper.tolist(),
            "occlusion_level": self.occlusion_level,
            "disc_diameter_px": self.disc_diameter_px,
            "disc_centre_px": list(self.disc_centre_px),
            "seed": self.seed,
        }


def augment_seed(base_seed: int, *keys) -> int:
    """A stable 63-bit seed from a base seed and keys (ints or strings, e.g. scene id,
    frame, level): the same on every machine and every run (no Python ``hash``)."""
    ints = [int(base_seed) & 0xFFFFFFFF]
    for k in keys:
        if isinstance(k, (int, np.integer)):
            ints.append(int(k) & 0xFFFFFFFF)
        else:
            ints.append(zlib.crc32(str(k).encode()))
    return int(np.random.SeedSequence(ints).generate_state(1, dtype=np.uint64)[0] >> np.uint64(1))


def disc_diameters(width: int, height: int, frac_range: tuple[float, float]) -> np.ndarray:
    """Whole-pixel diameters allowed for a level: ``lo <= d / width <= hi``, ``d <= min(W, H)``."""
    lo, hi = frac_range
    if hi <= 0:
        return np.zeros(1, dtype=np.int64)
    d_lo = max(1, math.ceil(lo * width - 1e-9))
    d_hi = min(math.floor(hi * width + 1e-9), width, height)
    if d_hi < d_lo:
        raise ValueError(f"no whole-pixel disc diameter in {frac_range} of a {width} px wide image")
    return np.arange(d_lo, d_hi + 1)


def sample_augment(
    seed: int | np.random.Generator,
    shape: tuple[int, int],
    noise: str = "none",
    occlusion: str = "none",
    noise_levels: dict[str, float] | None = None,
    occlusion_levels: dict[str, tuple[float, float]] | None = None,
) -> AugmentParams:
    """Draw the parameters of one corruption of an (H, W) image (no image needed)."""
    noise_levels = NOISE_LEVELS if noise_levels is None else noise_levels
    occlusion_levels = OCCLUSION_LEVELS if occlusion_levels is None else occlusion_levels
    if noise not in noise_levels:
        raise ValueError(f"noise level {noise!r} is not one of {list(noise_levels)}")
    if occlusion not in occlusion_levels:
        raise ValueError(f"occlusion level {occlusion!r} is not one of {list(occlusion_levels)}")
    rng = seed if isinstance(seed, np.random.Generator) else np.random.default_rng(seed)
    h, w = int(shape[0]), int(shape[1])
    # always the same draws in the same order, whatever the levels
    diam = disc_diameters(w, h, occlusion_levels[occlusion])
    d = int(diam[rng.integers(len(diam))])
    r0 = int(rng.integers(0, h - d + 1))
    c0 = int(rng.integers(0, w - d + 1))
    density = float(noise_levels[noise])
    if not 0.0 <= density <= 1.0:
        raise ValueError(f"noise density {density} is outside [0, 1]")
    n_hit = int(round(density * h * w))
    hit = rng.permutation(h * w)[:n_hit].astype(np.int64)
    n_pepper = n_hit // 2
    return AugmentParams(
        shape=(h, w),
        noise_level=noise,
        density=density,
        salt=np.sort(hit[n_pepper:]),
        pepper=np.sort(hit[:n_pepper]),
        occlusion_level=occlusion,
        disc_diameter_px=d,
        disc_centre_px=(r0 + 0.5 * (d - 1), c0 + 0.5 * (d - 1)),
        seed=None if isinstance(seed, np.random.Generator) else int(seed),
    )


def apply_augment(
    image: np.ndarray,
    params: AugmentParams,
    occluder_value: float = schema_default("dataset.occluder_value"),
) -> np.ndarray:
    """Apply a corruption to an (H, W) or (H, W, C) image (a copy is returned).

    Occlusion first, then salt-and-pepper on top (sensor noise). Values are on a
    [0, 1] scale (x255 for uint8 images): salt 1, pepper 0, occluder ``occluder_value``.
    """
    img = np.array(image, copy=True)
    if img.shape[:2] != tuple(params.shape):
        raise ValueError(f"image {img.shape[:2]} does not match the parameters' {params.shape}")
    scale = 255 if img.dtype == np.uint8 else 1.0
    if params.disc_diameter_px > 0:
        img[params.disc_mask()] = occluder_value * scale
    flat = img.reshape(params.shape[0] * params.shape[1], *img.shape[2:])
    flat[params.salt] = scale
    flat[params.pepper] = 0
    return img
