"""The network's input window: where in a camera frame the network looks, and how the
finger is found there. One home for what the dataset's camera views, ``finray ingest``,
the :class:`~finray.predictor.Predictor` and a calibration each need, so that one frame
gives one network input through every path.

The window is anchored on the finger itself (:func:`~finray.dataset.imageops.base_anchored_box`):
the widest of the mask's lowest rows is the clamped base, its width is ``base_width_mm``
(mm), which fixes the scale (px/mm), and ``crop_x_mm`` x ``crop_y_mm`` (mm from the base's
left edge and bottom) is cut around it. A model carries its window in ``model.ts.json``
(``preprocess``, :meth:`InputWindow.to_json`).
"""

from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np

from ..schema import schema_default
from .imageops import base_anchored_box, silhouette_input

#: The base is the widest of at least this many of the mask's lowest rows: a compressed
#: video's ragged bottom row (colour blocks at the clamp) must not set the scale. The same
#: on renders, camera frames and takes; ``base_band`` of the mask's height is the larger
#: on any finger taller than 4 / base_band rows.
BASE_ROWS = 4

#: The grey-level segmentation of the renders (config ``dataset``), which a model's
#: predictor applies by default.
SEGMENT_KEYS = ("threshold", "foreground", "min_object_frac", "max_hole_frac", "keep_largest")


def _segment_defaults() -> dict:
    return {k: schema_default(f"dataset.{k}") for k in SEGMENT_KEYS}


@dataclass(frozen=True)
class InputWindow:
    """The base-anchored window (mm) and the renders' segmentation settings."""

    #: The finger's width at the clamped base (mm): the frame's scale.
    base_width_mm: float = schema_default("finger.base_width_mm")
    #: The window from the base's left edge (x, mm) and bottom (y, mm).
    crop_x_mm: tuple[float, float] = schema_default("dataset.crop_x_mm", tuple)
    crop_y_mm: tuple[float, float] = schema_default("dataset.crop_y_mm", tuple)
    #: The base is the widest row among the lowest ``base_band`` of the mask's height (a
    #: rolled or pitched camera slants its bottom edge over several rows).
    base_band: float = schema_default("dataset.base_band")
    #: Grey-level segmentation (:func:`~finray.dataset.imageops.segment`'s keywords).
    segment: dict = field(default_factory=_segment_defaults)

    def __post_init__(self):
        object.__setattr__(self, "crop_x_mm", tuple(float(v) for v in self.crop_x_mm))
        object.__setattr__(self, "crop_y_mm", tuple(float(v) for v in self.crop_y_mm))
        object.__setattr__(self, "base_width_mm", float(self.base_width_mm))
        object.__setattr__(self, "base_band", float(self.base_band))
        for name in ("crop_x_mm", "crop_y_mm"):
            lo, hi = getattr(self, name)
            if not (np.isfinite(lo) and np.isfinite(hi) and lo < hi):
                raise ValueError(f"{name}: ({lo}, {hi}) is not an ordered span of mm")
        if not (np.isfinite(self.base_width_mm) and self.base_width_mm > 0):
            raise ValueError(f"base_width_mm: {self.base_width_mm} is not a width in mm")
        unknown = set(self.segment) - set(SEGMENT_KEYS)
        if unknown:
            raise ValueError(f"segment: unknown keys {sorted(unknown)} (known: {SEGMENT_KEYS})")

    @classmethod
    def from_sections(cls, finger: dict | None, dataset: dict | None) -> InputWindow:
        """From the config's ``finger`` and ``dataset`` sections (missing keys: the schema's
        defaults)."""
        finger, dataset = finger or {}, dataset or {}
        kw = {k: dataset[k] for k in ("crop_x_mm", "crop_y_mm", "base_band") if k in dataset}
        if "base_width_mm" in finger:
            kw["base_width_mm"] = finger["base_width_mm"]
        return cls(
            **kw,
            segment={
                **_segment_defaults(),
                **{k: dataset[k] for k in SEGMENT_KEYS if k in dataset},
            },
        )

    @classmethod
    def from_json(cls, pre: dict) -> tuple[InputWindow, list[str]]:
        """From a model's ``preprocess`` block: the window and the keys it lacks (an older
        export), each taken from the schema's defaults; ``base_band`` lacking is 0 (the
        lowest row, as exports before it were cropped)."""
        missing = [
            k
            for k in ("base_width_mm", "crop_x_mm", "crop_y_mm", "base_band", "segment")
            if k not in pre
        ]
        kw = {k: pre[k] for k in ("base_width_mm", "crop_x_mm", "crop_y_mm") if k in pre}
        segment = {**_segment_defaults(), **pre.get("segment", {})}
        return cls(**kw, base_band=pre.get("base_band", 0.0), segment=segment), missing

    def to_json(self) -> dict:
        """The ``preprocess`` block of ``model.ts.json``."""
        return {
            "base_width_mm": self.base_width_mm,
            "crop_x_mm": list(self.crop_x_mm),
            "crop_y_mm": list(self.crop_y_mm),
            "base_band": self.base_band,
            "segment": dict(self.segment),
        }

    def box(self, mask: np.ndarray) -> tuple[float, float, float, float]:
        """The window ``(col0, row0, col1, row1)`` in pixel edges of ``mask`` (an
        :class:`~finray.dataset.imageops.EmptyMaskError` where it holds no finger)."""
        return base_anchored_box(
            mask, self.base_width_mm, self.crop_x_mm, self.crop_y_mm, BASE_ROWS, self.base_band
        )

    def inputs(self, mask: np.ndarray, sizes, box=None) -> dict[tuple[int, int], np.ndarray]:
        """The network inputs (H, W) uint8 of ``mask`` at each of ``sizes`` (height, width)."""
        box = self.box(mask) if box is None else box
        return {tuple(s): silhouette_input(mask, box, tuple(s)) for s in sizes}
