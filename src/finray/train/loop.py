"""The training loop of :class:`~finray.model.FinRayNet`, on the CPU or a CUDA GPU.

Loss (the paper's eq. 1): ``alpha_stress * MSE(stress) + alpha_force * MSE(force)``,
each force component (``fx`` along the push, ``fy`` across it, as the paper's two-output
head) normalised by the training set's mean and standard deviation (stored in the
model, so that its outputs are in N), the MSE taken over the components. Adam, seeded
and deterministic: two runs with the same data and seed give identical losses.

With ``contact_weight`` > 0 (ours) the loss also has ``contact_weight * MSE(contact)``:
the contact height (mm), normalised by the mean and standard deviation of the frames it
is taken over (:func:`contact_mask`: a finite height and ``|fx| > contact_min_force_N``;
at first touch the FEA's contact is a node or two and the image barely changes, so the
height there is neither well defined nor visible). A batch without such frames adds 0.

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
- With ``ema_decay`` > 0 the weights validated and kept at each epoch's end are an
  exponential moving average of the trained ones (:class:`WeightAverage`, updated after
  every step; its batch-norm statistics re-estimated as above): the average of the last
  steps rather than where the last mini-batches left the weights.

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
import math
import os
import time
from dataclasses import dataclass, replace
from typing import Callable

import numpy as np
import torch
from torch import nn

from ..model import FinRayNet, NetConfig
from ..precision import device_name, resolve_bf16, resolve_device
from .precision_trial import time_precisions
from .config import KEEP, SCHEDULES, History, TrainConfig
from ..schema import schema_default


def seed_everything(seed: int) -> torch.Generator:
    torch.manual_seed(seed)
    np.random.seed(seed % 2**32)
    torch.use_deterministic_algorithms(True)
    g = torch.Generator()
    g.manual_seed(seed)
    return g


def lr_factor(
    step: int,
    total: int,
    schedule: str = schema_default("train.schedule"),
    warmup_frac: float = schema_default("train.warmup_frac"),
) -> float:
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
def recalibrate_batchnorm(
    model: FinRayNet, batches, device: torch.device, channels_last: bool, bf16: bool
) -> int:
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


class WeightAverage:
    """An exponential moving average of a model's weights, ``module`` (a copy of the
    model): the first update copies the weights, each later one moves the average by
    ``1 - decay`` towards them. The arithmetic of ``torch.optim.swa_utils.AveragedModel``
    with ``get_ema_multi_avg_fn`` (one ``torch._foreach_lerp_``), without its per-call
    regrouping of the tensors, which cost a camera model's step three times what the
    average itself costs (studies/training_speed/README.md, "Weight averaging"). Buffers
    (batch-norm statistics) are not averaged: :meth:`take_buffers` copies the trained
    model's."""

    def __init__(self, model: nn.Module, decay: float):
        self.module, self.decay, self.updates = copy.deepcopy(model), float(decay), 0
        self._model = model
        self._mine = [p.detach() for p in self.module.parameters()]
        self._trained = [p.detach() for p in model.parameters()]
        self.module.requires_grad_(False)

    @torch.no_grad()
    def take_buffers(self) -> None:
        """The trained model's buffers (batch-norm statistics) into the average."""
        for mine, trained in zip(self.module.buffers(), self._model.buffers()):
            mine.copy_(trained)

    @torch.no_grad()
    def update(self) -> None:
        if self.updates == 0:
            torch._foreach_copy_(self._mine, self._trained)
        else:
            torch._foreach_lerp_(self._mine, self._trained, 1.0 - self.decay)
        self.updates += 1


def contact_mask(contact_mm: torch.Tensor, fx_N: torch.Tensor, min_force_N: float) -> torch.Tensor:
    """Frames whose contact height trains and scores the contact head (bool (N,)): a finite
    height (mm) and ``|fx_N| > min_force_N`` (N)."""
    return torch.isfinite(contact_mm) & (fx_N.abs() > min_force_N)


def _masked_mse(pred: torch.Tensor, target: torch.Tensor, mask: torch.Tensor) -> torch.Tensor:
    """Mean squared error over ``mask``'s frames (0 where there are none); NaN targets
    outside the mask touch neither the value nor the gradient."""
    m = mask.to(pred.dtype)
    err = torch.where(
        mask, pred - torch.where(mask, target, torch.zeros_like(target)), torch.zeros_like(pred)
    )
    return (err**2 * m).sum() / m.sum().clamp_min(1.0)


def _use_bf16(cfg: TrainConfig, device: torch.device) -> bool:
    return resolve_bf16(cfg.bf16, device=device)[0] if isinstance(cfg.bf16, str) else bool(cfg.bf16)


def _precision_trial(model: FinRayNet, data: _TrainData, cfg: TrainConfig, device):
    """Training steps of each numeric type timed on a copy of ``model``, on the first
    batch of training frames (:mod:`finray.train.precision_trial`)."""
    idx = torch.arange(min(cfg.batch_size, data.n))
    x, s = data.x[idx], data.s[idx]
    return time_precisions(
        model,
        lambda m, bf16: _batch_loss(m, data, idx, x, s, cfg, device, bf16)[0],
        lr=cfg.lr,
    )


def _step_times(hist: History, step_s: list[tuple[float, float]]) -> None:
    """Median wall and CPU time of a step (ms), leaving out the first fifth (warm-up)."""
    t = np.asarray(step_s[len(step_s) // 5 :])
    hist.step_ms, hist.step_cpu_ms = (1e3 * float(v) for v in np.median(t, axis=0))


def _autocast(enabled: bool, device: torch.device):
    if enabled:
        return torch.autocast(device.type, dtype=torch.bfloat16)
    return contextlib.nullcontext()


def _prep(x: torch.Tensor, channels_last: bool) -> torch.Tensor:
    return x.contiguous(memory_format=torch.channels_last) if channels_last else x


def evaluate(
    model: FinRayNet,
    images: torch.Tensor,
    stress: torch.Tensor,
    force_N: torch.Tensor,
    cfg: TrainConfig,
    batch_size: int = 256,
    contact_mm: torch.Tensor | None = None,
) -> dict:
    """Losses and force errors (N) of ``model`` on a set, in eval mode, on the model's
    device (the set's batches go there; the predicted forces come back to the CPU).
    A model with the contact head, given ``contact_mm`` (N,): also ``contact_pred_mm``
    (N,), and ``contact_rmse_mm`` and the loss's contact term over :func:`contact_mask`'s
    frames (NaN and 0 where there are none)."""
    model.eval()
    device = next(model.parameters()).device
    n = len(images)
    contact = model.cfg.contact and contact_mm is not None
    s_se, f_se, f_pred, c_pred = 0.0, 0.0, [], []
    with torch.no_grad(), _autocast(_use_bf16(cfg, device), device):
        for i in range(0, n, batch_size):
            x = _prep(images[i : i + batch_size].to(device), cfg.channels_last)
            s, f, c = model.forward_normalised_all(x)
            s_se += float(((s.float() - stress[i : i + batch_size].to(device)) ** 2).mean()) * len(
                x
            )
            fn = model.normalise_force(force_N[i : i + batch_size].to(device))
            f_se += float(((f.float() - fn) ** 2).mean()) * len(x)
            f_pred.append((f.float() * model.force_scale_N + model.force_mean_N).cpu())
            if contact:
                c_pred.append((c.float() * model.contact_scale_mm + model.contact_mean_mm).cpu())
    f_pred = torch.cat(f_pred)
    s_mse, f_mse = s_se / n, f_se / n
    out = {
        "loss": cfg.alpha_stress * s_mse + cfg.alpha_force * f_mse,
        "stress_mse": s_mse,
        "force_mse_normalised": f_mse,
        # the first component (fx, the headline force); every component's beside it
        "force_rmse_N": float(((f_pred[:, 0] - force_N[:, 0]) ** 2).mean().sqrt()),
        "force_rmse_components_N": ((f_pred - force_N) ** 2).mean(0).sqrt().tolist(),
        "force_pred_N": f_pred,
    }
    if contact:
        c_pred = torch.cat(c_pred)
        mask = contact_mask(contact_mm, force_N[:, 0], cfg.contact_min_force_N)
        se = _masked_mse(c_pred, contact_mm, mask)
        scale = float(model.contact_scale_mm.cpu())
        out.update(
            contact_pred_mm=c_pred,
            contact_mse_normalised=float(se) / scale**2,
            contact_rmse_mm=float(se.sqrt()) if mask.any() else float("nan"),
        )
        out["loss"] += cfg.contact_weight * out["contact_mse_normalised"]
    return out


@dataclass
class _TrainData:
    """The training frames as tensors (CPU): images ``x``, log-stress ``s``, forces ``f``
    (N), camera views ``c``, force weights ``w``, contact heights ``y`` (mm) and the
    frames that train the contact head ``ym``."""

    x: torch.Tensor
    s: torch.Tensor
    f: torch.Tensor
    c: torch.Tensor | None
    w: torch.Tensor | None
    y: torch.Tensor | None
    ym: torch.Tensor | None
    contact: bool

    @property
    def n(self) -> int:
        return len(self.x)

    @classmethod
    def checked(
        cls,
        images,
        stress,
        force_N,
        camera_images,
        force_weight,
        contact_mm,
        net_cfg: NetConfig,
        cfg: TrainConfig,
    ) -> "_TrainData":
        """The arrays as tensors, each checked against the images (one line per fault)."""
        x = torch.as_tensor(images, dtype=torch.float32)
        s = torch.as_tensor(stress, dtype=torch.float32)
        f = torch.as_tensor(force_N, dtype=torch.float32).reshape(len(x), -1)
        c = (
            torch.as_tensor(camera_images, dtype=torch.float32)
            if camera_images is not None
            else None
        )
        if c is not None and c.shape != x.shape:
            raise ValueError(
                f"camera images {tuple(c.shape)} do not match the images {tuple(x.shape)}"
            )
        w = (
            None
            if force_weight is None
            else torch.as_tensor(force_weight, dtype=torch.float32).reshape(-1)
        )
        if w is not None and len(w) != len(x):
            raise ValueError(f"{len(w)} force weights for {len(x)} frames")
        if not (torch.isfinite(x).all() and torch.isfinite(s).all() and torch.isfinite(f).all()):
            raise ValueError("training data contain NaN or infinite values")
        contact = net_cfg.contact
        if contact != (cfg.contact_weight > 0):
            raise ValueError(
                f"train.contact_weight {cfg.contact_weight:g} and a network "
                f"{'with' if contact else 'without'} the contact head do not go together"
            )
        y = ym = None
        if contact:
            if contact_mm is None:
                raise ValueError("train.contact_weight > 0 needs the frames' contact heights")
            y = torch.as_tensor(contact_mm, dtype=torch.float32).reshape(-1)
            if len(y) != len(x):
                raise ValueError(f"{len(y)} contact heights for {len(x)} frames")
            ym = contact_mask(y, f[:, 0], cfg.contact_min_force_N)
            if not ym.any():
                raise ValueError(
                    f"train.contact_weight > 0, but no training frame has a contact "
                    f"height with |fx| above {cfg.contact_min_force_N:g} N (shards built "
                    "before the FEA wrote contact_y_mm?); rebuild them or set "
                    "train.contact_weight: 0"
                )
        return cls(x, s, f, c, w, y, ym, contact)

    def batch(self, idx: torch.Tensor, augment, gen: torch.Generator):
        """Images and stress of the frames ``idx``, augmented (``augment`` drawing from ``gen``)."""
        x, s = self.x[idx], self.s[idx]
        if augment is not None:
            x, s = augment(x, s, gen) if self.c is None else augment(x, s, gen, self.c[idx])
        return x, s

    def bn_batches(self, epoch: int, cfg: TrainConfig, augment, size: int = 256):
        """``cfg.bn_frames`` training frames, augmented as in training, from their own
        generator (the training draws stay those of a run without re-estimates)."""
        g = torch.Generator().manual_seed(cfg.seed * 100003 + epoch)
        pick = torch.randperm(self.n, generator=g)[: min(cfg.bn_frames, self.n)]
        for i in range(0, len(pick), size):
            yield self.batch(pick[i : i + size], augment, g)[0]


def _new_model(net_cfg: NetConfig, data: _TrainData, init_state: dict | None):
    """A new network (CPU) with the training forces' normalisation (and the contact
    heights'), or ``init_state``'s weights and normalisation; with the force mean and
    scale (N) it trains with."""
    model = FinRayNet(net_cfg)
    mean = data.f.mean(0)
    scale = data.f.std(0).clamp_min(1e-6)
    model.set_force_normalisation(mean, scale)
    if data.contact:
        y_in = data.y[data.ym]
        model.set_contact_normalisation(
            y_in.mean(), y_in.std().clamp_min(1e-3) if len(y_in) > 1 else 1.0
        )
    if init_state is not None:  # fine-tuning: the start's weights, its force scale too
        model.load_state_dict(init_state)
        mean, scale = model.force_mean_N.clone(), model.force_scale_N.clone()
    return model, mean, scale


@dataclass
class _ValSet:
    """The validation frames as tensors (the contact heights ``c`` for a contact head)."""

    x: torch.Tensor
    s: torch.Tensor
    f: torch.Tensor
    c: torch.Tensor | None

    @classmethod
    def of(cls, val, contact: bool) -> "_ValSet | None":
        if val is None:
            return None
        vx, vs, vf, *rest = (torch.as_tensor(a, dtype=torch.float32) for a in val)
        return cls(
            vx, vs, vf.reshape(len(vx), -1), rest[0].reshape(-1) if contact and rest else None
        )


class _Keeper:
    """The kept epoch's weights: the lowest score offered (``train.keep``)."""

    def __init__(self):
        self.best, self.score = None, math.inf

    def offer(self, score: float, model: FinRayNet) -> bool:
        if score < self.score:
            self.score, self.best = score, copy.deepcopy(model.state_dict())
            return True
        return False


def _batch_loss(
    model: FinRayNet,
    data: _TrainData,
    idx: torch.Tensor,
    x: torch.Tensor,
    s: torch.Tensor,
    cfg: TrainConfig,
    device: torch.device,
    bf16: bool,
):
    """The loss of one batch (``x``, ``s`` augmented) and its terms: stress MSE, force MSE
    (normalised; weighted by ``data.w``), contact MSE (None without the head)."""
    f = data.f[idx].to(device)
    x = _prep(x.to(device), cfg.channels_last)
    s = s.to(device)
    with _autocast(bf16, device):
        s_pred, f_pred, c_pred = model.forward_normalised_all(x)
    ls = nn.functional.mse_loss(s_pred.float(), s)
    if data.w is None:
        lf = nn.functional.mse_loss(f_pred.float(), model.normalise_force(f))
    else:
        se = ((f_pred.float() - model.normalise_force(f)) ** 2).mean(1)
        lf = (se * data.w[idx].to(device)).mean()
    loss = cfg.alpha_stress * ls + cfg.alpha_force * lf
    lc = None
    if data.contact:
        lc = _masked_mse(
            c_pred.float(), model.normalise_contact(data.y[idx].to(device)), data.ym[idx].to(device)
        )
        loss = loss + cfg.contact_weight * lc
    return loss, ls, lf, lc


def _train_epoch(
    model,
    data: _TrainData,
    opt,
    sched,
    gen,
    augment,
    cfg: TrainConfig,
    device,
    bf16: bool,
    epoch: int,
    n_batches: int,
    hist: History,
    log,
    ema: WeightAverage | None = None,
) -> dict:
    """One pass over the shuffled training frames; the summed loss and terms. The first
    epoch's step times go into ``hist`` (a log line after 25 steps). ``ema``: the
    weights' moving average, updated after every step."""
    try:
        from tqdm import tqdm
    except ImportError:  # pragma: no cover
        tqdm = None
    model.train()
    perm = torch.randperm(data.n, generator=gen)
    tot = {"loss": 0.0, "s": 0.0, "f": 0.0, "c": 0.0}
    it = range(n_batches)
    bar = (
        tqdm(it, desc=f"epoch {epoch}/{cfg.epochs}", leave=False, disable=not cfg.progress)
        if tqdm
        else it
    )
    step_s: list[tuple[float, float]] = []  # first epoch's (wall, CPU) step times (s)
    te = t_log = time.perf_counter()
    for b in bar:
        tb, cb = time.perf_counter(), time.thread_time()
        idx = perm[b * cfg.batch_size : (b + 1) * cfg.batch_size]
        x, s = data.batch(idx, augment, gen)
        loss, ls, lf, lc = _batch_loss(model, data, idx, x, s, cfg, device, bf16)
        if lc is not None:
            tot["c"] += float(lc.detach())
        if not torch.isfinite(loss):
            raise FloatingPointError(f"loss became {float(loss)} at epoch {epoch}, batch {b}")
        opt.zero_grad(set_to_none=True)
        loss.backward()
        opt.step()
        sched.step()
        if ema is not None:
            ema.update()
        tot["loss"] += float(loss.detach())
        tot["s"] += float(ls.detach())
        tot["f"] += float(lf.detach())
        now = time.perf_counter()
        if epoch == 1:
            step_s.append((now - tb, time.thread_time() - cb))
            if len(step_s) == min(n_batches, 25):  # past the first steps' warm-up
                _step_times(hist, step_s)
                log(
                    f"step time {hist.step_ms:.1f} ms ({hist.step_cpu_ms:.1f} ms CPU; "
                    f"{hist.precision}, batch {cfg.batch_size}): about "
                    f"{hist.step_ms * n_batches / 1e3:.0f} s per epoch"
                )
        if now - t_log >= cfg.log_every_s:
            t_log = now
            log(
                f"epoch {epoch}/{cfg.epochs}: batch {b + 1}/{n_batches}, train loss "
                f"{tot['loss'] / (b + 1):.5f}, {now - te:.0f} s"
            )
        if tqdm and cfg.progress:
            bar.set_postfix(loss=f"{tot['loss'] / (b + 1):.4f}")
    if step_s:  # the whole first epoch (the log line had 25 steps)
        _step_times(hist, step_s)
    return tot


def _validate(
    model: FinRayNet, vset: _ValSet | None, cfg: TrainConfig, hist: History, epoch: int
) -> tuple[str, float]:
    """The epoch's log line and its score for ``train.keep`` (lower is better): the
    validation metrics (into ``hist``), or the training loss without validation frames."""
    msg = f"epoch {epoch}/{cfg.epochs}: train loss {hist.train_loss[-1]:.5f}"
    if vset is None:
        return msg, (hist.train_loss[-1] if cfg.keep != "last" else -epoch)
    ev = evaluate(model, vset.x, vset.s, vset.f, cfg, contact_mm=vset.c)
    hist.val_loss.append(ev["loss"])
    hist.val_force_rmse_N.append(ev["force_rmse_N"])
    hist.val_force_rmse_components_N.append(ev["force_rmse_components_N"])
    msg += f", val loss {ev['loss']:.5f}, val force RMSE {ev['force_rmse_N']:.4f} N"
    if "contact_rmse_mm" in ev:
        hist.val_contact_rmse_mm.append(ev["contact_rmse_mm"])
        msg += f", val contact RMSE {ev['contact_rmse_mm']:.2f} mm"
    if hist.val_force_rmse_running_bn_N:
        msg += (
            f" ({hist.val_force_rmse_running_bn_N[-1]:.4f} N with training's batch-norm averages)"
        )
    return msg, {"val_force_rmse": ev["force_rmse_N"], "val_loss": ev["loss"]}.get(cfg.keep, -epoch)


def train(
    images: np.ndarray,
    stress: np.ndarray,
    force_N: np.ndarray,
    val: tuple[np.ndarray, np.ndarray, np.ndarray] | None,
    net_cfg: NetConfig,
    cfg: TrainConfig,
    augment: Callable[[torch.Tensor, torch.Tensor, torch.Generator], tuple] | None = None,
    log: Callable[[str], None] = print,
    camera_images: np.ndarray | None = None,
    init_state: dict | None = None,
    contact_mm: np.ndarray | None = None,
    force_weight: np.ndarray | None = None,
) -> tuple[FinRayNet, History]:
    """Train a network; returns the kept model (``cfg.keep``) and the history.

    ``images`` (N, C, H, W) float in [0, 1]; ``stress`` (N, 1, H, W) log-stress maps;
    ``force_N`` (N, n_forces). ``augment(x, s, generator) -> (x, s)`` is applied to each
    training batch (on the fly, seeded by the training generator); with
    ``camera_images`` (N, C, H, W: each frame seen by its randomised camera) it is called
    ``augment(x, s, generator, x_camera)`` and picks between the two views.
    Runs on ``cfg.device`` (:func:`~finray.precision.resolve_device`: ``cuda`` without a
    GPU stops here, before any work); the model is returned on the CPU. ``init_state``:
    a state dict of the same network to start from instead of new weights.
    ``contact_mm`` (N,): each frame's contact height (mm, NaN where none), for a network
    with the contact head (``net_cfg.contact``, which goes with ``cfg.contact_weight`` >
    0); ``val`` then has a fourth array, the validation frames' heights.
    ``force_weight`` (N,): each frame's weight in the force term (mean 1; None: 1 each;
    :func:`~finray.train.data.scene_force_weights` for ``cfg.force_loss`` relative).
    """
    if cfg.keep not in KEEP:
        raise ValueError(f"train.keep: {cfg.keep!r} is not one of {list(KEEP)}")
    lr_factor(0, 1, cfg.schedule, cfg.warmup_frac)  # an unknown schedule stops here
    device = resolve_device(cfg.device, "train.device")
    if (
        device.type == "cuda"
    ):  # deterministic cuBLAS needs a fixed workspace (torch's reproducibility notes)
        os.environ.setdefault("CUBLAS_WORKSPACE_CONFIG", ":4096:8")
    torch.set_num_threads(cfg.threads)
    gen = seed_everything(cfg.seed)
    bf16, why = resolve_bf16(cfg.bf16, device=device)
    data = _TrainData.checked(
        images, stress, force_N, camera_images, force_weight, contact_mm, net_cfg, cfg
    )
    model, mean, scale = _new_model(net_cfg, data, init_state)
    model = model.to(device)  # initialised on the CPU: the same weights on any device
    if cfg.channels_last:
        model = model.to(memory_format=torch.channels_last)
    trial = None
    if cfg.bf16 == "auto" and device.type == "cpu" and bf16:
        # the CPU computes bfloat16 in hardware: whether it is faster is measured
        trial = _precision_trial(model, data, cfg, device)
        bf16, why = trial.bf16, trial.describe()
    if device.type == "cuda" and not bf16:
        # cuDNN convolutions default to TF32 (10-bit mantissa) on Ampere and later: a
        # float32 run is float32, as on the CPU
        torch.backends.cudnn.allow_tf32 = False
        torch.backends.cuda.matmul.allow_tf32 = False
    cfg = replace(cfg, bf16=bf16)
    log(f"precision: {why}")
    log(f"device: {device_name(device)}")
    opt = torch.optim.Adam(model.parameters(), lr=cfg.lr)
    vset = _ValSet.of(val, data.contact)
    hist = History(
        precision="bfloat16" if bf16 else "float32",
        precision_reason=why,
        precision_trial_ms=trial.as_dict() if trial else None,
        device=device_name(device),
        force_mean_N=mean.tolist(),
        force_std_N=scale.tolist(),
    )
    if data.contact:
        hist.contact_mean_mm = float(model.contact_mean_mm)
        hist.contact_std_mm = float(model.contact_scale_mm)
        hist.n_contact_frames = int(data.ym.sum())
        log(
            f"contact height: {hist.n_contact_frames} of {data.n} training frames "
            f"(|fx| > {cfg.contact_min_force_N:g} N), mean {hist.contact_mean_mm:.1f} mm, "
            f"sd {hist.contact_std_mm:.1f} mm; loss weight {cfg.contact_weight:g}"
        )
    n = data.n
    n_batches = max(1, n // cfg.batch_size)  # drop the last partial batch (batch-norm)
    total = cfg.epochs * n_batches
    sched = torch.optim.lr_scheduler.LambdaLR(
        opt, lambda k: lr_factor(k, total, cfg.schedule, cfg.warmup_frac)
    )
    log(
        f"{cfg.epochs} epochs of {n_batches} batches of {cfg.batch_size} "
        f"({n} frames), {cfg.threads} thread(s); learning rate {cfg.lr:g}, {cfg.schedule}"
        + (f" after a {cfg.warmup_frac:.0%} warm-up" if cfg.schedule == "cosine" else "")
        + (
            f"; batch-norm re-estimated on {min(cfg.bn_frames, n)} frames per epoch"
            if cfg.bn_frames > 0
            else ""
        )
        + (f"; weights averaged (EMA, decay {cfg.ema_decay:g})" if cfg.ema_decay > 0 else "")
        + f"; kept: {cfg.keep.replace('_', ' ')}"
    )
    keeper = _Keeper()
    # the weights validated and kept: the trained ones, or their moving average
    ema = WeightAverage(model, cfg.ema_decay) if cfg.ema_decay > 0 else None
    scored = model if ema is None else ema.module
    t0 = time.perf_counter()
    for epoch in range(1, cfg.epochs + 1):
        te = time.perf_counter()
        tot = _train_epoch(
            model,
            data,
            opt,
            sched,
            gen,
            augment,
            cfg,
            device,
            bf16,
            epoch,
            n_batches,
            hist,
            log,
            ema,
        )
        hist.epoch.append(epoch)
        hist.train_loss.append(tot["loss"] / n_batches)
        hist.train_stress_mse.append(tot["s"] / n_batches)
        hist.train_force_mse.append(tot["f"] / n_batches)
        if data.contact:
            hist.train_contact_mse.append(tot["c"] / n_batches)
        hist.lr.append(float(opt.param_groups[0]["lr"]))
        if ema is not None:  # the average's batch-norm statistics start from training's
            ema.take_buffers()
        if cfg.compare_running_bn and vset is not None:
            hist.val_force_rmse_running_bn_N.append(
                evaluate(scored, vset.x, vset.s, vset.f, cfg)["force_rmse_N"]
            )
        if cfg.bn_frames > 0:
            recalibrate_batchnorm(
                scored, data.bn_batches(epoch, cfg, augment), device, cfg.channels_last, bf16
            )
        hist.wall_time_s.append(time.perf_counter() - t0)
        msg, score = _validate(scored, vset, cfg, hist, epoch)
        hist.epoch_time_s.append(time.perf_counter() - te)
        msg += f", {hist.epoch_time_s[-1]:.0f} s"
        if keeper.offer(score, scored):
            hist.best_epoch = epoch
            msg += " (best)"
        log(msg)
    best = keeper.best
    model.load_state_dict(best)
    model = model.cpu().eval()  # checkpoints and exports load anywhere
    return model, hist
