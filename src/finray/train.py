"""Training of :class:`~finray.model.FinRayNet` on the CPU or a CUDA GPU.

Loss (the paper's eq. 1): ``alpha_stress * MSE(stress) + alpha_force * MSE(force)``,
each force component (``fx`` along the push, ``fy`` across it, as the paper's two-output
head) normalised by the training set's mean and standard deviation (stored in the
model, so that its outputs are in N), the MSE taken over the components. Adam, seeded
and deterministic: two runs with the same data and seed give identical losses.

Where training differs from the paper (whose rate is a constant 1e-4 and whose kept
weights are not said), and why: at a constant rate a model's validation error wandered
from epoch to epoch, and the kept weights were one draw of that wander.

- ``schedule="cosine"`` (default): the rate rises linearly to ``lr`` over the first
  ``warmup_frac`` of the steps, then falls to 0 on a cosine; ``"constant"`` is the
  paper's. The same steps either way.
- Batch-norm statistics (the force head's) are re-estimated at the end of every epoch
  over ``bn_frames`` augmented training frames, with a cumulative average
  (:func:`recalibrate_batchnorm`): the running averages of training (momentum 0.1,
  batches of 16) hold the last few batches only, which, with a mix of front views,
  perspective views and occlusions, are a noisy draw.
- The kept epoch is the one with the lowest validation force RMSE of ``fx`` (``keep``;
  ``"val_loss"``: the loss, ``"last"``: the last epoch).

Speed on the CPU: ``channels_last`` memory, one intra-op thread per job when other jobs
share the machine, and ``bfloat16`` autocast only where the CPU runs it natively
(``bf16="auto"``, :mod:`finray.precision`); the choice and the measured step time go to
the log and to ``history.json``.

On a GPU (``device="cuda"``, or ``"auto"`` where torch sees one) the model and each
batch go to the GPU; the frames stay in host memory and the augmentation runs on the
CPU from the same generator, so that a run draws the same batches and augmentations on
either device (results differ in rounding only). bfloat16 autocast follows the GPU's
native support. Batch size, learning rate and epochs are the config's on every device.
The trained model comes back on the CPU, and checkpoints and exports are written from
it, so that they load on any machine.
"""
from __future__ import annotations

import contextlib
import copy
import json
import math
import os
import time
from dataclasses import asdict, dataclass, field, replace
from pathlib import Path
from typing import Callable

import numpy as np
import torch
from torch import nn

from .model import FinRayNet, NetConfig
from .precision import cpu_name, device_name, resolve_bf16, resolve_device


@dataclass
class TrainConfig:
    epochs: int = 10
    batch_size: int = 16
    lr: float = 1e-4
    alpha_stress: float = 1.0
    alpha_force: float = 10.0
    seed: int = 0
    threads: int = 1
    bf16: bool | str = "auto"  # "auto": bfloat16 autocast where the device runs it natively
    device: str = "auto"  # "auto" (the GPU when torch sees one), "cpu" or "cuda"
    channels_last: bool = True
    progress: bool = True  # a tqdm bar (interactive use); the log gets lines either way
    log_every_s: float = 60.0  # a progress line in the log at most this often (s)
    schedule: str = "cosine"  # "cosine" (warm-up, then cosine to 0) or "constant" (the paper's)
    warmup_frac: float = 0.05  # of all steps, linear warm-up of the cosine schedule
    bn_frames: int = 2048  # augmented training frames per batch-norm re-estimate (0: keep training's)
    keep: str = "val_force_rmse"  # the kept epoch: lowest "val_force_rmse" (fx), "val_loss", or "last"
    # also validate with training's running batch-norm averages before each re-estimate
    # (History.val_force_rmse_running_bn_N; a diagnostic: one more validation pass)
    compare_running_bn: bool = False


@dataclass
class History:
    epoch: list = field(default_factory=list)
    train_loss: list = field(default_factory=list)
    train_stress_mse: list = field(default_factory=list)
    train_force_mse: list = field(default_factory=list)
    val_loss: list = field(default_factory=list)
    val_force_rmse_N: list = field(default_factory=list)  # of the first force component (fx)
    val_force_rmse_components_N: list = field(default_factory=list)  # per epoch, every component
    wall_time_s: list = field(default_factory=list)
    epoch_time_s: list = field(default_factory=list)  # training loop + validation (s)
    precision: str = ""  # "bfloat16" or "float32", as resolved from TrainConfig.bf16
    precision_reason: str = ""
    device: str = ""  # where it trained: "cpu (<CPU>)" or "cuda:0 (<GPU>)"
    step_ms: float = float("nan")  # median training step, wall (batch, augmentation included)
    step_cpu_ms: float = float("nan")  # the same in the thread's CPU time (less load-dependent)
    best_epoch: int = 0  # the epoch whose weights are kept (TrainConfig.keep; train loss without validation)
    lr: list = field(default_factory=list)  # the learning rate at the end of each epoch
    val_force_rmse_running_bn_N: list = field(default_factory=list)  # TrainConfig.compare_running_bn
    force_mean_N: list = field(default_factory=list)  # the force normalisation (training frames)
    force_std_N: list = field(default_factory=list)


@dataclass
class AugmentConfig:
    """On-the-fly training augmentation (kornia + the dataset's disc occlusion)."""

    affine_p: float = 0.5
    degrees: float = 2.0  # rotation jitter (deg)
    translate: float = 0.02  # fraction of the image size
    scale: float = 0.03  # relative
    perspective_p: float = 0.0
    perspective: float = 0.1  # kornia distortion scale
    salt_pepper_p: float = 0.5
    salt_pepper_amount: tuple[float, float] = (0.0, 0.05)  # fraction of pixels
    occlusion_p: float = 0.0  # probability of a random occluding disc
    occlusion_levels: tuple[str, ...] = ("low", "medium", "high")
    pitch_p: float = 0.0  # probability of a camera pitch (finray.dataset.viewpoint)
    pitch_max_deg: float = 30.0  # pitch drawn uniformly in [0, pitch_max_deg]
    # probability that a sample is its frame's randomised camera view (the shards'
    # camera_input_HxW, finray.dataset.camera_views) instead of the front view; the
    # stress target stays the front view's map either way
    camera_p: float = 0.0
    # geometry of the input for the pitch: set by the training script from the config
    mm_per_px: float = 1.25  # image-plane mm per input pixel
    pitch_centre_row: float = 31.5  # input row of the camera's rotation axis
    extrusion_mm: float = 20.0


def pitch_geometry(dataset: dict, render: dict, height_px: int, extrusion_mm: float) -> dict:
    """Input geometry the pitch augmentation needs, from the config sections
    ``dataset`` (crop) and ``render`` (camera window, whose centre is the pitch axis)."""
    y0, y1 = dataset["crop_y_mm"]
    mm_per_px = (y1 - y0) / height_px
    yc = 0.5 * sum(render["window_y_mm"])
    return {"mm_per_px": mm_per_px, "pitch_centre_row": (y1 - yc) / mm_per_px - 0.5,
            "extrusion_mm": float(extrusion_mm)}


class TrainAugment:
    """Random jitter (image and stress map alike), the camera view in place of the front
    view (``camera_p``; the stress map stays unjittered: it is the front view's),
    salt-and-pepper and occlusion (image only), drawn from the training generator, so
    training stays replayable."""

    def __init__(self, cfg: AugmentConfig, occlusion_levels: dict | None = None):
        import kornia.augmentation as K

        self.cfg = cfg
        self.geometric = []
        if cfg.affine_p > 0:
            self.geometric.append(K.RandomAffine(cfg.degrees, (cfg.translate, cfg.translate),
                                                 (1 - cfg.scale, 1 + cfg.scale), p=cfg.affine_p))
        if cfg.perspective_p > 0:
            self.geometric.append(K.RandomPerspective(cfg.perspective, p=cfg.perspective_p))
        self.noise = (K.RandomSaltAndPepperNoise(amount=tuple(cfg.salt_pepper_amount),
                                                 salt_vs_pepper=0.5, p=cfg.salt_pepper_p)
                      if cfg.salt_pepper_p > 0 else None)
        self.occlusion_levels = occlusion_levels

    def __call__(self, x: torch.Tensor, s: torch.Tensor, gen: torch.Generator,
                 x_camera: torch.Tensor | None = None):
        from .dataset.augment import sample_augment

        # kornia draws from torch's global generator: seed it from ours (replayable)
        torch.manual_seed(int(torch.randint(0, 2**62, (1,), generator=gen)))
        s_front = s
        if self.geometric:
            both = torch.cat([x, s], dim=1)
            for aug in self.geometric:
                both = aug(both)
            x, s = both[:, :x.shape[1]], both[:, x.shape[1]:]
        if x_camera is not None and self.cfg.camera_p > 0:
            draw = (torch.rand(len(x), generator=gen) < self.cfg.camera_p).reshape(-1, 1, 1, 1)
            x = torch.where(draw, x_camera, x)
            s = torch.where(draw, s_front, s)
        if self.cfg.occlusion_p > 0:
            x = x.clone()
            draw = torch.rand(len(x), generator=gen) < self.cfg.occlusion_p
            for i in torch.nonzero(draw).flatten().tolist():
                k = int(torch.randint(0, len(self.cfg.occlusion_levels), (1,), generator=gen))
                p = sample_augment(int(torch.randint(0, 2**62, (1,), generator=gen)),
                                   tuple(x.shape[2:]), occlusion=self.cfg.occlusion_levels[k],
                                   occlusion_levels=self.occlusion_levels)
                x[i, :, torch.from_numpy(p.disc_mask())] = 0.0
        if self.cfg.pitch_p > 0:
            from .dataset.viewpoint import pitch_silhouette

            draw = torch.rand(len(x), generator=gen) < self.cfg.pitch_p
            pitch = torch.rand(len(x), generator=gen) * self.cfg.pitch_max_deg * draw
            x = pitch_silhouette(x, pitch, self.cfg.mm_per_px, self.cfg.pitch_centre_row,
                                 self.cfg.extrusion_mm)
        if self.noise is not None:
            x = self.noise(x)
        return x, s


def seed_everything(seed: int) -> torch.Generator:
    torch.manual_seed(seed)
    np.random.seed(seed % 2**32)
    torch.use_deterministic_algorithms(True)
    g = torch.Generator()
    g.manual_seed(seed)
    return g


SCHEDULES = ("cosine", "constant")
KEEP = ("val_force_rmse", "val_loss", "last")


def lr_factor(step: int, total: int, schedule: str = "cosine", warmup_frac: float = 0.05) -> float:
    """The learning rate of step ``step`` (0-based, of ``total``) as a fraction of the
    peak: 1 throughout (``constant``), or a linear warm-up over ``warmup_frac`` of the
    steps to 1, then a cosine to 0 at the last step (``cosine``)."""
    if schedule == "constant":
        return 1.0
    if schedule != "cosine":
        raise ValueError(f"train.schedule: {schedule!r} is not one of {list(SCHEDULES)}")
    warm = int(round(warmup_frac * total))
    if step < warm:
        return (step + 1) / (warm + 1)
    rest = max(1, total - warm)
    return 0.5 * (1.0 + math.cos(math.pi * min(step - warm, rest) / rest))


@torch.no_grad()
def recalibrate_batchnorm(model: FinRayNet, batches, device: torch.device, channels_last: bool,
                          bf16: bool) -> int:
    """Re-estimate every batch-norm layer's running mean and variance as the plain
    average over ``batches`` (an iterable of input tensors, drawn as in training) --
    ``torch.optim.swa_utils.update_bn``'s method, on the encoder and force head only
    (the stress decoder has no batch-norm). Returns the number of frames seen."""
    bns = [m for m in model.modules() if isinstance(m, nn.modules.batchnorm._BatchNorm)]
    if not bns:
        return 0
    momenta = {m: m.momentum for m in bns}
    was_training = model.training
    for m in bns:
        m.reset_running_stats()
        m.momentum = None  # cumulative average
    model.train()
    n = 0
    try:
        for x in batches:
            with _autocast(bf16, device):
                model.force_head(model.encode(_prep(x.to(device), channels_last))[0])
            n += len(x)
    finally:
        for m in bns:
            m.momentum = momenta[m]
        model.train(was_training)
    return n


def _use_bf16(cfg: TrainConfig, device: torch.device) -> bool:
    return resolve_bf16(cfg.bf16, device=device)[0] if isinstance(cfg.bf16, str) else bool(cfg.bf16)


def _step_times(hist: History, step_s: list[tuple[float, float]]) -> None:
    """Median wall and CPU time of a step (ms), leaving out the first fifth (warm-up)."""
    t = np.asarray(step_s[len(step_s) // 5:])
    hist.step_ms, hist.step_cpu_ms = (1e3 * float(v) for v in np.median(t, axis=0))


def _autocast(enabled: bool, device: torch.device):
    if enabled:
        return torch.autocast(device.type, dtype=torch.bfloat16)
    return contextlib.nullcontext()


def _prep(x: torch.Tensor, channels_last: bool) -> torch.Tensor:
    return x.contiguous(memory_format=torch.channels_last) if channels_last else x


def evaluate(model: FinRayNet, images: torch.Tensor, stress: torch.Tensor, force_N: torch.Tensor,
             cfg: TrainConfig, batch_size: int = 256) -> dict:
    """Losses and force errors (N) of ``model`` on a set, in eval mode, on the model's
    device (the set's batches go there; the predicted forces come back to the CPU)."""
    model.eval()
    device = next(model.parameters()).device
    n = len(images)
    s_se, f_se, f_pred = 0.0, 0.0, []
    with torch.no_grad(), _autocast(_use_bf16(cfg, device), device):
        for i in range(0, n, batch_size):
            x = _prep(images[i:i + batch_size].to(device), cfg.channels_last)
            s, f = model.forward_normalised(x)
            s_se += float(((s.float() - stress[i:i + batch_size].to(device)) ** 2).mean()) * len(x)
            fn = model.normalise_force(force_N[i:i + batch_size].to(device))
            f_se += float(((f.float() - fn) ** 2).mean()) * len(x)
            f_pred.append((f.float() * model.force_scale_N + model.force_mean_N).cpu())
    f_pred = torch.cat(f_pred)
    s_mse, f_mse = s_se / n, f_se / n
    return {
        "loss": cfg.alpha_stress * s_mse + cfg.alpha_force * f_mse,
        "stress_mse": s_mse, "force_mse_normalised": f_mse,
        # the first component (fx, the headline force); every component's beside it
        "force_rmse_N": float(((f_pred[:, 0] - force_N[:, 0]) ** 2).mean().sqrt()),
        "force_rmse_components_N": ((f_pred - force_N) ** 2).mean(0).sqrt().tolist(),
        "force_pred_N": f_pred,
    }


def train(images: np.ndarray, stress: np.ndarray, force_N: np.ndarray,
          val: tuple[np.ndarray, np.ndarray, np.ndarray] | None,
          net_cfg: NetConfig, cfg: TrainConfig,
          augment: Callable[[torch.Tensor, torch.Tensor, torch.Generator], tuple] | None = None,
          log: Callable[[str], None] = print,
          camera_images: np.ndarray | None = None) -> tuple[FinRayNet, History]:
    """Train a network; returns the kept model (``cfg.keep``) and the history.

    ``images`` (N, C, H, W) float in [0, 1]; ``stress`` (N, 1, H, W) log-stress maps;
    ``force_N`` (N, n_forces). ``augment(x, s, generator) -> (x, s)`` is applied to each
    training batch (on the fly, seeded by the training generator); with
    ``camera_images`` (N, C, H, W: each frame seen by its randomised camera) it is called
    ``augment(x, s, generator, x_camera)`` and picks between the two views.
    Runs on ``cfg.device`` (:func:`~finray.precision.resolve_device`: ``cuda`` without a
    GPU stops here, before any work); the model is returned on the CPU.
    """
    if cfg.keep not in KEEP:
        raise ValueError(f"train.keep: {cfg.keep!r} is not one of {list(KEEP)}")
    lr_factor(0, 1, cfg.schedule, cfg.warmup_frac)  # an unknown schedule stops here
    device = resolve_device(cfg.device, "train.device")
    if device.type == "cuda":  # deterministic cuBLAS needs a fixed workspace (torch's reproducibility notes)
        os.environ.setdefault("CUBLAS_WORKSPACE_CONFIG", ":4096:8")
    torch.set_num_threads(cfg.threads)
    gen = seed_everything(cfg.seed)
    bf16, why = resolve_bf16(cfg.bf16, device=device)
    cfg = replace(cfg, bf16=bf16)
    log(f"precision: {why}")
    log(f"device: {device_name(device)}")
    x_all = torch.as_tensor(images, dtype=torch.float32)
    s_all = torch.as_tensor(stress, dtype=torch.float32)
    f_all = torch.as_tensor(force_N, dtype=torch.float32).reshape(len(x_all), -1)
    c_all = (torch.as_tensor(camera_images, dtype=torch.float32)
             if camera_images is not None else None)
    if c_all is not None and c_all.shape != x_all.shape:
        raise ValueError(f"camera images {tuple(c_all.shape)} do not match the images {tuple(x_all.shape)}")
    if not (torch.isfinite(x_all).all() and torch.isfinite(s_all).all() and torch.isfinite(f_all).all()):
        raise ValueError("training data contain NaN or infinite values")
    model = FinRayNet(net_cfg)
    mean = f_all.mean(0)
    scale = f_all.std(0).clamp_min(1e-6)
    model.set_force_normalisation(mean, scale)
    model = model.to(device)  # initialised on the CPU: the same weights on any device
    if cfg.channels_last:
        model = model.to(memory_format=torch.channels_last)
    opt = torch.optim.Adam(model.parameters(), lr=cfg.lr)
    mse = nn.MSELoss()
    if val is not None:
        vx, vs, vf = (torch.as_tensor(a, dtype=torch.float32) for a in val)
        vf = vf.reshape(len(vx), -1)
    hist = History(precision="bfloat16" if bf16 else "float32", precision_reason=why,
                   device=device_name(device), force_mean_N=mean.tolist(),
                   force_std_N=scale.tolist())
    best, best_loss = None, math.inf
    n = len(x_all)
    n_batches = max(1, n // cfg.batch_size)  # drop the last partial batch (batch-norm)
    total = cfg.epochs * n_batches
    sched = torch.optim.lr_scheduler.LambdaLR(
        opt, lambda k: lr_factor(k, total, cfg.schedule, cfg.warmup_frac))
    log(f"{cfg.epochs} epochs of {n_batches} batches of {cfg.batch_size} "
        f"({n} frames), {cfg.threads} thread(s); learning rate {cfg.lr:g}, {cfg.schedule}"
        + (f" after a {cfg.warmup_frac:.0%} warm-up" if cfg.schedule == "cosine" else "")
        + (f"; batch-norm re-estimated on {min(cfg.bn_frames, n)} frames per epoch"
           if cfg.bn_frames > 0 else "") + f"; kept: {cfg.keep.replace('_', ' ')}")

    def bn_batches(epoch: int, size: int = 256):
        """``bn_frames`` training frames, augmented as in training, from their own
        generator (the training draws stay those of a run without re-estimates)."""
        g = torch.Generator().manual_seed(cfg.seed * 100003 + epoch)
        pick = torch.randperm(n, generator=g)[:min(cfg.bn_frames, n)]
        for i in range(0, len(pick), size):
            idx = pick[i:i + size]
            x, s = x_all[idx], s_all[idx]
            if augment is not None:
                x, s = augment(x, s, g) if c_all is None else augment(x, s, g, c_all[idx])
            yield x
    step_s: list[tuple[float, float]] = []  # first epoch's (wall, CPU) step times (s)
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
        te = t_log = time.perf_counter()
        for b in bar:
            tb, cb = time.perf_counter(), time.thread_time()
            idx = perm[b * cfg.batch_size:(b + 1) * cfg.batch_size]
            x, s, f = x_all[idx], s_all[idx], f_all[idx]
            if augment is not None:
                x, s = augment(x, s, gen) if c_all is None else augment(x, s, gen, c_all[idx])
            x = _prep(x.to(device), cfg.channels_last)
            s, f = s.to(device), f.to(device)
            with _autocast(bf16, device):
                s_pred, f_pred = model.forward_normalised(x)
            ls = mse(s_pred.float(), s)
            lf = mse(f_pred.float(), model.normalise_force(f))
            loss = cfg.alpha_stress * ls + cfg.alpha_force * lf
            if not torch.isfinite(loss):
                raise FloatingPointError(f"loss became {float(loss)} at epoch {epoch}, batch {b}")
            opt.zero_grad(set_to_none=True)
            loss.backward()
            opt.step()
            sched.step()
            tot["loss"] += float(loss.detach())
            tot["s"] += float(ls.detach())
            tot["f"] += float(lf.detach())
            now = time.perf_counter()
            if epoch == 1:
                step_s.append((now - tb, time.thread_time() - cb))
                if len(step_s) == min(n_batches, 25):  # past the first steps' warm-up
                    _step_times(hist, step_s)
                    log(f"step time {hist.step_ms:.1f} ms ({hist.step_cpu_ms:.1f} ms CPU; "
                        f"{hist.precision}, batch {cfg.batch_size}): about "
                        f"{hist.step_ms * n_batches / 1e3:.0f} s per epoch")
            if now - t_log >= cfg.log_every_s:
                t_log = now
                log(f"epoch {epoch}/{cfg.epochs}: batch {b + 1}/{n_batches}, train loss "
                    f"{tot['loss'] / (b + 1):.5f}, {now - te:.0f} s")
            if tqdm and cfg.progress:
                bar.set_postfix(loss=f"{tot['loss'] / (b + 1):.4f}")
        if epoch == 1 and step_s:  # the whole first epoch (the log line had 25 steps)
            _step_times(hist, step_s)
        hist.epoch.append(epoch)
        hist.train_loss.append(tot["loss"] / n_batches)
        hist.train_stress_mse.append(tot["s"] / n_batches)
        hist.train_force_mse.append(tot["f"] / n_batches)
        hist.lr.append(float(opt.param_groups[0]["lr"]))
        if cfg.compare_running_bn and val is not None:
            hist.val_force_rmse_running_bn_N.append(evaluate(model, vx, vs, vf, cfg)["force_rmse_N"])
        if cfg.bn_frames > 0:
            recalibrate_batchnorm(model, bn_batches(epoch), device, cfg.channels_last, bf16)
        hist.wall_time_s.append(time.perf_counter() - t0)
        msg = f"epoch {epoch}/{cfg.epochs}: train loss {hist.train_loss[-1]:.5f}"
        if val is not None:
            ev = evaluate(model, vx, vs, vf, cfg)
            hist.val_loss.append(ev["loss"])
            hist.val_force_rmse_N.append(ev["force_rmse_N"])
            hist.val_force_rmse_components_N.append(ev["force_rmse_components_N"])
            msg += f", val loss {ev['loss']:.5f}, val force RMSE {ev['force_rmse_N']:.4f} N"
            if hist.val_force_rmse_running_bn_N:
                msg += f" ({hist.val_force_rmse_running_bn_N[-1]:.4f} N with training's batch-norm averages)"
            score = {"val_force_rmse": ev["force_rmse_N"], "val_loss": ev["loss"]}.get(cfg.keep, -epoch)
        else:
            score = hist.train_loss[-1] if cfg.keep != "last" else -epoch
        hist.epoch_time_s.append(time.perf_counter() - te)
        msg += f", {hist.epoch_time_s[-1]:.0f} s"
        if score < best_loss:
            best_loss, best = score, copy.deepcopy(model.state_dict())
            hist.best_epoch = epoch
            msg += " (best)"
        log(msg)
    model.load_state_dict(best)
    model = model.cpu().eval()  # checkpoints and exports load anywhere
    return model, hist


def save_checkpoint(model: FinRayNet, hist: History, path: str | Path, extra: dict | None = None) -> None:
    state = {k: v.detach().cpu() for k, v in model.state_dict().items()}  # loads anywhere
    torch.save({"net_config": model.config_dict(), "state_dict": state,
                "history": asdict(hist), "extra": extra or {}}, path)


def load_checkpoint(path: str | Path) -> tuple[FinRayNet, dict]:
    ck = torch.load(path, map_location="cpu", weights_only=False)
    cfg = dict(ck["net_config"])
    cfg["hidden"] = tuple(cfg["hidden"])
    model = FinRayNet(NetConfig(**cfg))
    model.load_state_dict(ck["state_dict"])
    model.eval()
    return model, ck


def export_torchscript(model: FinRayNet, path: str | Path, preprocess: dict | None = None,
                       forces: list[str] | None = None) -> None:
    """Trace the model (eval mode, float32) to TorchScript: ``forward`` gives (stress,
    force N), ``force`` the force (N) alone (no stress decoder); frozen.

    ``path + '.json'`` keeps the network's settings, the names of the force outputs
    (``forces``, e.g. ``["fx_N", "fy_N"]``; default ``fx_N`` and on) and the preprocessing
    (crop window, base width, segmentation) that :class:`finray.predict.Predictor` needs."""
    model = copy.deepcopy(model).cpu().float().eval().to(memory_format=torch.contiguous_format)
    c = model.cfg
    example = torch.rand(1, c.in_channels, c.height, c.width)
    with torch.no_grad():
        ts = torch.jit.trace_module(model, {"forward": example, "force": example})
        ts = torch.jit.freeze(ts, preserved_attrs=["force"])
    ts.save(str(path))
    names = list(forces or list(FORCE_COMPONENTS.values())[:c.n_forces])
    if len(names) != c.n_forces:
        raise ValueError(f"{len(names)} force names for a model with {c.n_forces} force outputs")
    Path(str(path) + ".json").write_text(json.dumps({**model.config_dict(), "forces": names,
                                                      "preprocess": preprocess or {}}, indent=1))


class _ForceOnly(nn.Module):
    def __init__(self, model: FinRayNet):
        super().__init__()
        self.model = model

    def forward(self, x: torch.Tensor) -> torch.Tensor:
        return self.model.force(x)


def export_onnx(model: FinRayNet, path: str | Path) -> None:
    """Write the model as ONNX (opset 17, float32, any batch size) for ONNX Runtime,
    faster than TorchScript at batch 1 on one CPU thread (``inference_latency.json``
    times both): ``path`` (input
    ``image``, outputs ``stress_log`` and ``force_N``) and ``path`` with suffix
    ``.force.onnx`` (the encoder and force head only, output ``force_N``)."""
    import warnings

    model = copy.deepcopy(model).cpu().float().eval().to(memory_format=torch.contiguous_format)
    c = model.cfg
    example = torch.rand(1, c.in_channels, c.height, c.width)
    path = Path(path)
    with warnings.catch_warnings(), torch.no_grad():
        warnings.simplefilter("ignore")  # the TorchScript-based exporter is deprecated
        torch.onnx.export(model, (example,), str(path), input_names=["image"],
                          output_names=["stress_log", "force_N"], opset_version=17,
                          dynamic_axes={"image": {0: "batch"}, "stress_log": {0: "batch"},
                                        "force_N": {0: "batch"}}, dynamo=False)
        torch.onnx.export(_ForceOnly(model), (example,), str(force_onnx_path(path)),
                          input_names=["image"], output_names=["force_N"], opset_version=17,
                          dynamic_axes={"image": {0: "batch"}, "force_N": {0: "batch"}},
                          dynamo=False)


def force_onnx_path(path: str | Path) -> Path:
    """``model.onnx`` -> ``model.force.onnx``."""
    path = Path(path)
    return path.with_name(path.stem + ".force.onnx")


# ----------------------------------------------------------------------------------
# Data from the dataset stage
# ----------------------------------------------------------------------------------
#: Force components a model can predict -> the shards' per-frame arrays (N): along the
#: push (the FEA's x, the headline force) and across it (y, friction).
FORCE_COMPONENTS = {"fx": "fx_N", "fy": "fy_N"}


def load_split(shards, size: tuple[int, int], every: int = 1,
               forces: tuple[str, ...] = ("fx",), camera: bool = False) -> dict[str, np.ndarray]:
    """The frames of shards at one input size as network tensors (arrays): ``images``
    (N, 1, H, W) in [0, 1], ``stress`` (N, 1, H, W), ``mask`` (N, H, W) bool, ``fx_N``
    (N, 1), ``force_N`` (N, len(forces)): the components ``forces`` (``fx``, ``fy``) in N,
    and per-frame ``scene_id``, ``displacement_mm``; with ``camera`` also
    ``camera_images`` (N, 1, H, W) in [0, 1]: each frame seen by its randomised camera.
    ``every``: keep every ``every``-th frame of each shard (see
    :func:`finray.dataset.load_frames`)."""
    from .dataset import load_frames

    a, table = load_frames(shards, size, every, require_stress=True, camera=camera)
    bad = [c for c in forces if c not in FORCE_COMPONENTS]
    if bad:
        raise ValueError(f"train.forces: unknown component(s) {bad}; known: {list(FORCE_COMPONENTS)}")
    out = {} if not camera else {
        "camera_images": a["camera_images"][:, None].astype(np.float32) / np.float32(255.0)}
    return out | {"images": a["images"][:, None].astype(np.float32) / np.float32(255.0),
            "stress": a["stress"][:, None].astype(np.float32), "mask": a["mask"],
            "fx_N": a["fx_N"][:, None].astype(np.float32),
            "force_N": np.column_stack([a[FORCE_COMPONENTS[c]] for c in forces]).astype(np.float32),
            "scene_id": np.array(table["scene_id"].tolist()),
            "displacement_mm": table["displacement_mm"].to_numpy()}


def validation_scenes(scene_ids, fraction: float, seed: int) -> set[str]:
    """Whole scenes held out for validation (frames of one scene are too alike to split)."""
    ids = sorted(set(scene_ids))
    rng = np.random.default_rng(seed)
    n_val = max(1, int(round(fraction * len(ids)))) if len(ids) > 1 else 0
    return set(rng.permutation(ids)[:n_val].tolist())


def train_from_shards(shards, out_dir: str | Path, net_cfg: NetConfig, cfg: TrainConfig,
                      augment: AugmentConfig | None, val_fraction: float = 0.1,
                      occlusion_levels: dict | None = None, preprocess: dict | None = None,
                      forces: tuple[str, ...] = ("fx",), frame_every: int = 1, log=print) -> dict:
    """Train on the shards (force components ``forces``, ``fx`` first; ``net_cfg.n_forces``
    is set to match), keep the epoch ``cfg.keep`` chooses and write
    ``model.pt``, ``model.ts`` (TorchScript), ``model.onnx`` and ``model.force.onnx``
    (ONNX), ``history.json`` and ``curves.png``. ``frame_every``: train and validate on
    every ``frame_every``-th frame of each scene (the rendered frames are interpolated
    between solver frames, so neighbours are near copies; the training-budget study).
    ``cuda`` without a GPU stops before the data load."""
    resolve_device(cfg.device, "train.device")
    if int(frame_every) < 1:
        raise ValueError(f"train.frame_every must be >= 1, got {frame_every}")
    out_dir = Path(out_dir)
    out_dir.mkdir(parents=True, exist_ok=True)
    forces = tuple(forces)
    if not forces or forces[0] != "fx":
        raise ValueError(f"train.forces must start with fx (the headline force), got {list(forces)}")
    net_cfg = replace(net_cfg, n_forces=len(forces))
    camera = augment is not None and augment.camera_p > 0
    data = load_split(shards, (net_cfg.height, net_cfg.width), every=frame_every, forces=forces,
                      camera=camera)
    val_ids = validation_scenes(data["scene_id"], val_fraction, cfg.seed)
    is_val = np.isin(data["scene_id"], list(val_ids))
    tr = {k: v[~is_val] for k, v in data.items()}
    va = {k: v[is_val] for k, v in data.items()}
    log(f"training frames {len(tr['images'])} from {len(set(tr['scene_id']))} scenes, "
        f"validation frames {len(va['images'])} from {len(val_ids)} scenes")
    aug = TrainAugment(augment, occlusion_levels) if augment is not None else None
    val = (va["images"], va["stress"], va["force_N"]) if len(va["images"]) else None
    if camera and val is not None:  # validate on both views of the validation frames
        val = (np.concatenate([va["images"], va["camera_images"]]), np.concatenate([va["stress"]] * 2),
               np.concatenate([va["force_N"]] * 2))
    t0, c0 = time.perf_counter(), time.process_time()
    model, hist = train(tr["images"], tr["stress"], tr["force_N"], val, net_cfg, cfg, aug, log=log,
                        camera_images=tr.get("camera_images"))
    seconds, cpu_seconds = time.perf_counter() - t0, time.process_time() - c0
    extra = {"train_config": asdict(cfg), "augment": asdict(augment) if augment else None,
             "cpu": cpu_name(), "device": hist.device, "torch_threads": torch.get_num_threads(),
             "validation_scenes": sorted(val_ids), "n_train": int(len(tr["images"])),
             "n_val": int(len(va["images"])), "train_seconds": seconds,
             "train_cpu_seconds": cpu_seconds, "frame_every": int(frame_every),
             "forces": [FORCE_COMPONENTS[c] for c in forces]}
    save_checkpoint(model, hist, out_dir / "model.pt", extra)
    export_torchscript(model, out_dir / "model.ts", preprocess, extra["forces"])
    export_onnx(model, out_dir / "model.onnx")
    (out_dir / "history.json").write_text(json.dumps({**asdict(hist), **extra}, indent=1))
    training_curves(hist, out_dir / "curves.png")
    return extra


def training_curves(hist: History, path: str | Path) -> None:
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    fig, ax = plt.subplots(1, 2, figsize=(8, 3.2))
    ax[0].semilogy(hist.epoch, hist.train_loss, "o-", label="train")
    if hist.val_loss:
        ax[0].semilogy(hist.epoch, hist.val_loss, "s-", label="validation")
    ax[0].set_xlabel("epoch")
    ax[0].set_ylabel("loss (stress MSE + 10 force MSE)")
    ax[0].legend()
    if hist.val_force_rmse_N:
        ax[1].plot(hist.epoch, hist.val_force_rmse_N, "s-", label="batch-norm re-estimated"
                   if hist.val_force_rmse_running_bn_N else None)
    if hist.val_force_rmse_running_bn_N:
        ax[1].plot(hist.epoch, hist.val_force_rmse_running_bn_N, "x--", color="0.5",
                   label="training's running batch-norm averages")
        ax[1].legend(fontsize=7)
    ax[1].set_xlabel("epoch")
    ax[1].set_ylabel("validation force RMSE (N)")
    fig.tight_layout()
    fig.savefig(path, dpi=130)
    plt.close(fig)
