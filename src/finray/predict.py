"""``finray predict``: every frame of an image, a folder, a video or a live source
(camera, network stream) through a :class:`~finray.predictor.Predictor` into an output
folder: ``forces.csv`` written row by row, stress maps, annotated frames or video; a
run's files are moved into place only when it ends, so nothing half-written is left.
:class:`Predictor` is re-exported here, the API a control loop imports.
"""
from __future__ import annotations

from dataclasses import dataclass, field
from pathlib import Path

import numpy as np

from .errors import DeviceInputError, FrameError, InputError  # noqa: F401 - callers import them here
from .media import (IMAGE_SUFFIXES, VIDEO_SUFFIXES, LiveFrames, MediaError, is_live,
                    read_image, video_frames)
from .predictor import Predictor  # noqa: F401 - the API: finray.predict.Predictor


def read_frames(path: str | Path):
    """``(name, frame, t_s)`` of every frame of an image, a folder of images or a video
    (read with PyAV), lazily; ``t_s`` the frame's time in a video (s, from its time
    stamps), None for images. A frame that cannot be read comes as ``(name,
    FrameError, t_s)``, so that the caller can report it and go on; a source that
    cannot be read at all raises :class:`InputError` here (a live source: when it is
    opened, see :class:`_Live`)."""
    if is_live(path):
        return _Live(path)
    path = Path(path)
    if path.is_dir():
        files = sorted(p for p in path.iterdir() if p.suffix.lower() in IMAGE_SUFFIXES)
        if not files:
            raise InputError(f"no images ({', '.join(IMAGE_SUFFIXES)}) in {path}")
        return ((p.name, _read_image(p), None) for p in files)
    if not path.is_file():
        raise InputError(f"{path} does not exist")
    if path.suffix.lower() in VIDEO_SUFFIXES:
        return _video_frames(path)
    return iter([(path.name, _read_image(path), None)])


class _Live:
    """``(name, rgb | FrameError, t_s)`` of a live source's frames (:class:`finray.media.
    LiveFrames`: the newest frame each time, the ones in between dropped), named
    ``live_<k>``, k the frame's count since it opened. Opened by :meth:`open` (by
    :func:`predict_files` once the model is loaded: a source opened earlier would send
    frames that the loading drops)."""

    def __init__(self, source):
        self.source, self.frames = source, None

    def open(self) -> None:
        try:
            self.frames = LiveFrames(self.source)
        except MediaError as exc:
            raise InputError(str(exc)) from None

    def __iter__(self):
        if self.frames is None:
            self.open()
        for f in self.frames:
            name = f"live_{f.index:06d}" if not f.rest else "live (rest)"
            yield name, (f.image if f.error is None else FrameError(f.error)), f.t_s

    def close(self) -> None:
        if self.frames is not None:
            self.frames.close()


def _read_image(path: Path) -> np.ndarray | FrameError:
    """The image (H, W[, C]) of a file, or the :class:`FrameError` saying why not."""
    img, why = read_image(path)
    return img if why is None else FrameError(why)


def _video_frames(path: Path):
    """``(name, rgb (H, W, 3) uint8 | FrameError, t_s)`` of each frame of a video
    (:func:`finray.media.video_frames`: a lost frame comes as a FrameError in its
    place); names ``<stem>_<k:05d>``, k the frame's rank in the stream (from its time
    stamp, so that a lost frame leaves its rank out; by order where a frame has none),
    ``<stem> (rest)`` for a stream that cannot be read on."""
    try:
        frames = video_frames(path)
    except MediaError as exc:
        raise InputError(str(exc)) from None
    count = iter(range(1 << 62))  # ranks by order where a time stamp is missing

    def named():
        for f in frames:
            if f.rest:
                yield f"{path.stem} (rest)", FrameError(f.error), f.t_s
                continue
            name = f"{path.stem}_{f.rank if f.rank is not None else next(count):05d}"
            yield name, (f.image if f.error is None else FrameError(f.error)), f.t_s
    return named()


def _colour_segmenter(spec: dict):
    """The finger's mask of a frame as ``finray ingest`` found it in the calibration's
    takes (their learned or given colour, :func:`finray.recording.segment_finger`)."""
    from .recording.colour import ColourRange, segment_finger

    colour = ColourRange.from_take(spec["colour"])

    def seg(frame):
        frame = np.asarray(frame)
        if frame.ndim != 3:
            raise FrameError(f"expected an (H, W, 3) colour frame, got shape {frame.shape}")
        mask = segment_finger(frame[..., :3], colour, spec["stride"], spec["min_object_frac"],
                              spec["max_hole_frac"])
        if mask is None:
            raise FrameError(f"no finger of the calibrated colour ({colour.describe()})")
        return mask

    return seg


#: what a run of :func:`predict_files` leaves in its folder, besides the per-frame files
RUN_FILES = ("forces.csv", "forces.png", "annotated.mp4")


def run_files(out_dir) -> list[Path]:
    """The files a run of :func:`predict_files` leaves in ``out_dir``: ``forces.csv``, the
    stress maps (``*_stress.exr``, ``*_stress.png``) and, annotated, ``*_annotated.png``,
    ``annotated.mp4`` and ``forces.png``."""
    out_dir = Path(out_dir)
    if not out_dir.is_dir():
        return []
    return sorted([f for f in (out_dir / n for n in RUN_FILES) if f.is_file()]
                  + [f for g in ("*_stress.exr", "*_stress.png", "*_annotated.png")
                     for f in out_dir.glob(g)])


def predict_files(model_path, source, out_dir, threads: int = 1, backend: str = "auto",
                  force_only: bool = False, on_frame=None, on_skip=None,
                  device: str = "auto", calibration: dict | None = None,
                  overwrite: bool = False, annotate: bool = False, maps: bool = True,
                  on_annotated=None) -> dict:
    """Predict every frame of ``source`` (image, folder of images, video, or a live source:
    :func:`finray.media.is_live`, read until it ends or Ctrl-C) into
    ``out_dir``: ``forces.csv`` (``frame,fx_N``; also ``fy_N`` for a model that predicts
    it, and ``contact_mm``, the contact height in mm, for a model with the contact head
    (:attr:`Predictor.has_contact`); while it runs ``forces.csv.part``, a row appended and flushed as each frame
    completes; for a video also ``t_s``, each frame's time) and, per frame unless
    ``force_only``, the stress map as EXR and as a coloured PNG. ``annotate``
    (:mod:`finray.annotate`): each frame with its stress map drawn over the finger, the
    force arrow and values, the contact height's mark on the finger's front edge
    (``<name>_annotated.png``; a video's frames go into
    ``annotated.mp4`` instead, at its frame rate) and, for more than one frame, the
    force against time (``forces.png``). ``maps=False``: no per-frame stress map files
    (a long video or a stream; the annotated frames still show the maps).
    ``on_annotated(rgb)`` gets each annotated frame too (a window, ``--show``).

    A frame that cannot be predicted (unreadable, not an image, no finger) is skipped:
    ``on_skip(name, message)`` is called and the run goes on. ``on_frame(row)`` gets
    each row ``{"frame", "fx_N"[, "fy_N"][, "contact_mm"]}`` as it completes. Returns ``{"rows": [...],
    "skipped": [(name, message), ...], "interrupted"}`` (a live source ended by Ctrl-C),
    for a live source also ``received`` and ``dropped`` (frames it sent; frames that
    came while the network was busy). With ``calibration`` (a ``calibration.json`` of
    :func:`finray.calibration.calibrate_takes`, its model's heads' spread per frame) rows
    and columns also have ``force_N``, ``lo_N``, ``hi_N`` (the calibrated force's median
    and predictive interval, N) and ``level``. Raises :class:`InputError` for a missing
    model or source, a ``device`` this machine does not have (:class:`Predictor`), a
    single image that cannot be predicted, and when no frame at all could be, and for an
    ``out_dir`` that holds another run's files (:func:`run_files`) unless ``overwrite``
    (which removes them first). Nothing half-written is left: the table is written as
    ``forces.csv.part`` and moved into place at the end (also when interrupted, with the
    frames done so far); a run that predicts no frame leaves no table and no maps.
    """
    out_dir = Path(out_dir)
    old = run_files(out_dir)
    if old and not overwrite:
        raise InputError(f"{out_dir} holds another run's results ({len(old)} files: "
                         f"{', '.join(f.name for f in old[:2])}{', ...' if len(old) > 2 else ''}); "
                         "give --overwrite to replace them, or another --out")
    if annotate and force_only:
        raise InputError("annotating draws the stress map: leave out force-only")
    frames = read_frames(source)  # checks a file source before the model loads
    live = isinstance(frames, _Live)
    one_image = not live and Path(source).is_file() and Path(source).suffix.lower() not in VIDEO_SUFFIXES
    video = live or (Path(source).is_file() and Path(source).suffix.lower() in VIDEO_SUFFIXES)
    run = _Run(frames, source, out_dir, one_image, video, force_only, on_frame, on_skip,
               calibration, annotate, maps, on_annotated)
    try:
        return _predict_files(run, model_path, old, threads, backend, device)
    finally:
        if live:
            frames.close()


@dataclass
class _Run:
    """What one :func:`predict_files` run reads, writes and reports."""

    frames: object
    source: object
    out_dir: Path
    one_image: bool
    video: bool
    force_only: bool
    on_frame: object
    on_skip: object
    calibration: dict | None
    annotate: bool
    maps: bool
    on_annotated: object
    part: Path | None = None
    written: list = field(default_factory=list)  # files made so far (removed on failure)


def _predict_files(run: _Run, model_path, old: list, threads, backend, device) -> dict:
    """:func:`predict_files` once its source is open: the model loaded, the table written
    as ``forces.csv.part`` and moved into place."""
    frames, out_dir = run.frames, run.out_dir
    p = Predictor(model_path, threads, backend, device)
    if isinstance(frames, _Live):  # opened once ready: no frames dropped while loading
        import matplotlib  # noqa: F401 - the loop's imports, done before the stream runs

        from .render import imageio  # noqa: F401
        p.warm_up()
        frames.open()
    for f in old:
        f.unlink()
    out_dir.mkdir(parents=True, exist_ok=True)
    part = run.part = out_dir / "forces.csv.part"
    try:
        out = _predict_into(p, run)
    except KeyboardInterrupt:
        if part.is_file() and sum(1 for _ in open(part)) > 1:
            part.replace(out_dir / "forces.csv")  # the frames done so far
        else:
            _remove(part, *run.written)
        raise
    except BaseException:
        _remove(part, *run.written)
        raise
    part.replace(out_dir / "forces.csv")
    return out


def _remove(*paths: Path) -> None:
    for f in paths:
        f.unlink(missing_ok=True)


def _predict_into(p, run: _Run) -> dict:
    """:func:`predict_files`'s loop (:func:`_predict_loop`), with the annotated video
    open around it and the force-against-time figure after it where ``annotate``."""
    frames, out_dir, written = run.frames, run.out_dir, run.written
    writer = None
    if run.annotate and run.video:
        from .annotate import VideoWriter
        from .media import video_info

        rate = frames.frames.rate_hz if isinstance(frames, _Live) else video_info(run.source).rate_hz
        writer = VideoWriter(out_dir / "annotated.mp4", rate or 30.0)
        written.append(writer.path)
    try:
        out = _predict_loop(p, run, writer)
    finally:
        if writer is not None:
            writer.close()
    if isinstance(frames, _Live):
        out.update(received=frames.frames.received, dropped=frames.frames.dropped)
    if run.annotate and len(out["rows"]) > 1:
        from .annotate import force_time_figure

        written.append(out_dir / "forces.png")
        force_time_figure(out["rows"], written[-1], title=Path(run.source).name)
    return out


def _predict_loop(p, run: _Run, writer) -> dict:
    """Rows into ``run.part``, stress maps (and annotated frames) into ``run.out_dir``
    (their paths appended to ``run.written``), annotated video frames to ``writer``."""
    frames, out_dir, written, calibration, video = (run.frames, run.out_dir, run.written,
                                                     run.calibration, run.video)
    import matplotlib

    matplotlib.use("Agg")
    from matplotlib import cm

    from .render.imageio import write_exr, write_png

    segment_frame = p.segment
    if calibration is not None and calibration.get("segment"):
        segment_frame = _colour_segmenter(calibration["segment"])
    rows, skipped, interrupted = [], [], False
    with open(run.part, "w") as table:
        cal_cols = ["force_N", "lo_N", "hi_N"] if calibration is not None else []
        time_cols = ["t_s"] if video else []
        out_cols = [*p.force_names, *(["contact_mm"] if p.has_contact else [])]
        table.write(",".join(["frame", *time_cols, *out_cols, *cal_cols]) + "\n")
        table.flush()
        try:
            for name, frame, t_s in frames:
                try:
                    if isinstance(frame, FrameError):
                        raise frame
                    mask = segment_frame(frame)
                    x = p.network_input(mask)
                    if run.force_only:
                        fvec, cvec = p.run_force_contact(x)
                    else:
                        stress, fvec, cvec = p.run_contact(x)
                        stress = stress[0, 0]
                    fvec, force, contact = fvec[0], float(fvec[0, 0]), float(cvec[0])
                except FrameError as exc:
                    msg = f"{name}: {exc}"
                    if run.one_image:
                        raise InputError(msg) from None
                    skipped.append((name, msg))
                    if run.on_skip is not None:
                        run.on_skip(name, msg)
                    continue
                if not run.force_only and run.maps:
                    stem = Path(name).stem
                    written += [out_dir / f"{stem}_stress.exr", out_dir / f"{stem}_stress.png"]
                    write_exr(written[-2], {"stress": stress.astype(np.float32)},
                              {"source": str(name), "force_N": force})
                    s = np.clip(stress / max(float(stress.max()), 1e-6), 0, 1)
                    write_png(written[-1], (cm.inferno(s)[..., :3] * 255).astype(np.uint8))
                row = {"frame": name, **({"t_s": t_s} if video else {}),
                       **{n: float(v) for n, v in zip(p.force_names, fvec)},
                       **({"contact_mm": contact} if p.has_contact else {})}
                if calibration is not None:
                    from .calibration import predictive, spread

                    members = p.run_members(x)[0]
                    band = predictive(calibration, [members.mean()], spread(members[:, None]),
                                      calibration.get("level", 0.9), seed=len(rows))
                    row.update(force_N=float(band["median"][0]), lo_N=float(band["lo"][0]),
                               hi_N=float(band["hi"][0]), level=band["level"])
                if run.annotate:
                    from .annotate import annotate_frame

                    cal = {k: row[k] for k in ("force_N", "lo_N", "hi_N", "level")} if calibration else None
                    label = name + (f"  t = {t_s:.3f} s" if t_s is not None else "")
                    img = annotate_frame(frame, mask, p.crop_box(mask), stress, row, cal, label,
                                         crop_y_mm=p.crop_y_mm,
                                         contact_min_force_N=p.contact_min_force_N)
                    if run.on_annotated is not None:
                        run.on_annotated(img)
                    if writer is not None:
                        writer.write(img)
                    else:
                        written.append(out_dir / f"{Path(name).stem}_annotated.png")
                        write_png(written[-1], img)
                times = ["" if t_s is None else f"{t_s:.6f}"] if video else []
                table.write(",".join([name, *times,
                                      *(f"{row[n]:.6g}" for n in [*out_cols, *cal_cols])]) + "\n")
                table.flush()  # a long video's forces can be read while it runs
                rows.append(row)
                if run.on_frame is not None:
                    run.on_frame(row)
        except KeyboardInterrupt:
            if not isinstance(frames, _Live):
                raise
            interrupted = True  # Ctrl-C is how a live source ends: the rows so far stand
    if not rows:
        if not skipped:
            raise InputError(f"{run.source} has no frames")
        raise InputError(f"no frame of {run.source} could be predicted ({len(skipped)} skipped)")
    return {"rows": rows, "skipped": skipped, "interrupted": interrupted}
