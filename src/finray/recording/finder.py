"""Finding the finger in a camera's frames: the one way that ``finray predict`` (files,
videos, cameras, streams), ``finray ingest`` and the live loop share.

A :class:`FingerFinder` tells the finger from the rest of a frame in one of two ways:

- ``"colour"``: the finger's colour range (:mod:`finray.recording.colour`), given (a
  name such as ``orange``, a range, or a saved segmentation: ``segmentation.json`` of
  ``finray predict``, ``ingest.json`` of ``finray ingest``, ``calibration.json`` of
  ``finray calibrate``) or learned from the first frames of a take or a stream
  (:func:`learn_finder`);
- ``"grey"``: the dataset stage's grey-level threshold
  (:func:`finray.dataset.imageops.segment` with the model's settings,
  ``DatasetParams.foreground``), which is how the renders the model was trained on are
  segmented, pixel for pixel.

Learned (``auto``): the colour is learned from the first frames; where everything on
the finger's side of the grey threshold is the finger the colour finds there (IoU >=
:data:`AGREE_IOU`: a render, a bright finger alone on a dark background) the grey
threshold is kept, so that renders are segmented as in training; elsewhere (a camera's
view of a lit room, a bright object that will touch the finger) the colour is used;
where nothing in view is coloured, the grey threshold.

Each frame's mask comes with a confidence in [0, 1]: the share of the frame's pixels
of the finger's colour (or grey side) that the kept finger holds. Clutter of the
finger's colour, or a background on the finger's side of the threshold, lowers it.
"""

from __future__ import annotations

import json
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np

from ..dataset.imageops import segment
from ..errors import BadInput, FrameError
from .colour import NAMED_HUES, ColourRange, learn_colour, segment_finger

MODES = ("auto", "colour", "grey")
#: IoU of the grey threshold's mask with the colour's above which ``auto`` keeps the grey
#: threshold (the training's own segmentation)
AGREE_IOU = 0.9
#: Frames of a take or stream the colour is learned from.
LEARN_FRAMES = 5


@dataclass(frozen=True)
class FingerFinder:
    """How the finger is told from the rest (see the module's text). ``mode``:
    ``"colour"`` (``colour``; the finger is found on every ``stride``-th row and column,
    specks up to ``min_object_frac`` of the frame dropped, holes up to ``max_hole_frac``
    filled: :func:`~finray.recording.colour.segment_finger`) or ``"grey"``
    (``segment_kw``, the model's threshold settings; ``stride``: ``roi_stride`` of
    :func:`~finray.dataset.imageops.segment`). ``source``: how it was chosen (one line)."""

    mode: str
    colour: ColourRange | None = None
    segment_kw: dict = field(default_factory=dict)
    stride: int = 4
    min_object_frac: float = 1e-3
    max_hole_frac: float = 1e-5
    source: str = ""

    def __post_init__(self):
        if self.mode not in ("colour", "grey"):
            raise ValueError(f"a finger finder's mode is colour or grey, not {self.mode!r}")
        if self.mode == "colour" and self.colour is None:
            raise ValueError("a colour finger finder needs its colour range")

    @classmethod
    def grey(
        cls, segment_kw: dict | None = None, stride: int = 1, source: str = ""
    ) -> "FingerFinder":
        """The grey-level threshold with the model's settings (``segment_kw``: threshold,
        foreground, min_object_frac, max_hole_frac, keep_largest)."""
        return cls(
            "grey",
            None,
            dict(segment_kw or {}),
            int(stride),
            source=source or "grey-level threshold (the renders' segmentation)",
        )

    def find(self, frame: np.ndarray) -> tuple[np.ndarray | None, float]:
        """The finger's mask (H, W) bool, or None where it is not found, and the mask's
        confidence in [0, 1] (the share of the candidate pixels it holds)."""
        frame = np.asarray(frame)
        stats: dict = {}
        if self.mode == "grey":
            if frame.ndim not in (2, 3):
                raise FrameError(f"expected an (H, W) or (H, W, 3) image, got shape {frame.shape}")
            mask = segment(frame, **self.segment_kw, roi_stride=self.stride, stats=stats)
        else:
            if frame.ndim != 3 or frame.shape[2] < 3:
                raise FrameError(f"expected an (H, W, 3) colour frame, got shape {frame.shape}")
            mask = segment_finger(
                frame[..., :3],
                self.colour,
                self.stride,
                self.min_object_frac,
                self.max_hole_frac,
                stats=stats,
            )
            if mask is None:
                return None, 0.0
        kept = np.count_nonzero(mask)
        if kept == 0:
            return None, 0.0
        return mask, float(min(1.0, kept / mask.size / max(stats["candidate_frac"], 1e-12)))

    def mask(self, frame: np.ndarray) -> np.ndarray:
        """The finger's mask (H, W) bool; :class:`FrameError` where it is not found."""
        mask, _ = self.find(frame)
        if mask is None:
            raise FrameError(f"no finger found ({self.describe()})")
        return mask

    def describe(self) -> str:
        if self.mode == "grey":
            return self.source
        return f"colour {self.colour.describe()} ({self.source or self.colour.source})"

    def to_dict(self) -> dict:
        """What ``segmentation.json`` keeps (read back by :func:`finder_from_spec`)."""
        out = {"mode": self.mode, "stride": self.stride, "source": self.source}
        if self.mode == "colour":
            out.update(
                colour=self.colour.to_dict(),
                min_object_frac=self.min_object_frac,
                max_hole_frac=self.max_hole_frac,
            )
        else:
            out["segment"] = self.segment_kw
        return out


def colour_finder(
    colour: ColourRange,
    stride: int = 4,
    min_object_frac: float = 1e-3,
    max_hole_frac: float = 1e-5,
    source: str = "",
) -> FingerFinder:
    """A colour finder with ``finray ingest``'s sizes by default."""
    return FingerFinder(
        "colour",
        colour,
        {},
        int(stride),
        float(min_object_frac),
        float(max_hole_frac),
        source or colour.source,
    )


def learn_finder(
    frames,
    grey: FingerFinder,
    stride: int = 4,
    min_object_frac: float = 1e-3,
    max_hole_frac: float = 1e-5,
) -> FingerFinder:
    """``auto``: the finder for a take or stream from its first frames (see the
    module's text); ``grey``: the model's grey-level finder."""
    colours = [np.asarray(f)[..., :3] for f in frames if np.asarray(f).ndim == 3]
    if not colours:
        return grey
    learned = learn_colour(colours, stride)
    if learned is None:
        return FingerFinder.grey(
            grey.segment_kw,
            grey.stride,
            "grey-level threshold (nothing coloured in the first frames)",
        )
    by_colour = colour_finder(
        learned,
        stride,
        min_object_frac,
        max_hole_frac,
        f"learned from the first {len(colours)} frames",
    )
    a, _ = by_colour.find(colours[0])
    # everything on the finger's side of the threshold, not only its largest part: an
    # object apart now may touch the finger later, and the threshold would then join them
    b = segment(colours[0], **{**grey.segment_kw, "keep_largest": False}, roi_stride=grey.stride)
    if a is not None and b.any():
        iou = np.count_nonzero(a & b) / max(np.count_nonzero(a | b), 1)
        if iou >= AGREE_IOU:
            return FingerFinder.grey(
                grey.segment_kw,
                grey.stride,
                f"grey-level threshold (the same finger as its learned colour, IoU {iou:.2f})",
            )
    return by_colour


def finder_from_spec(spec, stride: int = 4) -> FingerFinder:
    """A colour finder from what a user gives (``--finger-colour``): a colour name
    (:data:`~finray.recording.colour.NAMED_HUES`), a range as JSON (``{"space": "hsv",
    "lo": [...], "hi": [...]}``), or a saved segmentation (a JSON file:
    ``segmentation.json`` of ``finray predict``, ``ingest.json`` of ``finray ingest``,
    ``calibration.json`` of ``finray calibrate``). One line (:class:`BadInput`) on
    anything else."""
    if isinstance(spec, dict):
        return _from_saved(spec, "given", stride)
    text = str(spec).strip()
    if text in NAMED_HUES:
        return colour_finder(ColourRange.from_take(text), stride)
    if text.startswith("{"):
        try:
            return _from_saved(json.loads(text), "given", stride)
        except json.JSONDecodeError as exc:
            raise BadInput(f"finger colour {text!r} is not JSON ({exc.msg})") from None
    path = Path(text)
    if path.is_file():
        try:
            return _from_saved(json.loads(path.read_text()), str(path), stride)
        except (json.JSONDecodeError, UnicodeDecodeError):
            raise BadInput(f"{path} is not a JSON file of a segmentation") from None
    raise BadInput(
        f"finger colour {text!r}: not a colour name ({', '.join(NAMED_HUES)}), a "
        "JSON range or a segmentation file (segmentation.json, ingest.json, "
        "calibration.json)"
    )


def _from_saved(d: dict, where: str, stride: int) -> FingerFinder:
    """A finder from a saved segmentation's dict (see :func:`finder_from_spec`)."""
    try:
        if "segment" in d and isinstance(d["segment"], dict) and "colour" in d["segment"]:
            d = d["segment"]  # calibration.json
        if d.get("mode") == "grey":
            return FingerFinder.grey(d.get("segment"), int(d.get("stride", 1)), f"saved: {where}")
        if "colour" in d:  # segmentation.json, ingest.json, calibration.json's segment
            colour = ColourRange.from_take(d["colour"])
            return colour_finder(
                colour,
                int(d.get("stride", stride)),
                float(d.get("min_object_frac", 1e-3)),
                float(d.get("max_hole_frac", 1e-5)),
                f"saved: {where}",
            )
        if {"space", "lo", "hi"} <= set(d):
            return colour_finder(ColourRange.from_take(d), stride, source=f"given: {where}")
    except (KeyError, TypeError, ValueError) as exc:
        raise BadInput(f"{where}: not a segmentation ({exc})") from None
    raise BadInput(f"{where}: holds no finger colour (no 'colour', 'segment' or range)")
