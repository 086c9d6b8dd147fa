"""Training of :class:`~finray.model.FinRayNet` on the CPU.

Loss (the paper's eq. 1): ``alpha_stress * MSE(stress) + alpha_force * MSE(force)``,
the force normalised by the training set's mean and standard deviation (stored in the
model, so that its outputs are in N). Adam, seeded and deterministic: two runs with
the same data and seed give identical losses.

Speed on the CPU: ``channels_last`` memory and ``bfloat16`` autocast (about 2x), one
intra-op thread per job when other jobs share the machine.
"""
from __future__ import annotations

import contextlib
import copy
import json
import math
import time
from dataclasses import asdict, dataclass, field
from pathlib import Path
from typing import Callable

import numpy as np
import torch
from torch import nn

from .model import FinRayNet, NetConfig


@dataclass
class TrainConfig:
    epochs: int = 10
    batch_size: int = 16
    lr: float = 1e-4
    alpha_stress: float = 1.0
    alpha_force: float = 10.0
    seed: int = 0
    threads: int = 1
    bf16: bool = True
    channels_last: bool = True
    progress: bool = True


@dataclass
class History:
    epoch: list = field(default_factory=list)
    train_loss: list = field(default_factory=list)
    train_stress_mse: list = field(default_factory=list)
    train_force_mse: list = field(default_factory=list)
    val_loss: list = field(default_factory=list)
    val_force_rmse_N: list = field(default_factory=list)
    wall_time_s: list = field(default_factory=list)


def seed_everything(seed: int) -> torch.Generator:
    torch.manual_seed(seed)
    np.random.seed(seed % 2**32)
    torch.use_deterministic_algorithms(True)
    g = torch.Generator()
    g.manual_seed(seed)
    return g


def _autocast(enabled: bool):
    if enabled:
        return torch.autocast("cpu", dtype=torch.bfloat16)
    return contextlib.nullcontext()


def _prep(x: torch.Tensor, channels_last: bool) -> torch.Tensor:
    return x.contiguous(memory_format=torch.channels_last) if channels_last else x


def evaluate(model: FinRayNet, images: torch.Tensor, stress: torch.Tensor, force_N: torch.Tensor,
             cfg: TrainConfig, batch_size: int = 256) -> dict:
    """Losses and force errors (N) of ``model`` on a set, in eval mode."""
    model.eval()
    n = len(images)
    s_se, f_se, f_pred = 0.0, 0.0, []
    with torch.no_grad(), _autocast(cfg.bf16):
        for i in range(0, n, batch_size):
            x = _prep(images[i:i + batch_size], cfg.channels_last)
            s, f = model.forward_normalised(x)
            s_se += float(((s.float() - stress[i:i + batch_size]) ** 2).mean()) * len(x)
            fn = model.normalise_force(force_N[i:i + batch_size])
            f_se += float(((f.float() - fn) ** 2).mean()) * len(x)
            f_pred.append(f.float() * model.force_scale_N + model.force_mean_N)
    f_pred = torch.cat(f_pred)
    s_mse, f_mse = s_se / n, f_se / n
    return {
        "loss": cfg.alpha_stress * s_mse + cfg.alpha_force * f_mse,
        "stress_mse": s_mse, "force_mse_normalised": f_mse,
        "force_rmse_N": float(((f_pred - force_N) ** 2).mean().sqrt()),
        "force_pred_N": f_pred,
    }


def train(images: np.ndarray, stress: np.ndarray, force_N: np.ndarray,
          val: tuple[np.ndarray, np.ndarray, np.ndarray] | None,
          net_cfg: NetConfig, cfg: TrainConfig,
          augment: Callable[[torch.Tensor, torch.Tensor, torch.Generator], tuple] | None = None,
          log: Callable[[str], None] = print) -> tuple[FinRayNet, History]:
    """Train a network; returns the best model by validation loss and the history.

    ``images`` (N, C, H, W) float in [0, 1]; ``stress`` (N, 1, H, W) log-stress maps;
    ``force_N`` (N, n_forces). ``augment(x, s, generator) -> (x, s)`` is applied to each
    training batch (on the fly, seeded by the training generator).
    """
    torch.set_num_threads(cfg.threads)
    gen = seed_everything(cfg.seed)
    x_all = torch.as_tensor(images, dtype=torch.float32)
    s_all = torch.as_tensor(stress, dtype=torch.float32)
    f_all = torch.as_tensor(force_N, dtype=torch.float32).reshape(len(x_all), -1)
    if not (torch.isfinite(x_all).all() and torch.isfinite(s_all).all() and torch.isfinite(f_all).all()):
        raise ValueError("training data contain NaN or infinite values")
    model = FinRayNet(net_cfg)
    mean = f_all.mean(0)
    scale = f_all.std(0).clamp_min(1e-6)
    model.set_force_normalisation(mean, scale)
    if cfg.channels_last:
        model = model.to(memory_format=torch.channels_last)
    opt = torch.optim.Adam(model.parameters(), lr=cfg.lr)
    mse = nn.MSELoss()
    if val is not None:
        vx, vs, vf = (torch.as_tensor(a, dtype=torch.float32) for a in val)
        vf = vf.reshape(len(vx), -1)
    hist = History()
    best, best_loss = None, math.inf
    n = len(x_all)
    n_batches = max(1, n // cfg.batch_size)  # drop the last partial batch (batch-norm)
    t0 = time.perf_counter()
    try:
        from tqdm import tqdm
    except ImportError:  # pragma: no cover
        tqdm = None
    for epoch in range(1, cfg.epochs + 1):
        model.train()
        perm = torch.randperm(n, generator=gen)
        tot = {"loss": 0.0, "s": 0.0, "f": 0.0}
        it = range(n_batches)
        bar = tqdm(it, desc=f"epoch {epoch}/{cfg.epochs}", leave=False,
                   disable=not cfg.progress) if tqdm else it
        for b in bar:
            idx = perm[b * cfg.batch_size:(b + 1) * cfg.batch_size]
            x, s, f = x_all[idx], s_all[idx], f_all[idx]
            if augment is not None:
                x, s = augment(x, s, gen)
            x = _prep(x, cfg.channels_last)
            with _autocast(cfg.bf16):
                s_pred, f_pred = model.forward_normalised(x)
            ls = mse(s_pred.float(), s)
            lf = mse(f_pred.float(), model.normalise_force(f))
            loss = cfg.alpha_stress * ls + cfg.alpha_force * lf
            if not torch.isfinite(loss):
                raise FloatingPointError(f"loss became {float(loss)} at epoch {epoch}, batch {b}")
            opt.zero_grad(set_to_none=True)
            loss.backward()
            opt.step()
            tot["loss"] += float(loss.detach())
            tot["s"] += float(ls.detach())
            tot["f"] += float(lf.detach())
            if tqdm and cfg.progress:
                bar.set_postfix(loss=f"{tot['loss'] / (b + 1):.4f}")
        hist.epoch.append(epoch)
        hist.train_loss.append(tot["loss"] / n_batches)
        hist.train_stress_mse.append(tot["s"] / n_batches)
        hist.train_force_mse.append(tot["f"] / n_batches)
        hist.wall_time_s.append(time.perf_counter() - t0)
        msg = f"epoch {epoch}: train loss {hist.train_loss[-1]:.5f}"
        if val is not None:
            ev = evaluate(model, vx, vs, vf, cfg)
            hist.val_loss.append(ev["loss"])
            hist.val_force_rmse_N.append(ev["force_rmse_N"])
            msg += f", val loss {ev['loss']:.5f}, val force RMSE {ev['force_rmse_N']:.4f} N"
            score = ev["loss"]
        else:
            score = hist.train_loss[-1]
        if score < best_loss:
            best_loss, best = score, copy.deepcopy(model.state_dict())
            msg += " (best)"
        log(msg)
    model.load_state_dict(best)
    model.eval()
    return model, hist


def save_checkpoint(model: FinRayNet, hist: History, path: str | Path, extra: dict | None = None) -> None:
    torch.save({"net_config": model.config_dict(), "state_dict": model.state_dict(),
                "history": asdict(hist), "extra": extra or {}}, path)


def load_checkpoint(path: str | Path) -> tuple[FinRayNet, dict]:
    ck = torch.load(path, map_location="cpu", weights_only=False)
    cfg = dict(ck["net_config"])
    cfg["hidden"] = tuple(cfg["hidden"])
    model = FinRayNet(NetConfig(**cfg))
    model.load_state_dict(ck["state_dict"])
    model.eval()
    return model, ck


def export_torchscript(model: FinRayNet, path: str | Path) -> None:
    """Trace the model (eval mode, float32) to TorchScript; outputs are (stress, force N)."""
    model = copy.deepcopy(model).eval().to(memory_format=torch.contiguous_format)
    c = model.cfg
    example = torch.rand(1, c.in_channels, c.height, c.width)
    with torch.no_grad():
        ts = torch.jit.trace(model, example)
        ts = torch.jit.freeze(ts)
    ts.save(str(path))
    Path(str(path) + ".json").write_text(json.dumps(model.config_dict()))
