"""A trained model on disk: the checkpoint (``model.pt``), TorchScript (``model.ts`` with
its JSON settings) and ONNX (``model.onnx``, force-only ``model.force.onnx``), each
written from the CPU so that it loads anywhere.

A model file proves what it is before it is used: a checkpoint (or any ``torch.save``
file of the package) holds tensors and plain data only (dicts, lists, str, numbers) and
is read with ``torch.load(weights_only=True)``, which refuses anything else unread (an
object whose unpickling would run code); ``model.ts.json`` keeps the SHA-256 of the
model's files (``sha256``: :data:`MODEL_FILES`), checked before use
(:func:`check_sealed`)."""

from __future__ import annotations

import copy
import hashlib
import json
from dataclasses import asdict
from pathlib import Path

import torch
from torch import nn

from ..dataset.window import InputWindow
from ..errors import ModelError
from ..model import FinRayNet, NetConfig
from .config import History
from .data import FORCE_COMPONENTS
from .settings import settings_digest


def _plain(value):
    """``value`` as JSON's plain types (dict, list, str, float, int, bool, None)."""
    return json.loads(json.dumps(value))


def _one_line(exc: BaseException) -> str:
    text = str(exc).strip().splitlines()
    return f"{type(exc).__name__}: {text[0] if text else ''}".rstrip(": ")


def save_checkpoint(
    model: FinRayNet, hist: History, path: str | Path, extra: dict | None = None
) -> None:
    """``model.pt``: the weights (tensors) and, as plain data, the network's settings,
    the training's history and ``extra``: what :func:`load_checkpoint` reads back with
    ``weights_only=True``."""
    state = {k: v.detach().cpu() for k, v in model.state_dict().items()}  # loads anywhere
    torch.save(
        {
            "net_config": _plain(model.config_dict()),
            "state_dict": state,
            "history": _plain(asdict(hist)),
            "extra": _plain(extra or {}),
        },
        path,
    )


def load_plain(path: str | Path, what: str = "a finray model checkpoint") -> dict:
    """The mapping of a ``torch.save`` file of tensors and plain data, read with
    ``weights_only=True``: anything else in it (an object whose unpickling could run
    code) is refused unread. :class:`~finray.errors.ModelError` in one line for a file
    that is missing, empty, not such a file, or not a mapping (``what`` names what it
    should be)."""
    import pickle

    path = Path(path)
    if not path.is_file():
        raise ModelError(f"no file at {path} ({what})")
    try:
        saved = torch.load(path, map_location="cpu", weights_only=True)
    except pickle.UnpicklingError as exc:
        text = str(exc)
        if "Unsupported global" not in text and "GLOBAL" not in text:  # not a pickle at all
            why = [ln.strip() for ln in text.splitlines() if ln.strip()]
            why = next((w for w in why if w.startswith("Unsupported")), why[0] if why else "")
            raise ModelError(f"{path} is not {what} (UnpicklingError: {why})") from None
        raise ModelError(
            f"{path} is not {what}: it holds objects that are not tensors or plain data "
            "(refused unread: loading them could run code)"
        ) from None
    except Exception as exc:  # an empty or truncated file, not a torch.save archive
        raise ModelError(f"{path} is not {what} ({_one_line(exc)})") from None
    if not isinstance(saved, dict):
        raise ModelError(f"{path} is not {what} (it holds a {type(saved).__name__})")
    return saved


def load_checkpoint(path: str | Path) -> tuple[FinRayNet, dict]:
    """The network of a ``model.pt`` (:func:`save_checkpoint`), in eval mode, and the
    checkpoint's mapping; :class:`~finray.errors.ModelError` in one line for a file that
    is not one (:func:`load_plain`) or whose weights are not its network's."""
    what = "a finray model checkpoint (model.pt)"
    ck = load_plain(path, what)
    if not isinstance(ck.get("net_config"), dict) or not isinstance(ck.get("state_dict"), dict):
        raise ModelError(f"{path} is not {what} (no net_config and state_dict)")
    try:
        cfg = dict(ck["net_config"])
        cfg["hidden"] = tuple(cfg["hidden"])
        model = FinRayNet(NetConfig(**cfg))
        model.load_state_dict(ck["state_dict"])
    except (TypeError, KeyError, ValueError, RuntimeError) as exc:
        raise ModelError(
            f"{path}: its weights are not the network of its net_config ({_one_line(exc)})"
        ) from None
    model.eval()
    return model, ck


def check_settings(meta: dict, model: FinRayNet, meta_name: str) -> None:
    """Refuse settings (``model.ts.json``) that describe another network than ``model``
    (its :meth:`~finray.model.FinRayNet.config_dict`), in one line."""
    cfg = _plain(model.config_dict())
    differ = [k for k, v in cfg.items() if k in meta and _plain(meta[k]) != v]
    missing = [k for k in ("height", "width") if k not in meta]
    if differ or missing:
        k = (differ or missing)[0]
        raise ModelError(
            f"{meta_name} describes another network than the model's ({k}: "
            f"{meta.get(k, 'missing')}, the model's {cfg.get(k)}); put the model's own "
            "settings beside it"
        )


#: The files of an exported model, beside ``model.ts``, whose SHA-256 ``model.ts.json``
#: keeps (``sha256``), by role: the suffix that replaces ``.ts``.
MODEL_FILES = {
    "torchscript": ".ts",
    "checkpoint": ".pt",
    "onnx": ".onnx",
    "onnx_force": ".force.onnx",
}


def sha256(path: str | Path) -> str:
    """The SHA-256 (hex) of a file's bytes."""
    h = hashlib.sha256()
    with open(path, "rb") as f:
        for block in iter(lambda: f.read(1 << 20), b""):
            h.update(block)
    return h.hexdigest()


def model_file(ts_path: str | Path, role: str) -> Path:
    """The file of ``role`` (:data:`MODEL_FILES`) of the model exported to ``ts_path``."""
    return Path(ts_path).with_suffix(MODEL_FILES[role])


def model_settings(ts_path: str | Path) -> dict:
    """The settings exported beside ``model.ts`` (``model.ts.json``: preprocessing, force
    names, the training's ranges ``trained``...), checked
    (:func:`~finray.train.settings.read_settings`)."""
    from .settings import read_settings

    return read_settings(Path(str(ts_path) + ".json"))[0]


def seal(ts_path: str | Path, roles=("torchscript",)) -> None:
    """Record the SHA-256 of the model's files of ``roles`` (:data:`MODEL_FILES`; those
    that exist) in ``ts_path + '.json'`` (``sha256``), beside the ones it has, and of the
    settings themselves (``sha256.settings``, :func:`~finray.train.settings.settings_digest`)."""
    meta_path = Path(str(ts_path) + ".json")
    meta = json.loads(meta_path.read_text())
    hashes = dict(meta.get("sha256") or {})
    for role in roles:
        f = model_file(ts_path, role)
        if f.is_file():
            hashes[role] = sha256(f)
    meta["sha256"] = {r: hashes[r] for r in MODEL_FILES if r in hashes}
    meta["sha256"]["settings"] = settings_digest(meta)  # the file's own values
    meta_path.write_text(json.dumps(meta, indent=1))


def check_sealed(ts_path: str | Path, meta: dict, roles) -> str | None:
    """Check the model's files of ``roles`` against the SHA-256 in its settings ``meta``
    (``model.ts.json``): :class:`~finray.errors.ModelError` in one line where one
    differs (the settings belong to another model, or the file changed since its
    export). Settings without hashes (exported before they were kept) are taken as
    they are; returns the line that says so (else None)."""
    meta_name = Path(str(ts_path) + ".json").name
    hashes = meta.get("sha256")
    if not hashes:
        return (
            f"{meta_name} has no SHA-256 of the model's files (exported before it was "
            "kept): not checked against them; export the model again (the workflow's "
            "train stage does) to have them checked"
        )
    if not isinstance(hashes, dict):
        raise ModelError(f"{meta_name}: sha256 is not a mapping of the model's files")
    for role in roles:
        f = model_file(ts_path, role)
        if role in hashes and f.is_file() and sha256(f) != hashes[role]:
            raise ModelError(
                f"{f} is not the model that {meta_name} describes (its SHA-256 differs: "
                "another model's settings, or a file changed since its export); put the "
                "model's own files side by side, or export it again"
            )
    return None


#: The traced methods of a model with the contact head, besides ``forward`` and ``force``.
CONTACT_METHODS = ("contact", "force_contact", "forward_contact")


def export_torchscript(
    model: FinRayNet,
    path: str | Path,
    preprocess: dict | None = None,
    forces: list[str] | None = None,
    contact_min_force_N: float | None = None,
    stress_ref_MPa: float | None = None,
    trained: dict | None = None,
) -> None:
    """Trace the model (eval mode, float32) to TorchScript: ``forward`` gives (stress,
    force N), ``force`` the force (N) alone (no stress decoder); frozen. A model with the
    contact head also has ``contact`` (contact height (B,) mm), ``force_contact`` (force
    N, contact mm) and ``forward_contact`` (stress, force N, contact mm).

    ``path + '.json'`` keeps the network's settings (``contact``: whether it has the
    head), the names of the force outputs (``forces``, e.g. ``["fx_N", "fy_N"]``; default
    ``fx_N`` and on), ``contact_min_force_N`` (the smallest |fx| the contact height was
    trained on) and the preprocessing (crop window, base width, segmentation) that
    :class:`finray.predict.Predictor` needs; also what the outputs mean and where they
    hold: ``stress_ref_MPa`` (the maps are ``log10(1 + sigma / stress_ref_MPa)``, the
    renders' ``render.stress_ref_MPa``), ``force_normalisation`` (the force head's mean
    and scale, N) and ``trained`` (the training's ranges,
    :func:`finray.validity.training_ranges`, which each predicted frame is checked
    against) and ``sha256``, the SHA-256 of ``model.ts`` and of ``model.pt`` beside it
    (:func:`seal`; :func:`export_onnx` adds its files')."""
    model = copy.deepcopy(model).cpu().float().eval().to(memory_format=torch.contiguous_format)
    c = model.cfg
    example = torch.rand(1, c.in_channels, c.height, c.width)
    methods = ["force", *(CONTACT_METHODS if c.contact else ())]
    with torch.no_grad():
        ts = torch.jit.trace_module(model, {"forward": example, **{m: example for m in methods}})
        ts = torch.jit.freeze(ts, preserved_attrs=methods)
    ts.save(str(path))
    names = list(forces or list(FORCE_COMPONENTS.values())[: c.n_forces])
    if len(names) != c.n_forces:
        raise ValueError(f"{len(names)} force names for a model with {c.n_forces} force outputs")
    extra = {"contact_min_force_N": contact_min_force_N} if c.contact else {}
    if stress_ref_MPa is not None:
        extra["stress_ref_MPa"] = float(stress_ref_MPa)
    extra["force_normalisation"] = {
        "mean_N": model.force_mean_N.tolist(),
        "scale_N": model.force_scale_N.tolist(),
    }
    if trained is not None:
        extra["trained"] = trained
    Path(str(path) + ".json").write_text(
        json.dumps(
            {
                **model.config_dict(),
                "forces": names,
                **extra,
                # none given: the window of the config schema's defaults (InputWindow())
                "preprocess": InputWindow().to_json() if preprocess is None else preprocess,
            },
            indent=1,
        )
    )
    seal(path, ("torchscript", "checkpoint"))  # model.pt: saved before the export


class _ForceOnly(nn.Module):
    def __init__(self, model: FinRayNet):
        super().__init__()
        self.model = model

    def forward(self, x: torch.Tensor):
        return self.model.force_contact(x) if self.model.cfg.contact else self.model.force(x)


class _Full(nn.Module):
    def __init__(self, model: FinRayNet):
        super().__init__()
        self.model = model

    def forward(self, x: torch.Tensor):
        return self.model.forward_contact(x) if self.model.cfg.contact else self.model(x)


def export_onnx(model: FinRayNet, path: str | Path) -> None:
    """Write the model as ONNX (opset 17, float32, any batch size) for ONNX Runtime,
    faster than TorchScript at batch 1 on one CPU thread (``inference_latency.json``
    times both): ``path`` (input
    ``image``, outputs ``stress_log`` and ``force_N``) and ``path`` with suffix
    ``.force.onnx`` (the encoder and force head only, output ``force_N``). A model with
    the contact head has one more output in each, ``contact_mm`` (B,)."""
    import warnings

    model = copy.deepcopy(model).cpu().float().eval().to(memory_format=torch.contiguous_format)
    c = model.cfg
    example = torch.rand(1, c.in_channels, c.height, c.width)
    path = Path(path)
    contact = ["contact_mm"] if c.contact else []
    with warnings.catch_warnings(), torch.no_grad():
        warnings.simplefilter("ignore")  # the TorchScript-based exporter is deprecated
        for module, file, outputs in (
            (_Full(model), path, ["stress_log", "force_N", *contact]),
            (_ForceOnly(model), force_onnx_path(path), ["force_N", *contact]),
        ):
            torch.onnx.export(
                module,
                (example,),
                str(file),
                input_names=["image"],
                output_names=outputs,
                opset_version=17,
                dynamic_axes={n: {0: "batch"} for n in ["image", *outputs]},
                dynamo=False,
            )
    if Path(str(path.with_suffix(".ts")) + ".json").is_file():  # its TorchScript's settings
        seal(path.with_suffix(".ts"), ("onnx", "onnx_force"))


def force_onnx_path(path: str | Path) -> Path:
    """``model.onnx`` -> ``model.force.onnx``."""
    path = Path(path)
    return path.with_name(path.stem + ".force.onnx")
