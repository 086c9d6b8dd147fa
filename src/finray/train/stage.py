"""The train stage's entry point: shards in, a trained and exported model out
(:func:`train_from_shards`), with its history and training curves."""

from __future__ import annotations

import json
import time
from dataclasses import asdict, replace
from pathlib import Path

import numpy as np
import torch

from ..model import NetConfig
from ..precision import cpu_name, resolve_device
from .augment import TrainAugment
from .config import FORCE_LOSS, AugmentConfig, History, TrainConfig
from ..validity import training_ranges
from .data import (
    FORCE_COMPONENTS,
    frame_stiffness,
    load_split,
    scene_force_weights,
    shard_stress_ref,
    validation_scenes,
)
from .export import export_onnx, export_torchscript, load_checkpoint, save_checkpoint
from .loop import train
from ..schema import schema_default


def train_from_shards(
    shards,
    out_dir: str | Path,
    net_cfg: NetConfig,
    cfg: TrainConfig,
    augment: AugmentConfig | None,
    val_fraction: float = schema_default("train.val_fraction"),
    occlusion_levels: dict | None = None,
    preprocess: dict | None = None,
    forces: tuple[str, ...] = ("fx",),
    frame_every: int = schema_default("train.frame_every"),
    log=print,
    init: str | Path | None = None,
) -> dict:
    """Train on the shards (force components ``forces``, ``fx`` first; ``net_cfg.n_forces``
    is set to match; with ``cfg.contact_weight`` > 0 also the contact height, the shards'
    ``contact_y_mm``, and ``net_cfg.contact`` follows), keep the epoch ``cfg.keep`` chooses
    and write
    ``model.pt``, ``model.ts`` (TorchScript), ``model.onnx`` and ``model.force.onnx``
    (ONNX), ``history.json`` and ``curves.png``. ``frame_every``: train and validate on
    every ``frame_every``-th frame of each scene (the rendered frames are interpolated
    between solver frames, so neighbours are near copies; the training-budget study).
    ``init``: a ``model.pt`` whose weights (force normalisation included) the training
    starts from instead of new ones; its network must be this one.
    ``cuda`` without a GPU stops before the data load."""
    resolve_device(cfg.device, "train.device")
    if cfg.force_loss not in FORCE_LOSS:
        raise ValueError(f"train.force_loss: {cfg.force_loss!r} is not one of {list(FORCE_LOSS)}")
    if int(frame_every) < 1:
        raise ValueError(f"train.frame_every must be >= 1, got {frame_every}")
    out_dir = Path(out_dir)
    out_dir.mkdir(parents=True, exist_ok=True)
    forces = tuple(forces)
    if not forces or forces[0] != "fx":
        raise ValueError(
            f"train.forces must start with fx (the headline force), got {list(forces)}"
        )
    net_cfg = replace(net_cfg, n_forces=len(forces), contact=cfg.contact_weight > 0)
    init_state = None
    if init is not None:
        start, _ = load_checkpoint(init)
        if start.cfg != net_cfg:
            raise ValueError(
                f"{init}: its network ({start.cfg}) is not the one to train "
                f"({net_cfg}); it cannot start from it"
            )
        init_state = start.state_dict()
        log(f"starting from the weights of {init}")
    camera = augment is not None and augment.camera_p > 0
    data = load_split(
        shards, (net_cfg.height, net_cfg.width), every=frame_every, forces=forces, camera=camera
    )
    val_ids = validation_scenes(data["scene_id"], val_fraction, cfg.split_seed)
    is_val = np.isin(data["scene_id"], list(val_ids))
    tr = {k: v[~is_val] for k, v in data.items()}
    va = {k: v[is_val] for k, v in data.items()}
    log(
        f"training frames {len(tr['images'])} from {len(set(tr['scene_id']))} scenes, "
        f"validation frames {len(va['images'])} from {len(val_ids)} scenes"
    )
    aug = TrainAugment(augment, occlusion_levels) if augment is not None else None
    labels = ["stress", "force_N", *(["contact_mm"] if net_cfg.contact else [])]
    val = (va["images"], *(va[k] for k in labels)) if len(va["images"]) else None
    if camera and val is not None:  # validate on both views of the validation frames
        val = (
            np.concatenate([va["images"], va["camera_images"]]),
            *(np.concatenate([va[k]] * 2) for k in labels),
        )
    weight = (
        scene_force_weights(tr["scene_id"], tr["force_N"], cfg.force_floor_N)
        if cfg.force_loss == "relative"
        else None
    )
    t0, c0 = time.perf_counter(), time.process_time()
    model, hist = train(
        tr["images"],
        tr["stress"],
        tr["force_N"],
        val,
        net_cfg,
        cfg,
        aug,
        log=log,
        camera_images=tr.get("camera_images"),
        init_state=init_state,
        contact_mm=tr["contact_mm"] if net_cfg.contact else None,
        force_weight=weight,
    )
    seconds, cpu_seconds = time.perf_counter() - t0, time.process_time() - c0
    extra = {
        "train_config": asdict(cfg),
        "augment": asdict(augment) if augment else None,
        "cpu": cpu_name(),
        "device": hist.device,
        "torch_threads": torch.get_num_threads(),
        "validation_scenes": sorted(val_ids),
        "n_train": int(len(tr["images"])),
        "n_val": int(len(va["images"])),
        "train_seconds": seconds,
        "train_cpu_seconds": cpu_seconds,
        "frame_every": int(frame_every),
        "forces": [FORCE_COMPONENTS[c] for c in forces],
        "start_from": None if init is None else str(init),
    }
    save_checkpoint(model, hist, out_dir / "model.pt", extra)
    seen = [tr["images"], tr["camera_images"]] if camera else [tr["images"]]
    trained = training_ranges(
        seen,
        tr["force_N"],
        extra["forces"],
        tr["contact_mm"] if net_cfg.contact else None,
        cfg.contact_min_force_N,
        stiffness_N_per_mm=(
            frame_stiffness(tr["scene_id"], tr["displacement_mm"], tr["fx_N"])
            if net_cfg.contact
            else None
        ),
    )
    export_torchscript(
        model,
        out_dir / "model.ts",
        preprocess,
        extra["forces"],
        contact_min_force_N=cfg.contact_min_force_N,
        stress_ref_MPa=shard_stress_ref(shards),
        trained=trained,
    )
    export_onnx(model, out_dir / "model.onnx")
    (out_dir / "history.json").write_text(json.dumps({**asdict(hist), **extra}, indent=1))
    training_curves(hist, out_dir / "curves.png")
    return extra


def training_curves(hist: History, path: str | Path) -> None:
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    contact = bool(hist.val_contact_rmse_mm)
    fig, ax = plt.subplots(1, 3 if contact else 2, figsize=(12 if contact else 8, 3.2))
    ax[0].semilogy(hist.epoch, hist.train_loss, "o-", label="train")
    if hist.val_loss:
        ax[0].semilogy(hist.epoch, hist.val_loss, "s-", label="validation")
    ax[0].set_xlabel("epoch")
    ax[0].set_ylabel("loss (stress MSE + 10 force MSE)")
    ax[0].legend()
    if hist.val_force_rmse_N:
        ax[1].plot(
            hist.epoch,
            hist.val_force_rmse_N,
            "s-",
            label="batch-norm re-estimated" if hist.val_force_rmse_running_bn_N else None,
        )
    if hist.val_force_rmse_running_bn_N:
        ax[1].plot(
            hist.epoch,
            hist.val_force_rmse_running_bn_N,
            "x--",
            color="0.5",
            label="training's running batch-norm averages",
        )
        ax[1].legend(fontsize=7)
    ax[1].set_xlabel("epoch")
    ax[1].set_ylabel("validation force RMSE (N)")
    if contact:
        ax[2].plot(hist.epoch, hist.val_contact_rmse_mm, "s-")
        ax[2].set_xlabel("epoch")
        ax[2].set_ylabel("validation contact-height RMSE (mm)")
    fig.tight_layout()
    fig.savefig(path, dpi=130)
    plt.close(fig)
