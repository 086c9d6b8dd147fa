"""``finray predict``: every frame of an image, a folder, a video or a live source
(camera, network stream) through a :class:`~finray.predictor.Predictor` into an output
folder: ``forces.csv`` written row by row, stress maps, annotated frames or video; a
run's files are moved into place only when it ends, so nothing half-written is left.
:class:`Predictor` is re-exported here, the API a control loop imports.
"""

from __future__ import annotations

from contextlib import nullcontext
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np

from .errors import DeviceInputError, FrameError, InputError  # noqa: F401 - callers import them here
from .media import (
    IMAGE_SUFFIXES,
    VIDEO_SUFFIXES,
    LiveFrames,
    MediaError,
    is_live,
    read_image,
    video_frames,
)
from .outputs import raised
from .predictor import Predictor  # the API: finray.predict.Predictor


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
        #: the frames still to come, where some were read ahead (:func:`choose_finder`)
        self.iterator = None

    def open(self) -> None:
        try:
            self.frames = LiveFrames(self.source)
        except MediaError as exc:
            raise InputError(str(exc)) from None

    def __iter__(self):
        return self.iterator if self.iterator is not None else self._read()

    def _read(self):
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


SEGMENTATIONS = ("auto", "colour", "grey")


def choose_finder(
    p: Predictor,
    frames,
    segmentation: str = "auto",
    finger_colour=None,
    calibration: dict | None = None,
    rest: bool = False,
):
    """How the finger is found in ``frames`` (:mod:`finray.recording.finder`), set as
    ``p.finder``; returns the frames to predict (the first ones read here put back).
    ``finger_colour`` (a name, a JSON range or a saved segmentation file): that colour;
    else a calibration's (``segment``: its takes' colour, as ingest found it); else
    ``segmentation``: ``"grey"`` the model's grey-level threshold, ``"colour"`` the
    colour learned from the first frames, ``"auto"`` learned, or the grey threshold
    where it finds the same finger (:func:`~finray.recording.finder.learn_finder`).
    ``rest`` (a video or a stream): where the colour is learned, its first frames' mask
    pixels (median) become ``p.rest_px``, the reference of the check ``grown``."""
    import itertools

    from .recording.finder import LEARN_FRAMES, finder_from_spec, learn_finder

    if segmentation not in SEGMENTATIONS:
        raise InputError(f"segmentation must be one of {SEGMENTATIONS}, not {segmentation!r}")
    if finger_colour is not None:
        p.finder = finder_from_spec(finger_colour)
        return frames
    if calibration is not None and calibration.get("segment"):
        p.finder = finder_from_spec(calibration["segment"])
        return frames
    if segmentation == "grey":
        return frames
    it = iter(frames)
    head = []
    for item in it:
        head.append(item)
        if sum(not isinstance(f, FrameError) for _, f, _ in head) >= LEARN_FRAMES:
            break
    images = [f for _, f, _ in head if not isinstance(f, FrameError)]
    finder = learn_finder(images, p.finder)
    if segmentation == "colour" and finder.mode != "colour":
        raise InputError(
            "no finger colour could be learned: nothing coloured in the first "
            f"{len(images)} frames (give --finger-colour)"
        )
    p.finder = finder
    if rest:
        px = [np.count_nonzero(m) for m, _ in map(finder.find, images) if m is not None]
        p.rest_px = float(np.median(px)) if px else None
    rest_frames = itertools.chain(head, it)
    if isinstance(frames, _Live):
        frames.iterator = rest_frames
        return frames
    return rest_frames


#: what a run of :func:`predict_files` leaves in its folder, besides the per-frame files
RUN_FILES = ("forces.csv", "forces.png", "annotated.mp4", "segmentation.json")


def run_files(out_dir) -> list[Path]:
    """The files a run of :func:`predict_files` leaves in ``out_dir``: ``forces.csv``, the
    stress maps (``*_stress.exr``, ``*_stress.png``) and, annotated, ``*_annotated.png``,
    ``annotated.mp4`` and ``forces.png``."""
    out_dir = Path(out_dir)
    if not out_dir.is_dir():
        return []
    return sorted(
        [f for f in (out_dir / n for n in RUN_FILES) if f.is_file()]
        + [f for g in ("*_stress.exr", "*_stress.png", "*_annotated.png") for f in out_dir.glob(g)]
    )


def predict_files(
    model_path,
    source,
    out_dir,
    threads: int = 1,
    backend: str = "auto",
    force_only: bool = False,
    on_frame=None,
    on_skip=None,
    device: str = "auto",
    calibration: dict | None = None,
    overwrite: bool = False,
    annotate: bool = False,
    maps: bool = True,
    on_annotated=None,
    segmentation: str = "auto",
    finger_colour=None,
    on_note=None,
) -> dict:
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

    The finger is found by :func:`choose_finder` (``segmentation``, ``finger_colour``,
    the calibration's colour; written to ``segmentation.json``, which
    ``finger_colour`` reads back). Each row is checked (:meth:`Predictor.check`,
    :mod:`finray.validity`): ``valid`` is ``ok`` or its flags joined by ``+`` (a column of
    ``forces.csv``, drawn on the annotated frame); the result's ``flagged`` counts them
    by flag. ``on_note(line)`` gets how the finger is found and what an old model's
    export lacks, before the first frame.

    A frame that cannot be predicted (unreadable, not an image, no finger) is skipped:
    ``on_skip(name, message)`` is called (for those before the first predicted frame,
    once it is: a run that predicts none ends with its one error) and the run goes on.
    ``on_frame(row)`` gets each row ``{"frame", "fx_N"[, "fy_N"][, "contact_mm"],
    "valid"}`` as it completes. Returns ``{"rows": [...], "skipped": [(name, message),
    ...], "interrupted", "flagged", "finder"}`` (a live source ended by Ctrl-C; flags
    counted; how the finger was found),
    for a live source also ``received`` and ``dropped`` (frames it sent; frames that
    came while the network was busy). With ``calibration`` (a ``calibration.json`` of
    :func:`finray.sim2real.calibration.calibrate_takes`, its model's heads' spread per frame) rows
    and columns also have ``force_N``, ``lo_N``, ``hi_N`` (the calibrated force's median
    and predictive interval, N) and ``level``. Raises :class:`InputError` for a missing
    model or source, a ``device`` this machine does not have (:class:`Predictor`), a
    single image that cannot be predicted, and when no frame at all could be, and for an
    ``out_dir`` that holds another run's files (:func:`run_files`) unless ``overwrite``
    (which removes them first), and, in one line, where the finger is found in no frame. Nothing half-written is left: the table is written as
    ``forces.csv.part`` and moved into place at the end (also when interrupted, with the
    frames done so far); a run that predicts no frame leaves no table and no maps.
    """
    out_dir = Path(out_dir)
    old = run_files(out_dir)
    if old and not overwrite:
        raise InputError(
            f"{out_dir} holds another run's results ({len(old)} files: "
            f"{', '.join(f.name for f in old[:2])}{', ...' if len(old) > 2 else ''}); "
            "give --overwrite to replace them, or another --out"
        )
    if annotate and force_only:
        raise InputError("annotating draws the stress map: leave out force-only")
    frames = read_frames(source)  # checks a file source before the model loads
    live = isinstance(frames, _Live)
    one_image = (
        not live and Path(source).is_file() and Path(source).suffix.lower() not in VIDEO_SUFFIXES
    )
    video = live or (Path(source).is_file() and Path(source).suffix.lower() in VIDEO_SUFFIXES)
    run = _Run(
        frames,
        source,
        out_dir,
        one_image,
        video,
        force_only,
        on_frame,
        on_skip,
        calibration,
        annotate,
        maps,
        on_annotated,
        segmentation,
        finger_colour,
        on_note,
    )
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
    segmentation: str = "auto"
    finger_colour: object = None
    on_note: object = None
    part: Path | None = None
    written: list = field(default_factory=list)  # files made so far (removed on failure)


def _predict_files(run: _Run, model_path, old: list, threads, backend, device) -> dict:
    """:func:`predict_files` once its source is open: the model loaded, the table written
    as ``forces.csv.part`` and moved into place."""
    out_dir = run.out_dir
    p = Predictor(model_path, threads, backend, device)
    if isinstance(run.frames, _Live):  # opened once ready: no frames dropped while loading
        import matplotlib  # noqa: F401 - the loop's imports, done before the stream runs

        from .render import imageio  # noqa: F401

        p.warm_up()
        run.frames.open()
    run.frames = choose_finder(
        p, run.frames, run.segmentation, run.finger_colour, run.calibration, rest=run.video
    )
    if run.on_note is not None:
        for line in [f"finger found by {p.finder.describe()}", *p.notes, time_note(run)]:
            run.on_note(line)
    for f in old:
        f.unlink()
    out_dir.mkdir(parents=True, exist_ok=True)
    import json

    seg = out_dir / "segmentation.json"
    run.written.append(seg)
    seg.write_text(json.dumps(p.finder.to_dict(), indent=1))
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
    out["finder"] = p.finder.describe()
    return out


def time_note(run) -> str:
    """What the forces say of a print's time dependence (:mod:`finray.viscoelastic`)."""
    from .sim2real.calibration import is_time_dependent

    if run.calibration is None:
        return (
            "note: forces are the simulated finger's elastic force at the frame's shape; a "
            "printed finger relaxes while a push is held and reads lower on unloading and in "
            "later cycles, so a held push's force is not known to better than the print's "
            "relaxation (finray calibrate on context takes learns it)"
        )
    if not is_time_dependent(run.calibration):
        return "note: a static calibration: the print's relaxation is not modelled"
    if not run.video:  # a video's or a live source's frames have times
        return (
            "note: images have no times: the calibration's relaxation is not applied "
            "(each frame reads as if loaded at once)"
        )
    return "note: the calibration's relaxation runs over the frames' times, causally"


def _remove(*paths: Path) -> None:
    for f in paths:
        f.unlink(missing_ok=True)


def _predict_into(p, run: _Run) -> dict:
    """:func:`predict_files`'s loop (:func:`_predict_loop`), with the annotated video
    open around it and the force-against-time figure after it where ``annotate``."""
    frames, out_dir, written = run.frames, run.out_dir, run.written
    writer = None
    if run.annotate and run.video:
        from .media import VideoWriter, video_info

        rate = (
            frames.frames.rate_hz if isinstance(frames, _Live) else video_info(run.source).rate_hz
        )
        # x264's fastest preset, no frame held back: the encoder shares the live loop's
        # core; chroma by point sampling (docs/studies/realtime.md)
        writer = VideoWriter(
            out_dir / "annotated.mp4", rate or 30.0, tune="zerolatency", interpolation="POINT"
        )
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
    frames, out_dir, written, calibration, video = (
        run.frames,
        run.out_dir,
        run.written,
        run.calibration,
        run.video,
    )
    import matplotlib

    matplotlib.use("Agg")
    from matplotlib import cm

    from .render.imageio import write_exr, write_png

    rows, skipped, interrupted, no_finger = [], [], False, 0
    if calibration is not None:
        from .sim2real.calibration import CalibratedStream

        stream = CalibratedStream(calibration)
    pending = []  # skips before the first predicted frame: reported once one is (a take
    # where the finger is never found ends in one line, not one per frame)
    with open(run.part, "w") as table:
        cal_cols = ["force_N", "lo_N", "hi_N"] if calibration is not None else []
        time_cols = ["t_s"] if video else []
        out_cols = [*p.force_names, *(["contact_mm"] if p.has_contact else [])]
        table.write(",".join(["frame", *time_cols, *out_cols, *cal_cols, "valid"]) + "\n")
        table.flush()
        # a live source ends with Ctrl-C: there the signal is raised into the loop
        # (finray.outputs.raised), to end it with the rows so far
        with raised() if isinstance(frames, _Live) else nullcontext():
            try:
                for name, frame, t_s in frames:
                    try:
                        if isinstance(frame, FrameError):
                            raise frame
                        try:
                            mask, confidence = p.find(frame)
                        except FrameError:
                            no_finger += 1
                            raise
                        box = p.crop_box(mask)
                        x = p.network_input(mask, box)
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
                        if run.on_skip is not None and rows:
                            run.on_skip(name, msg)
                        elif run.on_skip is not None:
                            pending.append((name, msg))
                        continue
                    if not run.force_only and run.maps:
                        stem = Path(name).stem
                        written += [out_dir / f"{stem}_stress.exr", out_dir / f"{stem}_stress.png"]
                        write_exr(
                            written[-2],
                            {"stress": stress.astype(np.float32)},
                            {
                                "source": str(name),
                                "force_N": force,
                                "stress_transform": "log10(1 + von_mises_MPa / stress_ref_MPa)",
                                "stress_ref_MPa": p.stress_ref_MPa,
                            },
                        )
                        s = np.clip(stress / max(float(stress.max()), 1e-6), 0, 1)
                        write_png(written[-1], (cm.inferno(s)[..., :3] * 255).astype(np.uint8))
                    row = {
                        "frame": name,
                        **({"t_s": t_s} if video else {}),
                        **{n: float(v) for n, v in zip(p.force_names, fvec)},
                        **({"contact_mm": contact} if p.has_contact else {}),
                    }
                    flags = p.check(mask, confidence, x, row, box)
                    row["valid"] = "+".join(flags) or "ok"
                    if calibration is not None:
                        from .sim2real.calibration import spread

                        members = p.run_members(x)[0]
                        # causal: the print's law (a time-dependent calibration) runs
                        # over this source's frames so far, at their times
                        band = stream.step(
                            t_s, float(members.mean()), float(spread(members[:, None])[0])
                        )
                        row.update(
                            force_N=band["median"],
                            lo_N=band["lo"],
                            hi_N=band["hi"],
                            level=band["level"],
                        )
                    if run.annotate:
                        from .annotate import annotate_frame

                        cal = (
                            {k: row[k] for k in ("force_N", "lo_N", "hi_N", "level")}
                            if calibration
                            else None
                        )
                        label = name + (f"  t = {t_s:.3f} s" if t_s is not None else "")
                        img = annotate_frame(
                            frame,
                            mask,
                            box,
                            stress,
                            row,
                            cal,
                            label,
                            crop_y_mm=p.window.crop_y_mm,
                            contact_min_force_N=p.contact_min_force_N,
                            stress_ref_MPa=p.stress_ref_MPa,
                            flags=flags,
                        )
                        if run.on_annotated is not None:
                            run.on_annotated(img)
                        if writer is not None:
                            writer.write(img)
                        else:
                            written.append(out_dir / f"{Path(name).stem}_annotated.png")
                            write_png(written[-1], img)
                    times = ["" if t_s is None else f"{t_s:.6f}"] if video else []
                    table.write(
                        ",".join(
                            [
                                name,
                                *times,
                                *(f"{row[n]:.6g}" for n in [*out_cols, *cal_cols]),
                                row["valid"],
                            ]
                        )
                        + "\n"
                    )
                    table.flush()  # a long video's forces can be read while it runs
                    rows.append(row)
                    for skip in pending:
                        run.on_skip(*skip)
                    pending.clear()
                    if run.on_frame is not None:
                        run.on_frame(row)
            except KeyboardInterrupt:
                if not isinstance(frames, _Live):
                    raise
                interrupted = True  # Ctrl-C is how a live source ends: the rows so far stand
    if not rows:
        if not skipped:
            raise InputError(f"{run.source} has no frames")
        if no_finger == len(skipped):
            raise InputError(
                f"the finger was found in none of the {no_finger} frames of "
                f"{run.source} ({p.finder.describe()}): give its colour "
                "(--finger-colour), or check the set-up (--check)"
            )
        raise InputError(f"no frame of {run.source} could be predicted ({len(skipped)} skipped)")
    from .validity import flag_counts

    return {
        "rows": rows,
        "skipped": skipped,
        "interrupted": interrupted,
        "flagged": flag_counts(rows),
    }


def check_setup(
    model_path,
    source,
    out_dir,
    n_frames: int = 6,
    segmentation: str = "auto",
    finger_colour=None,
    calibration: dict | None = None,
    backend: str = "auto",
    device: str = "auto",
) -> dict:
    """Check a set-up before trusting it: ``n_frames`` frames of ``source`` (spread over a
    file source; a live source's first ones) through the finger finder
    (:func:`choose_finder`) and the model, each with its mask's share of the frame, the
    segmentation's confidence, the force and its validity flags; ``check.png`` in
    ``out_dir`` shows the frames with their masks (green), windows (cyan) and flags.
    Returns ``{"finder", "notes", "frames": [{"frame", "found", "mask_frac",
    "confidence", "fx_N", "valid"}], "ok"}`` (``ok``: the finger found in every frame and
    none flagged)."""
    frames = read_frames(source)
    live = isinstance(frames, _Live)
    try:
        p = Predictor(model_path, 1, backend, device)
        video = live or Path(source).suffix.lower() in VIDEO_SUFFIXES
        frames = choose_finder(p, frames, segmentation, finger_colour, calibration, rest=video)
        picked = _pick(frames, n_frames, None if live else source)
    finally:
        if live:
            frames.close()
    rows, thumbs = [], []
    for name, frame, _ in picked:
        row = {
            "frame": name,
            "found": False,
            "mask_frac": 0.0,
            "confidence": 0.0,
            "fx_N": float("nan"),
            "valid": "no_finger",
        }
        mask = box = None
        if isinstance(frame, FrameError):
            row["valid"] = "unreadable"
        else:
            found, confidence = p.finder.find(frame)
            if found is not None:
                mask, box = found, p.crop_box(found)
                x = p.network_input(mask, box)
                f, c = p.run_force_contact(x)
                out = {n: float(v) for n, v in zip(p.force_names, f[0])}
                out |= {"contact_mm": float(c[0])} if p.has_contact else {}
                row.update(
                    found=True,
                    mask_frac=float(mask.mean()),
                    confidence=confidence,
                    fx_N=out["fx_N"],
                    valid="+".join(p.check(mask, confidence, x, out, box)) or "ok",
                )
            thumbs.append((name, frame, mask, box, row["valid"]))
        rows.append(row)
    out_dir = Path(out_dir)
    out_dir.mkdir(parents=True, exist_ok=True)
    if thumbs:
        _check_figure(out_dir / "check.png", thumbs, p.finder.describe())
    return {
        "finder": p.finder.describe(),
        "notes": list(p.notes),
        "frames": rows,
        "ok": bool(rows) and all(r["valid"] == "ok" for r in rows),
    }


def _pick(frames, n: int, source) -> list:
    """``n`` frames spread over a file source (every k-th of a video: its frame count
    from its header), a live source's first ``n``."""
    import itertools

    step = 1
    if source is not None and Path(source).suffix.lower() in VIDEO_SUFFIXES:
        from .media import video_info

        step = max(1, video_info(source).n_frames // max(n, 1))
    elif source is not None and Path(source).is_dir():
        step = max(
            1,
            len([f for f in Path(source).iterdir() if f.suffix.lower() in IMAGE_SUFFIXES])
            // max(n, 1),
        )
    return list(itertools.islice(itertools.islice(frames, 0, None, step), n))


def _check_figure(path, thumbs, finder: str) -> None:
    """The checked frames side by side: each with its mask (green), its window (cyan) and
    its flags in the title."""
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt
    from skimage.segmentation import find_boundaries

    fig, axes = plt.subplots(1, len(thumbs), figsize=(2.6 * len(thumbs), 3.6), squeeze=False)
    for ax, (name, frame, mask, box, valid) in zip(axes[0], thumbs):
        rgb = np.asarray(frame)
        rgb = np.repeat(rgb[..., None], 3, axis=2) if rgb.ndim == 2 else rgb[..., :3].copy()
        if mask is not None:
            rgb[mask] = (0.5 * rgb[mask] + 0.5 * np.array([0, 255, 0])).astype(np.uint8)
            rgb[find_boundaries(mask, mode="inner")] = (255, 0, 255)
            c0, r0, c1, r1 = box
            ax.plot([c0, c1, c1, c0, c0], [r0, r0, r1, r1, r0], color="cyan", lw=0.8)
        ax.imshow(rgb)
        ax.set_xlim(0, rgb.shape[1])
        ax.set_ylim(rgb.shape[0], 0)
        ax.set_title(f"{name}\n{valid}", fontsize=7, color="black" if valid == "ok" else "red")
        ax.axis("off")
    fig.suptitle(f"finger found by {finder}", fontsize=8)
    fig.tight_layout()
    fig.savefig(path, dpi=110)
    plt.close(fig)
