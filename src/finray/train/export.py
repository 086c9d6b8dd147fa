"""A trained model on disk: the checkpoint (``model.pt``), TorchScript (``model.ts`` with
its JSON settings) and ONNX (``model.onnx``, force-only ``model.force.onnx``), each
written from the CPU so that it loads anywhere."""

from __future__ import annotations

import copy
import json
from dataclasses import asdict
from pathlib import Path

import torch
from torch import nn

from ..model import FinRayNet, NetConfig
from .config import History
from .data import FORCE_COMPONENTS


def save_checkpoint(
    model: FinRayNet, hist: History, path: str | Path, extra: dict | None = None
) -> None:
    state = {k: v.detach().cpu() for k, v in model.state_dict().items()}  # loads anywhere
    torch.save(
        {
            "net_config": model.config_dict(),
            "state_dict": state,
            "history": asdict(hist),
            "extra": extra or {},
        },
        path,
    )


def load_checkpoint(path: str | Path) -> tuple[FinRayNet, dict]:
    ck = torch.load(path, map_location="cpu", weights_only=False)
    cfg = dict(ck["net_config"])
    cfg["hidden"] = tuple(cfg["hidden"])
    model = FinRayNet(NetConfig(**cfg))
    model.load_state_dict(ck["state_dict"])
    model.eval()
    return model, ck


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
    against)."""
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
            {**model.config_dict(), "forces": names, **extra, "preprocess": preprocess or {}},
            indent=1,
        )
    )


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


def force_onnx_path(path: str | Path) -> Path:
    """``model.onnx`` -> ``model.force.onnx``."""
    path = Path(path)
    return path.with_name(path.stem + ".force.onnx")
