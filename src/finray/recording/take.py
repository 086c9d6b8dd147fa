"""A lab take on disk (the recording format) and its checked contents.

One folder per take:

- the video: one file PyAV decodes (``.mp4``, ``.avi``, ``.mov``, ``.mkv``, ``.webm``;
  or the file ``take.json`` names under ``video``), frame times from the stream's time
  stamps; or a folder ``frames/`` of PNG/JPEG images with ``frames.csv`` beside it
  (columns ``frame``: the file name in ``frames/``, ``t_s``: camera time, s);
- ``forces.csv``: the sensor's log, ``t_s`` (its own clock, s) and any of ``fx_N``,
  ``fy_N``, ``fz_N`` (N), at its own rate;
- ``take.json``: ``object``, ``contact_height_mm``, ``push_axis`` (the sensor column
  along the push, with its sign: ``"fz"``, ``"-fz"``), ``camera`` (``{}``,
  ``{"px_per_mm": ..}`` or ``{"intrinsics": {"fx", "fy", "cx", "cy", ...}}``, px) and,
  optionally, ``finger_colour`` (see :mod:`finray.recording.colour`) and ``rotate_deg``
  (0, 90, 180 or 270: each frame is turned this much counter-clockwise before anything
  else, so that the finger's base is at the bottom, as ingest expects).

Every check fails with :class:`TakeError`, whose text is one line naming the file.
"""

from __future__ import annotations

import json
import os
from dataclasses import dataclass, field
from pathlib import Path, PurePath

import numpy as np

from ..media import VIDEO_SUFFIXES, MediaError, one_line, read_image, video_frames, video_info
from ..errors import TakeError
from ..schema import non_finite

FORCE_COLUMNS = ("fx_N", "fy_N", "fz_N")
#: Fewest sensor samples and frames a take may have (a clock offset needs a shape).
MIN_SAMPLES = 10


_NUMBER = {"type": "number"}
_RANGE3 = {"type": "array", "items": _NUMBER, "minItems": 3, "maxItems": 3}
#: a focal length or principal point (px): a camera's frame is at most tens of
#: thousands of pixels across
_PX = {"type": "number", "minimum": 0, "maximum": 1e5}
COLOUR_NAMES = ("red", "orange", "yellow", "green", "cyan", "blue", "purple", "magenta")

TAKE_SCHEMA = {
    "type": "object",
    "required": ["object", "contact_height_mm", "push_axis"],
    "properties": {
        "object": {"type": "string", "minLength": 1},
        # on the finger: a Fin Ray finger is tens to a few hundred mm long
        "contact_height_mm": {"type": "number", "exclusiveMinimum": 0, "maximum": 1000},
        "push_axis": {"type": "string", "pattern": "^[+-]?f[xyz]$"},
        "camera": {
            "type": "object",
            "properties": {
                # from a wide view (0.1 px/mm) to a macro lens (1000 px/mm, 1 um pixels)
                "px_per_mm": {"type": "number", "minimum": 0.1, "maximum": 1000},
                "intrinsics": {
                    "type": "object",
                    "required": ["fx", "fy", "cx", "cy"],
                    "properties": {
                        **{k: {**_PX, "exclusiveMinimum": 0} for k in ("fx", "fy")},
                        **{k: _PX for k in ("cx", "cy")},
                    },
                },
            },
            "additionalProperties": True,
        },
        "finger_colour": {
            "oneOf": [
                {"type": "string", "enum": list(COLOUR_NAMES)},
                {
                    "type": "object",
                    "required": ["space", "lo", "hi"],
                    "properties": {
                        "space": {"enum": ["hsv", "hcv", "lab"]},
                        "lo": _RANGE3,
                        "hi": _RANGE3,
                    },
                    "additionalProperties": False,
                },
            ]
        },
        "video": {"type": "string", "minLength": 1},
        "rotate_deg": {"enum": [0, 90, 180, 270]},
    },
    "additionalProperties": True,  # a rig may note more (operator, emulated, ...)
}


def read_take_json(path: Path) -> dict:
    """``take.json`` checked against :data:`TAKE_SCHEMA`; ``camera`` defaults to ``{}``."""
    import jsonschema

    if not path.is_file():
        raise TakeError(f"{path} is missing (object, contact_height_mm, push_axis, camera)")
    try:
        meta = json.loads(path.read_text())
    except (json.JSONDecodeError, UnicodeDecodeError) as exc:
        raise TakeError(f"{path} is not JSON ({one_line(exc)})") from None
    # JSON's NaN and Infinity are numbers to the schema: name them before its ranges do
    bad = non_finite(meta)
    if bad is not None:
        where = "/".join(str(k) for k in bad[0]) or "top level"
        raise TakeError(f"{path}: {where}: must be a finite number, got {bad[1]}")
    err = jsonschema.exceptions.best_match(
        jsonschema.Draft202012Validator(TAKE_SCHEMA).iter_errors(meta)
    )
    if err is not None:
        where = "/".join(str(p) for p in err.absolute_path) or "top level"
        raise TakeError(f"{path}: {where}: {err.message}")
    video = meta.get("video")
    if video is not None and not inside(path.parent, video):
        raise TakeError(f"{path}: video: {video!r} is not a file in the take's own folder")
    meta.setdefault("camera", {})
    return meta


def inside(folder: Path, name) -> bool:
    """Whether ``name`` (a path a take's file gives) is a file under ``folder``: relative,
    without ``..``, and, links followed, still under it."""
    v = PurePath(str(name))
    if v.is_absolute() or ".." in v.parts or not v.parts:
        return False
    real, top = Path(os.path.realpath(folder / v)), Path(os.path.realpath(folder))
    return real == top or top in real.parents


def _times(values: np.ndarray, name: str) -> np.ndarray:
    """``values`` as strictly increasing finite seconds, or a TakeError naming the line
    (line 1 is the header)."""
    t = np.asarray(values, dtype=np.float64)
    bad = np.flatnonzero(~np.isfinite(t))
    if len(bad):
        raise TakeError(f"{name}: t_s is not a number at line {bad[0] + 2}")
    step = np.diff(t)
    back = np.flatnonzero(step <= 0)
    if len(back):
        i = back[0] + 1
        raise TakeError(
            f"{name}: time is not increasing at line {i + 2} (t_s {t[i]:g} after {t[i - 1]:g})"
        )
    return t


def _read_csv(path: Path, required: tuple[str, ...]):
    import pandas as pd

    if not path.is_file():
        raise TakeError(f"{path} is missing")
    try:
        df = pd.read_csv(path, skipinitialspace=True)
    except (pd.errors.ParserError, pd.errors.EmptyDataError, UnicodeDecodeError) as exc:
        raise TakeError(f"{path} is not a readable CSV ({one_line(exc)})") from None
    df.columns = [str(c).strip() for c in df.columns]
    for col in required:
        if col not in df.columns:
            raise TakeError(f"{path}: no column {col!r} (columns: {', '.join(df.columns)})")
    if len(df) < MIN_SAMPLES:
        raise TakeError(f"{path}: too few samples ({len(df)} rows; at least {MIN_SAMPLES})")
    return df


def read_forces(path: Path, push_axis: str) -> tuple[np.ndarray, np.ndarray]:
    """Sensor times (s, its clock) and the push force (N, signed by ``push_axis``) of
    ``forces.csv``."""
    import pandas as pd

    sign = -1.0 if push_axis.startswith("-") else 1.0
    col = push_axis.lstrip("+-") + "_N"
    df = _read_csv(path, ("t_s", col))
    t = _times(pd.to_numeric(df["t_s"], errors="coerce").to_numpy(), str(path))
    f = pd.to_numeric(df[col], errors="coerce").to_numpy(dtype=np.float64)
    bad = np.flatnonzero(~np.isfinite(f))
    if len(bad):
        raise TakeError(f"{path}: {col} is not a number at line {bad[0] + 2}")
    return t, sign * f


@dataclass
class FrameSource:
    """The frames of a take: ``kind`` ("video" or "frames"), ``path``, ``n_frames`` (as
    the container or frames.csv says; a video may deliver fewer) and ``rate_hz``
    (nominal). Iterate for ``(index, t_s, rgb (H, W, 3) uint8 | None)``; ``None``: a
    frame that cannot be read, kept with its time so that nothing is lost
    (:mod:`finray.media`'s policy: a video's lost frames come after its others), its
    reason in ``lost``; a video that cannot be read on after its first frames ends there. ``rotate_deg``: each frame turned
    counter-clockwise by this much (take.json's ``rotate_deg``)."""

    kind: str
    path: Path
    n_frames: int
    rate_hz: float
    _times: np.ndarray | None = None
    _files: list | None = None
    rotate_deg: int = 0
    lost: list = field(default_factory=list)  # why frames were lost (one line each)

    def __iter__(self):
        frames = self._video() if self.kind == "video" else self._folder()
        turns = (int(self.rotate_deg) // 90) % 4
        if not turns:
            return frames
        return (
            (k, t, None if rgb is None else np.ascontiguousarray(np.rot90(rgb, turns)))
            for k, t, rgb in frames
        )

    def _folder(self):
        for k, (t, f) in enumerate(zip(self._times, self._files)):
            rgb, why = read_image(f, colour=True)
            if why is not None:
                self.lost.append(f"{f.name}: {why}")
            yield k, float(t), rgb

    def _video(self):
        try:
            frames = video_frames(self.path, threads=True)
        except MediaError as exc:
            raise TakeError(str(exc)) from None
        n_read = 0
        for f in frames:
            if f.rest and n_read == 0:
                raise TakeError(f"{self.path} is not a readable video ({f.error})")
            if f.error is not None:
                self.lost.append(f"frame {f.index}: {f.error}")
                if f.rest:  # the frames so far are kept
                    return
            n_read += f.image is not None
            yield f.index, float(f.t_s if f.t_s is not None else f.index / self.rate_hz), f.image


def open_frames(take: Path, meta: dict) -> FrameSource:
    """The take's video (``meta["video"]`` or the one video file in ``take``) or its
    ``frames/`` folder with ``frames.csv``."""
    if meta.get("video"):
        videos = [take / meta["video"]]
        if not videos[0].is_file():
            raise TakeError(f"{videos[0]} (the video of take.json) is missing")
    else:
        videos = sorted(p for p in take.iterdir() if p.suffix.lower() in VIDEO_SUFFIXES)
    if len(videos) > 1:
        raise TakeError(
            f"{take}: {len(videos)} videos ({', '.join(p.name for p in videos)}); "
            "name the take's in take.json under 'video'"
        )
    if videos:
        try:
            info = video_info(videos[0])
        except MediaError as exc:
            raise TakeError(str(exc)) from None
        if not info.rate_hz:
            raise TakeError(f"{videos[0]}: the video stream has no frame rate")
        return FrameSource(
            "video",
            videos[0],
            info.n_frames,
            info.rate_hz,
            rotate_deg=int(meta.get("rotate_deg", 0)),
        )
    folder = take / "frames"
    if not folder.is_dir():
        raise TakeError(f"{take}: no video ({', '.join(VIDEO_SUFFIXES)}) and no frames/ folder")
    import pandas as pd

    df = _read_csv(take / "frames.csv", ("frame", "t_s"))
    t = _times(pd.to_numeric(df["t_s"], errors="coerce").to_numpy(), str(take / "frames.csv"))
    names = [str(name).strip() for name in df["frame"]]
    outside = [n for n in names if not inside(folder, n)]
    if outside:
        raise TakeError(
            f"{take / 'frames.csv'}: frame {outside[0]!r} is not a file in {folder} "
            f"({len(outside)} such)"
        )
    files = [folder / n for n in names]
    missing = [f.name for f in files if not f.is_file()]
    if missing:
        raise TakeError(
            f"{take / 'frames.csv'}: {len(missing)} frames not in {folder} (first {missing[0]})"
        )
    return FrameSource(
        "frames",
        folder,
        len(files),
        float(1.0 / np.median(np.diff(t))),
        t,
        files,
        rotate_deg=int(meta.get("rotate_deg", 0)),
    )
