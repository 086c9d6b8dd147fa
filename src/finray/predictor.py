"""Force (N) and stress map from one camera frame: the API a control loop calls.

    from finray.predict import Predictor        # (defined in finray.predictor)
    predict = Predictor("results/train/plain/model.ts")
    force_N, stress_log = predict(frame)        # frame: (H, W, 3) uint8 numpy array
    force_N = predict.force(frame)              # force only: no stress decoder, faster
    out = predict.forces(frame)                 # {"fx_N", "fy_N"[, "contact_mm"]}

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

A model trained with the contact head (``train.contact_weight`` > 0) also gives the
contact height (mm, in the finger's frame: the clamped base at 0, up the finger), the
height of the force-weighted centroid of the contact; :attr:`Predictor.has_contact`
says whether it does (else the height is NaN). It was trained on frames with ``|fx|``
above :attr:`Predictor.contact_min_force_N`; below, it is a guess.
"""

from __future__ import annotations

from pathlib import Path

import numpy as np
import torch

from .dataset.imageops import EmptyMaskError, segment, silhouette_input
from .dataset.window import InputWindow
from .errors import DeviceInputError, FrameError, InputError, ModelError
from .media import one_line
from .precision import DeviceError, resolve_device
from .recording.finder import FingerFinder
from .validity import Limits, check_frame, window_outside

#: The stress maps' reference (MPa) of models exported before it was saved with them
#: (``render.stress_ref_MPa``'s value then: maps in log10(1 + sigma / 1 kPa)).
DEFAULT_STRESS_REF_MPA = 1e-3

BACKENDS = ("auto", "onnx", "torchscript")


def _check_meta(meta, meta_path: Path) -> None:
    """Refuse, in one line, settings that are not a model's: the input size (``height``,
    ``width``, one channel), the force names."""
    if not isinstance(meta, dict):
        raise ModelError(f"{meta_path} is not a model's settings (not a mapping)")
    for k in ("height", "width"):
        v = meta.get(k)
        if isinstance(v, bool) or not isinstance(v, int) or v < 1:
            raise ModelError(
                f"{meta_path} is not a model's settings ({k}: {v!r}, not a size in pixels)"
            )
    if meta.get("in_channels", 1) != 1:
        raise ModelError(
            f"{meta_path}: in_channels {meta['in_channels']!r}, not the 1 of a silhouette input"
        )
    forces = meta.get("forces")
    if forces is not None and (
        not isinstance(forces, list) or not forces or not all(isinstance(f, str) for f in forces)
    ):
        raise ModelError(f"{meta_path}: forces is not a list of output names")
    if not isinstance(meta.get("preprocess", {}), dict):
        raise ModelError(f"{meta_path}: preprocess is not a mapping")


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
    for pixel (the experiments). ``finder``: how the finger is found
    (:class:`~finray.recording.finder.FingerFinder`; None: the model's grey-level
    threshold, as its renders were segmented); :attr:`finder` may be set later (a colour
    learned from a stream's first frames).

    What the model's outputs depend on is read from ``model.ts.json``:
    :attr:`stress_ref_MPa` (the maps are ``log10(1 + sigma / stress_ref_MPa)``),
    :attr:`trained` (the training's ranges, for :meth:`check`); a model exported
    before they were saved gets the defaults, each with a line in :attr:`notes`.
    """

    def __init__(
        self,
        model_path: str | Path,
        threads: int = 1,
        backend: str = "auto",
        device: str = "auto",
        roi_stride: int = 4,
        finder: FingerFinder | None = None,
    ):
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
        from .train.settings import read_settings

        self.meta, settings_note = read_settings(meta_path)
        _check_meta(self.meta, meta_path)
        self.size = (self.meta["height"], self.meta["width"])
        #: Names of the force outputs, in order (``fx_N`` first; exports before the force
        #: vector had ``fx_N`` only).
        self.force_names = list(self.meta.get("forces") or ["fx_N"])
        #: Where in a frame the network looks, and the renders' segmentation (the model's
        #: ``preprocess``; :class:`~finray.dataset.window.InputWindow`).
        self.window, lacking = InputWindow.from_json(self.meta.get("preprocess", {}))
        #: How the finger is found in a frame (default: the model's grey-level threshold).
        self.finder = finder or FingerFinder.grey(self.window.segment, self.roi_stride)
        #: One line per setting an old export lacks and that is assumed here.
        self.notes: list[str] = [settings_note] if settings_note else []
        if lacking:
            self.notes.append(
                f"{meta_path.name} gives no preprocess/{', '.join(lacking)} (an older export): "
                "the config schema's defaults are assumed"
            )
        #: The stress maps' reference (MPa): a map holds log10(1 + sigma / stress_ref_MPa).
        self.stress_ref_MPa = self.meta.get("stress_ref_MPa")
        if self.stress_ref_MPa is None:
            self.stress_ref_MPa = DEFAULT_STRESS_REF_MPA
            self.notes.append(
                f"{meta_path.name} has no stress_ref_MPa (exported before it was "
                f"saved): the stress maps are read in log10(1 + sigma / 1 kPa)"
            )
        #: The training's ranges (:func:`finray.validity.training_ranges`), or None.
        self.trained = self.meta.get("trained")
        if self.trained is None:
            self.notes.append(
                f"{meta_path.name} has no training ranges (exported before they "
                "were saved): frames are checked for the mask only, not for "
                "shape, force or contact height"
            )
        self.limits = Limits()
        # the finger's mask pixels in the first frames its colour was learned from (the
        # validity check "grown"); None: not checked (finray.predict.choose_finder)
        self.rest_px: float | None = None
        #: Heads of an adapted ensemble (:mod:`finray.sim2real.adapt`; 0: a single network).
        self.ensemble = int(self.meta.get("ensemble", 0))
        if self.ensemble and backend == "onnx":
            raise InputError(
                f"{model_path} is a head ensemble: TorchScript only (backend torchscript or auto)"
            )
        onnx_full = model_path.with_suffix(".onnx")
        onnx_force = model_path.with_suffix(".force.onnx")
        cuda = self.device.type == "cuda"
        if backend == "auto":
            have = onnx_full.is_file() and onnx_force.is_file() and not cuda and not self.ensemble
            try:
                import onnxruntime  # noqa: F401
            except ImportError:
                have = False
            backend = "onnx" if have else "torchscript"
        self.backend = backend
        # the settings describe these files (their SHA-256), else a note (an old export)
        from .train.export import check_sealed

        roles = ("onnx", "onnx_force") if backend == "onnx" else ("torchscript",)
        note = check_sealed(model_path, self.meta, roles)
        if note is not None:
            self.notes.append(note)
        if backend == "onnx":
            import onnxruntime as ort

            providers = ["CPUExecutionProvider"]
            if cuda and "CUDAExecutionProvider" in ort.get_available_providers():
                providers.insert(0, "CUDAExecutionProvider")
            elif cuda and device == "cuda":
                raise DeviceInputError(
                    "backend onnx on cuda needs ONNX Runtime's CUDAExecutionProvider (the "
                    "onnxruntime-gpu package); this one has "
                    f"{', '.join(ort.get_available_providers())}: use backend torchscript"
                )
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
                raise InputError(
                    f"cannot load the ONNX model {onnx_full} ({one_line(exc)})"
                ) from None
        else:
            torch.set_num_threads(threads)
            try:
                self.model = torch.jit.load(str(model_path), map_location=self.device).eval()
            except (RuntimeError, ValueError) as exc:
                raise InputError(
                    f"{model_path} is not a TorchScript model ({one_line(exc)})"
                ) from None
            self._has_force = hasattr(self.model, "force")  # exports before the force path
        #: Whether the model predicts the contact height (mm): its TorchScript has
        #: ``force_contact`` (an adapted ensemble has not), its ONNX files ``contact_mm``.
        if backend == "onnx":
            self.has_contact = all(
                "contact_mm" in [o.name for o in sess.get_outputs()]
                for sess in (self._full, self._force)
            )
        else:
            self.has_contact = hasattr(self.model, "force_contact")
        #: The smallest |fx| (N) the contact height was trained on.
        self.contact_min_force_N = float(self.meta.get("contact_min_force_N") or 0.0)
        self._check_network(model_path, meta_path)

    def _check_network(self, model_path: Path, meta_path: Path) -> None:
        """Run the network once on a blank input of the settings' size: its outputs must
        have the shapes they describe (a map of that size, one force per name), else a
        one-line :class:`ModelError` (settings of another network)."""
        h, w = self.size
        x = np.zeros((1, 1, h, w), np.float32)
        try:
            stress, force, contact = self.run_contact(x)
            force_only, contact_only = self.run_force_contact(x)
        except Exception as exc:  # torch's, ONNX Runtime's own error types
            raise ModelError(
                f"{model_path} does not run on the input that {meta_path.name} describes "
                f"({h}x{w}): another network's settings? ({one_line(exc)})"
            ) from None
        n = len(self.force_names)
        want = {
            "stress map": ((1, 1, h, w), np.shape(stress)),
            "forces": ((1, n), np.shape(force)),
            "forces (force path)": ((1, n), np.shape(force_only)),
            "contact height": ((1,), np.shape(contact)),
            "contact height (force path)": ((1,), np.shape(contact_only)),
        }
        for what, (shape, got) in want.items():
            if tuple(got) != shape:
                raise ModelError(
                    f"{model_path}'s {what} has shape {tuple(got)}, not the {shape} that "
                    f"{meta_path.name} describes: the settings of another network; put "
                    "the model's own settings beside it"
                )

    def crop_box(self, mask: np.ndarray) -> tuple[float, float, float, float]:
        """Training window in pixel edges ``(col0, row0, col1, row1)`` from the mask
        (:func:`~finray.dataset.imageops.base_anchored_box`)."""
        try:
            return self.window.box(mask)
        except EmptyMaskError as exc:
            raise FrameError(str(exc)) from None

    def segment(self, frame: np.ndarray) -> np.ndarray:
        """Finger mask (H, W) bool: by :attr:`finder`; the default, the grey-level
        threshold, as in the dataset stage (empty where nothing is found)."""
        frame = np.asarray(frame)
        if frame.ndim not in (2, 3):
            raise FrameError(f"expected an (H, W) or (H, W, 3) image, got shape {frame.shape}")
        if self.finder.mode == "grey":
            return segment(frame, **self.finder.segment_kw, roi_stride=self.finder.stride)
        return self.finder.mask(frame)

    def find(self, frame: np.ndarray) -> tuple[np.ndarray, float]:
        """Finger mask (H, W) bool by :attr:`finder` and its confidence in [0, 1];
        :class:`FrameError` where no finger is found."""
        mask, confidence = self.finder.find(frame)
        if mask is None:
            raise FrameError(
                "no finger found in the image (empty segmentation)"
                if self.finder.mode == "grey"
                else f"no finger found ({self.finder.describe()})"
            )
        return mask, confidence

    def check(
        self,
        mask: np.ndarray,
        confidence: float,
        x: np.ndarray,
        outputs: dict[str, float],
        box=None,
    ) -> list[str]:
        """A frame's validity flags (:func:`finray.validity.check_frame`; empty: valid):
        its mask (H, W), the mask's confidence, the network input ``x`` (1, 1, h, w), the
        outputs by name (``fx_N``..., ``contact_mm``) and the window (``box``, else
        :meth:`crop_box`)."""
        box = self.crop_box(mask) if box is None else box
        px = float(np.count_nonzero(mask))
        return check_frame(
            px / mask.size,
            window_outside(box, mask.shape),
            confidence,
            x,
            outputs,
            self.trained,
            self.contact_min_force_N,
            self.limits,
            growth=px / self.rest_px - 1.0 if self.rest_px else None,
        )

    def network_input(self, mask: np.ndarray, box=None) -> np.ndarray:
        """Network input (1, 1, H, W) float32 in [0, 1] from the mask: the 8-bit soft
        silhouette of the training window (``box``, else :meth:`crop_box`), as in the
        training data."""
        box = self.crop_box(mask) if box is None else box
        x = silhouette_input(mask, box, self.size).astype(np.float32) / 255.0
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
        self.run_contact(x)
        self.run_force_contact(x)

    def run(self, x: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """The network on inputs (B, 1, H, W) float32: log-stress maps (B, 1, H, W) and
        forces (B, n_forces) in N."""
        x = np.ascontiguousarray(x, dtype=np.float32)
        if self.backend == "onnx":
            stress, force = self._full.run(["stress_log", "force_N"], {"image": x})
            return stress, force
        with torch.inference_mode():
            stress, force = self.model(torch.from_numpy(x).to(self.device))
        return stress.cpu().numpy(), force.cpu().numpy()

    def run_contact(self, x: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """:meth:`run` and the contact height (B,) in mm, in one pass (NaN for a model
        without the contact head)."""
        if not self.has_contact:
            stress, force = self.run(x)
            return stress, force, np.full(len(force), np.nan, np.float32)
        x = np.ascontiguousarray(x, dtype=np.float32)
        if self.backend == "onnx":
            stress, force, contact = self._full.run(
                ["stress_log", "force_N", "contact_mm"], {"image": x}
            )
            return stress, force, contact
        with torch.inference_mode():
            out = self.model.forward_contact(torch.from_numpy(x).to(self.device))
        return tuple(t.cpu().numpy() for t in out)

    def run_force_contact(self, x: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """:meth:`run_force` and the contact height (B,) in mm, without the stress decoder
        (NaN for a model without the contact head)."""
        if not self.has_contact:
            force = self.run_force(x)
            return force, np.full(len(force), np.nan, np.float32)
        x = np.ascontiguousarray(x, dtype=np.float32)
        if self.backend == "onnx":
            force, contact = self._force.run(["force_N", "contact_mm"], {"image": x})
            return force, contact
        with torch.inference_mode():
            force, contact = self.model.force_contact(torch.from_numpy(x).to(self.device))
        return force.cpu().numpy(), contact.cpu().numpy()

    def run_force(self, x: np.ndarray) -> np.ndarray:
        """Forces (B, n_forces) in N of inputs (B, 1, H, W) float32, without the stress
        decoder."""
        x = np.ascontiguousarray(x, dtype=np.float32)
        if self.backend == "onnx":
            return self._force.run(["force_N"], {"image": x})[0]
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

    def __call__(self, frame: np.ndarray) -> tuple[float, np.ndarray]:
        """Force (N, along the push) and the log-stress map (H, W) of one frame."""
        stress, force = self.run(self.network_input(self.segment(frame)))
        return float(force[0, 0]), stress[0, 0]

    def forces(self, frame: np.ndarray) -> dict[str, float]:
        """Every force output (N) of one frame by name (:attr:`force_names`, e.g.
        ``fx_N``, ``fy_N``) and, for a model with the contact head, ``contact_mm`` (the
        contact height, mm), without the stress map."""
        f, c = self.run_force_contact(self.network_input(self.segment(frame)))
        out = {n: float(v) for n, v in zip(self.force_names, f[0])}
        return out | ({"contact_mm": float(c[0])} if self.has_contact else {})

    def contact(self, frame: np.ndarray) -> float:
        """Contact height (mm, the clamped base at 0) of one frame, without the stress
        map; NaN for a model without the contact head."""
        return float(self.run_force_contact(self.network_input(self.segment(frame)))[1][0])

    def force(self, frame: np.ndarray) -> float:
        """Force (N, along the push) of one frame, without the stress map (faster)."""
        return float(self.run_force(self.network_input(self.segment(frame)))[0, 0])
