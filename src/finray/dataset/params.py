"""Settings of the dataset stage (config section ``dataset``) and the names it gives
shards and scenes."""
from __future__ import annotations

from dataclasses import dataclass, fields

import numpy as np

from .augment import NOISE_LEVELS, OCCLUSION_LEVELS
from .imageops import segment


#: The settings a shard's arrays depend on (sizes, crop, segmentation); the rest of
#: :class:`DatasetParams` is for the test-time corruptions and figures. A shard records
#: these only, and the workflow re-renders when one of them changes.
SHARD_KEYS = ("sizes", "crop_x_mm", "crop_y_mm", "threshold", "foreground", "min_object_frac",
              "max_hole_frac", "keep_largest", "base_band")


@dataclass(frozen=True)
class DatasetParams:
    """Settings of the dataset stage (config section ``dataset``)."""

    #: Output sizes (height, width); height = 2 x width.
    sizes: tuple[tuple[int, int], ...] = ((128, 64), (64, 32))
    #: Crop window in image-plane mm (2:1 like the sizes).
    crop_x_mm: tuple[float, float] = (-5.0, 35.0)
    crop_y_mm: tuple[float, float] = (0.0, 80.0)
    threshold: str | float = "isodata"
    foreground: str = "bright"
    min_object_frac: float = 1e-3
    max_hole_frac: float = 2e-4
    keep_largest: bool = True
    #: The base-anchored crop of camera frames (camera views, the predictor): the base is
    #: the widest row among the lowest ``base_band`` of the mask's height (a rolled or
    #: pitched camera slants its bottom edge over several rows).
    base_band: float = 0.03
    noise_levels: tuple[tuple[str, float], ...] = tuple(NOISE_LEVELS.items())
    occlusion_levels: tuple[tuple[str, tuple[float, float]], ...] = tuple(OCCLUSION_LEVELS.items())
    occluder_value: float = 0.0
    seed: int = 0
    pitch_object: str | None = None

    def __post_init__(self):
        for h, w in self.sizes:
            if h != 2 * w:
                raise ValueError(f"dataset.sizes: {h}x{w} is not height = 2 x width")
        cw = self.crop_x_mm[1] - self.crop_x_mm[0]
        ch = self.crop_y_mm[1] - self.crop_y_mm[0]
        if cw <= 0 or ch <= 0:
            raise ValueError("dataset.crop_x_mm / crop_y_mm: empty crop")
        if abs(ch - 2 * cw) > 1e-9:
            raise ValueError(f"dataset.crop_y_mm: the crop ({cw:g} x {ch:g} mm) must be twice "
                             "as tall as wide, like the output sizes")

    @classmethod
    def from_config(cls, section: dict | None) -> "DatasetParams":
        section = dict(section or {})
        names = {f.name for f in fields(cls)}
        kw = {}
        for k, v in section.items():
            if k not in names:
                continue
            if k == "sizes":
                v = tuple(tuple(int(x) for x in s) for s in v)
            elif k == "noise_levels":
                v = tuple((str(a), float(b)) for a, b in dict(v).items())
            elif k == "occlusion_levels":
                v = tuple((str(a), (float(b[0]), float(b[1]))) for a, b in dict(v).items())
            elif isinstance(v, list):
                v = tuple(v)
            kw[k] = v
        return cls(**kw)

    @property
    def noise(self) -> dict[str, float]:
        return dict(self.noise_levels)

    @property
    def occlusion(self) -> dict[str, tuple[float, float]]:
        return dict(self.occlusion_levels)

    def segment(self, image: np.ndarray) -> np.ndarray:
        return segment(image, self.threshold, self.foreground, self.min_object_frac,
                       self.max_hole_frac, self.keep_largest)

    def to_dict(self) -> dict:
        d = {f.name: getattr(self, f.name) for f in fields(self)}
        d["sizes"] = [list(s) for s in self.sizes]
        d["noise_levels"] = self.noise
        d["occlusion_levels"] = {k: list(v) for k, v in self.occlusion.items()}
        d["crop_x_mm"], d["crop_y_mm"] = list(self.crop_x_mm), list(self.crop_y_mm)
        return d


def size_key(size: tuple[int, int]) -> str:
    return f"{size[0]}x{size[1]}"


def scene_id(scene: dict) -> str:
    """``<object>_<material>_h<height>_p<pitch>``."""
    return (f"{scene.get('object', 'unknown')}_{scene.get('material', 'unknown')}"
            f"_h{float(scene.get('height_mm', 0)):g}_p{float(scene.get('pitch_deg', 0)):g}")
