"""Settings of the dataset stage (config section ``dataset``) and the names it gives
shards and scenes."""

from __future__ import annotations

from dataclasses import dataclass, fields

import numpy as np

from .augment import noise_levels, occlusion_levels
from .imageops import segment
from .window import SEGMENT_KEYS, InputWindow
from ..schema import schema_default


#: The settings a shard's arrays depend on (sizes, crop, segmentation); the rest of
#: :class:`DatasetParams` is for the test-time corruptions and figures. A shard records
#: these only, and the workflow re-renders when one of them changes.
SHARD_KEYS = (
    "sizes",
    "crop_x_mm",
    "crop_y_mm",
    "threshold",
    "foreground",
    "min_object_frac",
    "max_hole_frac",
    "keep_largest",
    "base_band",
)


def _noise_items(levels: dict) -> tuple:
    return tuple(noise_levels(levels).items())


def _occlusion_items(levels: dict) -> tuple:
    return tuple(occlusion_levels(levels).items())


@dataclass(frozen=True)
class DatasetParams:
    """Settings of the dataset stage (config section ``dataset``)."""

    #: Output sizes (height, width); height = 2 x width.
    sizes: tuple[tuple[int, int], ...] = schema_default("dataset.sizes")
    #: Crop window in image-plane mm (2:1 like the sizes).
    crop_x_mm: tuple[float, float] = schema_default("dataset.crop_x_mm")
    crop_y_mm: tuple[float, float] = schema_default("dataset.crop_y_mm")
    threshold: str | float = schema_default("dataset.threshold")
    foreground: str = schema_default("dataset.foreground")
    min_object_frac: float = schema_default("dataset.min_object_frac")
    max_hole_frac: float = schema_default("dataset.max_hole_frac")
    keep_largest: bool = schema_default("dataset.keep_largest")
    #: The base-anchored crop of camera frames (camera views, the predictor): the base is
    #: the widest row among the lowest ``base_band`` of the mask's height (a rolled or
    #: pitched camera slants its bottom edge over several rows).
    base_band: float = schema_default("dataset.base_band")
    noise_levels: tuple[tuple[str, float], ...] = schema_default(
        "dataset.noise_levels", _noise_items
    )
    occlusion_levels: tuple[tuple[str, tuple[float, float]], ...] = schema_default(
        "dataset.occlusion_levels", _occlusion_items
    )
    occluder_value: float = schema_default("dataset.occluder_value")
    pitch_object: str | None = schema_default("dataset.pitch_object")

    def __post_init__(self):
        for h, w in self.sizes:
            if h != 2 * w:
                raise ValueError(f"dataset.sizes: {h}x{w} is not height = 2 x width")
        cw = self.crop_x_mm[1] - self.crop_x_mm[0]
        ch = self.crop_y_mm[1] - self.crop_y_mm[0]
        if cw <= 0 or ch <= 0:
            raise ValueError("dataset.crop_x_mm / crop_y_mm: empty crop")
        if abs(ch - 2 * cw) > 1e-9:
            raise ValueError(
                f"dataset.crop_y_mm: the crop ({cw:g} x {ch:g} mm) must be twice "
                "as tall as wide, like the output sizes"
            )

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
                v = _noise_items(v)
            elif k == "occlusion_levels":
                v = _occlusion_items(v)
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
        return segment(
            image,
            self.threshold,
            self.foreground,
            self.min_object_frac,
            self.max_hole_frac,
            self.keep_largest,
        )

    def window(self, base_width_mm: float) -> InputWindow:
        """The network's input window of these settings, for a finger ``base_width_mm``
        (mm) wide at its base."""
        return InputWindow(
            base_width_mm,
            self.crop_x_mm,
            self.crop_y_mm,
            self.base_band,
            {k: getattr(self, k) for k in SEGMENT_KEYS},
        )

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
    return (
        f"{scene.get('object', 'unknown')}_{scene.get('material', 'unknown')}"
        f"_h{float(scene.get('height_mm', 0)):g}_p{float(scene.get('pitch_deg', 0)):g}"
    )
