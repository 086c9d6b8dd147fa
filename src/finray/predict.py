"""Force (N) and stress map from one camera frame: the API a control loop calls.

    from finray.predict import Predictor
    predict = Predictor("results/train/plain/model.ts")
    force_N, stress_log = predict(frame)        # frame: (H, W, 3) uint8 numpy array
    force_N = predict.force(frame)              # force only: no stress decoder, faster

Preprocessing is the dataset stage's: segment the finger (threshold + morphology),
crop, area-resample to the network's input. The crop is anchored on the finger
itself, so any image size and position works: the lowest row of the mask is the
clamped base, its width is the finger's base width (``base_width_mm``), which fixes
the scale (px/mm); the window ``crop_x_mm`` x ``crop_y_mm`` of the training data is
then cut around it.

The network runs in ONNX Runtime when ``model.onnx`` and ``model.force.onnx`` lie
beside ``model.ts`` (faster than TorchScript at batch 1 on one thread: both are timed in
``results/benchmarks/inference_latency.json``), else in TorchScript. On a CUDA GPU
(``device="cuda"``, or ``"auto"`` where torch sees one) it runs in TorchScript, or in
ONNX Runtime's CUDAExecutionProvider when ``backend="onnx"`` is asked for and the
installed ONNX Runtime has it; preprocessing stays on the CPU.
"""
from __future__ import annotations

import json
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np
import torch

from .dataset.imageops import EmptyMaskError, base_anchored_box, segment, silhouette_input
from .errors import DeviceInputError, FrameError, InputError  # noqa: F401 - callers import them here
from .media import (IMAGE_SUFFIXES, VIDEO_SUFFIXES, LiveFrames, MediaError, is_live, one_line,
                    read_image, video_frames)
from .precision import DeviceError, resolve_device

BACKENDS = ("auto", "onnx", "torchscript")


class Predictor:
    """Load an exported model (``model.ts`` + ``model.ts.json``, and ``model.onnx`` +
    ``model.force.onnx`` for ONNX Runtime) once; call per frame.

    ``backend``: ``"onnx"`` (ONNX Runtime), ``"torchscript"``, or ``"auto"`` (ONNX
    Runtime when its files and the package are there; TorchScript on a GPU).
    ``device``: ``"auto"`` (a CUDA GPU when torch sees one, else the CPU), ``"cpu"`` or
    ``"cuda"`` (:class:`DeviceInputError` without a GPU); ``backend="onnx"`` on
    ``"auto"`` stays on the CPU unless ONNX Runtime has its CUDAExecutionProvider.
    :attr:`device` is where the network runs. ``threads``: intra-op threads (CPU).
    ``roi_stride``: the segmentation finds the finger on every ``roi_stride``-th row and
    column first and works at full resolution around it only
    (:func:`~finray.dataset.imageops.segment`; 4: a 1280x720 frame segments ~2x faster,
    the threshold may move an edge pixel); 1 segments as the dataset stage does, pixel
    for pixel (the experiments).
    """

    def __init__(self, model_path: str | Path, threads: int = 1, backend: str = "auto",
                 device: str = "auto", roi_stride: int = 4):
        model_path = Path(model_path)
        meta_path = Path(str(model_path) + ".json")
        if not model_path.is_file():
            raise InputError(f"no model at {model_path}")
        if not meta_path.is_file():
            raise InputError(f"{meta_path} (the model's preprocessing settings) is missing")
        if backend not in BACKENDS:
            raise ValueError(f"backend must be one of {BACKENDS}, not {backend!r}")
        if int(roi_stride) < 1:
            raise ValueError(f"roi_stride must be >= 1, got {roi_stride}")
        self.roi_stride = int(roi_stride)
        try:
            self.device = resolve_device(device, "device")
        except DeviceError as exc:
            raise DeviceInputError(str(exc)) from None
        try:
            self.meta = json.loads(meta_path.read_text())
        except (json.JSONDecodeError, UnicodeDecodeError) as exc:
            raise InputError(f"{meta_path} is not the model's JSON settings ({one_line(exc)})"
                             ) from None
        self.size = (self.meta["height"], self.meta["width"])
        #: Names of the force outputs, in order (``fx_N`` first; exports before the force
        #: vector had ``fx_N`` only).
        self.force_names = list(self.meta.get("forces") or ["fx_N"])
        pre = self.meta.get("preprocess", {})
        self.base_width_mm = pre.get("base_width_mm", 30.0)
        self.crop_x_mm = tuple(pre.get("crop_x_mm", (-5.0, 35.0)))
        self.crop_y_mm = tuple(pre.get("crop_y_mm", (0.0, 80.0)))
        self.segment_kw = pre.get("segment", {})
        #: the base is the widest row among the lowest base_band of the mask's height
        #: (dataset.base_band; 0, the lowest row, for exports before it)
        self.base_band = float(pre.get("base_band", 0.0))
        #: Heads of an adapted ensemble (:mod:`finray.adapt`; 0: a single network).
        self.ensemble = int(self.meta.get("ensemble", 0))
        if self.ensemble and backend == "onnx":
            raise InputError(f"{model_path} is a head ensemble: TorchScript only (backend "
                             "torchscript or auto)")
        onnx_full = model_path.with_suffix(".onnx")
        onnx_force = model_path.with_suffix(".force.onnx")
        cuda = self.device.type == "cuda"
        if backend == "auto":
            have = (onnx_full.is_file() and onnx_force.is_file() and not cuda
                    and not self.ensemble)
            try:
                import onnxruntime  # noqa: F401
            except ImportError:
                have = False
            backend = "onnx" if have else "torchscript"
        self.backend = backend
        if backend == "onnx":
            import onnxruntime as ort

            providers = ["CPUExecutionProvider"]
            if cuda and "CUDAExecutionProvider" in ort.get_available_providers():
                providers.insert(0, "CUDAExecutionProvider")
            elif cuda and device == "cuda":
                raise DeviceInputError(
                    "backend onnx on cuda needs ONNX Runtime's CUDAExecutionProvider (the "
                    "onnxruntime-gpu package); this one has "
                    f"{', '.join(ort.get_available_providers())}: use backend torchscript")
            elif cuda:  # device auto: ONNX Runtime without CUDA runs on the CPU
                self.device = torch.device("cpu")
            opts = ort.SessionOptions()
            opts.intra_op_num_threads = threads
            opts.inter_op_num_threads = 1
            opts.graph_optimization_level = ort.GraphOptimizationLevel.ORT_ENABLE_ALL
            for f in (onnx_full, onnx_force):
                if not f.is_file():
                    raise InputError(f"no ONNX model at {f}")
            try:
                self._full = ort.InferenceSession(str(onnx_full), opts, providers=providers)
                self._force = ort.InferenceSession(str(onnx_force), opts, providers=providers)
            except Exception as exc:  # onnxruntime's own error types
                raise InputError(f"cannot load the ONNX model {onnx_full} ({one_line(exc)})"
                                 ) from None
        else:
            torch.set_num_threads(threads)
            try:
                self.model = torch.jit.load(str(model_path), map_location=self.device).eval()
            except (RuntimeError, ValueError) as exc:
                raise InputError(f"{model_path} is not a TorchScript model ({one_line(exc)})"
                                 ) from None
            self._has_force = hasattr(self.model, "force")  # exports before the force path

    def crop_box(self, mask: np.ndarray) -> tuple[float, float, float, float]:
        """Training window in pixel edges ``(col0, row0, col1, row1)`` from the mask
        (:func:`~finray.dataset.imageops.base_anchored_box`)."""
        try:
            return base_anchored_box(mask, self.base_width_mm, self.crop_x_mm, self.crop_y_mm,
                                     base_band=self.base_band)
        except EmptyMaskError as exc:
            raise FrameError(str(exc)) from None

    def segment(self, frame: np.ndarray) -> np.ndarray:
        """Finger mask (H, W) bool, as in the dataset stage."""
        frame = np.asarray(frame)
        if frame.ndim not in (2, 3):
            raise FrameError(f"expected an (H, W) or (H, W, 3) image, got shape {frame.shape}")
        return segment(frame, **self.segment_kw, roi_stride=self.roi_stride)

    def network_input(self, mask: np.ndarray) -> np.ndarray:
        """Network input (1, 1, H, W) float32 in [0, 1] from the mask: the 8-bit soft
        silhouette of the training window, as in the training data."""
        x = silhouette_input(mask, self.crop_box(mask), self.size).astype(np.float32) / 255.0
        return x[None, None]

    def preprocess(self, frame: np.ndarray) -> tuple[torch.Tensor, np.ndarray]:
        """Network input (1, 1, H, W) tensor in [0, 1] and the full-resolution mask."""
        mask = self.segment(frame)
        return torch.from_numpy(self.network_input(mask)), mask

    def warm_up(self) -> None:
        """Each path once on a synthetic frame (the segmentation's compiled kernels, ONNX
        Runtime's first runs), so that a live source's first frame takes its usual time."""
        frame = np.zeros((96, 48, 3), np.uint8)
        frame[8:88, 8:40] = 255
        x = self.network_input(self.segment(frame))
        self.run(x)
        self.run_force(x)

    def run(self, x: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """The network on inputs (B, 1, H, W) float32: log-stress maps (B, 1, H, W) and
        forces (B, n_forces) in N."""
        x = np.ascontiguousarray(x, dtype=np.float32)
        if self.backend == "onnx":
            stress, force = self._full.run(None, {"image": x})
            return stress, force
        with torch.inference_mode():
            stress, force = self.model(torch.from_numpy(x).to(self.device))
        return stress.cpu().numpy(), force.cpu().numpy()

    def run_force(self, x: np.ndarray) -> np.ndarray:
        """Forces (B, n_forces) in N of inputs (B, 1, H, W) float32, without the stress
        decoder."""
        x = np.ascontiguousarray(x, dtype=np.float32)
        if self.backend == "onnx":
            return self._force.run(None, {"image": x})[0]
        with torch.inference_mode():
            xt = torch.from_numpy(x).to(self.device)
            f = self.model.force(xt) if self._has_force else self.model(xt)[1]
        return f.cpu().numpy()

    def run_members(self, x: np.ndarray) -> np.ndarray:
        """Each head's force (B, M) in N of inputs (B, 1, H, W) float32 (an adapted
        ensemble; a single network: (B, 1), its force along the push)."""
        if not self.ensemble:
            return self.run_force(x)[:, :1]
        with torch.inference_mode():
            xt = torch.from_numpy(np.ascontiguousarray(x, np.float32)).to(self.device)
            return self.model.members(xt).cpu().numpy()

    def force_members(self, frame: np.ndarray) -> np.ndarray:
        """Each head's force (M,) in N of one frame (see :meth:`run_members`)."""
        return self.run_members(self.network_input(self.segment(frame)))[0]

    def __call__(self, frame: np.ndarray) -> tuple[float, np.ndarray]:
        """Force (N, along the push) and the log-stress map (H, W) of one frame."""
        stress, force = self.run(self.network_input(self.segment(frame)))
        return float(force[0, 0]), stress[0, 0]

    def forces(self, frame: np.ndarray) -> dict[str, float]:
        """Every force output (N) of one frame by name (:attr:`force_names`, e.g.
        ``fx_N``, ``fy_N``), without the stress map."""
        f = self.run_force(self.network_input(self.segment(frame)))[0]
        return {n: float(v) for n, v in zip(self.force_names, f)}

    def force(self, frame: np.ndarray) -> float:
        """Force (N, along the push) of one frame, without the stress map (faster)."""
        return float(self.run_force(self.network_input(self.segment(frame)))[0, 0])


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
    it; while it runs ``forces.csv.part``, a row appended and flushed as each frame
    completes; for a video also ``t_s``, each frame's time) and, per frame unless
    ``force_only``, the stress map as EXR and as a coloured PNG. ``annotate``
    (:mod:`finray.annotate`): each frame with its stress map drawn over the finger, the
    force arrow and values (``<name>_annotated.png``; a video's frames go into
    ``annotated.mp4`` instead, at its frame rate) and, for more than one frame, the
    force against time (``forces.png``). ``maps=False``: no per-frame stress map files
    (a long video or a stream; the annotated frames still show the maps).
    ``on_annotated(rgb)`` gets each annotated frame too (a window, ``--show``).

    A frame that cannot be predicted (unreadable, not an image, no finger) is skipped:
    ``on_skip(name, message)`` is called and the run goes on. ``on_frame(row)`` gets
    each row ``{"frame", "fx_N"[, "fy_N"]}`` as it completes. Returns ``{"rows": [...],
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
        table.write(",".join(["frame", *time_cols, *p.force_names, *cal_cols]) + "\n")
        table.flush()
        try:
            for name, frame, t_s in frames:
                try:
                    if isinstance(frame, FrameError):
                        raise frame
                    mask = segment_frame(frame)
                    x = p.network_input(mask)
                    if run.force_only:
                        fvec = p.run_force(x)[0]
                    else:
                        stress, fvec = p.run(x)
                        stress, fvec = stress[0, 0], fvec[0]
                    force = float(fvec[0])
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
                       **{n: float(v) for n, v in zip(p.force_names, fvec)}}
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
                    img = annotate_frame(frame, mask, p.crop_box(mask), stress, row, cal, label)
                    if run.on_annotated is not None:
                        run.on_annotated(img)
                    if writer is not None:
                        writer.write(img)
                    else:
                        written.append(out_dir / f"{Path(name).stem}_annotated.png")
                        write_png(written[-1], img)
                times = ["" if t_s is None else f"{t_s:.6f}"] if video else []
                table.write(",".join([name, *times,
                                      *(f"{row[n]:.6g}" for n in [*p.force_names, *cal_cols])]) + "\n")
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
