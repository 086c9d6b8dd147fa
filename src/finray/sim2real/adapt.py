"""Adapting a simulation-trained network to a rig: an ensemble of force heads on its
frozen encoder.

A rig's finger is not the simulated one (a print is stiffer or softer, grips more), so
the same deformation image means another force. The rig gets its own force heads,
each started from the simulation's head and fitted on the rig's frames (a bootstrap
sample of them, its own seed) with the encoder, the stress decoder and the
simulation's head frozen: the network cannot forget the simulation, and a fit takes
seconds, as the encoder's features are computed once. The members' spread is the
per-frame uncertainty of the network (:mod:`finray.sim2real.calibration` adds the sensor's).

- :func:`encoder_features` -- the frozen encoder's latent per frame
- :func:`fit_heads` -- the head ensemble on features and forces (N); :func:`head_from_state`
  one of its heads again from its weights
- :class:`SimAnchor` -- simulated frames fitted beside a rig's context frames
- :class:`HeadEnsemble` -- the network with the heads: ``force`` (mean, N),
  ``members`` (each head's, N); :func:`export_ensemble` writes it for
  :class:`finray.predict.Predictor`
"""

from __future__ import annotations

import copy
import json
import math
from dataclasses import dataclass
from pathlib import Path

import numpy as np
import torch
from torch import nn

from ..errors import CalibrationError
from ..model import FinRayNet
from ..schema import schema_default


@dataclass(frozen=True)
class HeadFit:
    """How the heads are fitted: ``members`` heads of ``steps`` Adam steps (batches of
    ``batch``, learning rate ``lr``, decayed to 0 on a cosine where ``lr_decay``), each
    on a bootstrap sample of the frames (``bootstrap``), seeded from ``seed``; of each
    head only the last ``layers`` linear layers are fitted (0: all). Where ``epochs`` > 0
    the steps follow the frames instead: ``ceil(epochs * frames / batch)``.

    Why ``epochs``: at a fixed step count, two context objects' frames were each seen
    half as often as one object's, and on one training of six the adapted error rose from
    one context object to two (3.22 to 3.42 % NRMSE before calibration); at the same
    passes over the frames it fell on all six (docs/studies/seeds.md, "Seeds, numeric types and what to
    expect").

    Fitting the whole head made it worse than the simulation's own, even on frames like
    those it was trained on: Adam moves every weight by up to ``lr`` a step whatever
    its gradient, and the first layer's 131,072 weights (latent 1024 -> 128) are of the
    order of 0.01, so a few hundred steps at 1e-3 overwrite what the simulation taught
    it with noise. The last three layers (64 -> 32 -> 8 -> 1, 2,353 parameters) adapt
    the force to a rig while the features the head learnt on 18,000 frames stay.

    The decay is what makes the members' spread a measure of the data: at a constant
    rate each head ends where its last mini-batches left it, and the heads then disagree
    even on frames that every bootstrap sample holds hundreds of times (a rig's rest
    frames), by the optimiser's jitter rather than by what the frames leave open."""

    members: int = schema_default("evaluate.sim2real.heads.members")
    steps: int = schema_default("evaluate.sim2real.heads.steps")
    batch: int = schema_default("evaluate.sim2real.heads.batch")
    lr: float = schema_default("evaluate.sim2real.heads.lr")
    lr_decay: bool = schema_default("evaluate.sim2real.heads.lr_decay")
    bootstrap: bool = schema_default("evaluate.sim2real.heads.bootstrap")
    seed: int = schema_default("evaluate.sim2real.heads.seed")
    # fit the last this many linear layers only (0: every layer)
    layers: int = schema_default("evaluate.sim2real.heads.layers")
    # > 0: steps = ceil(epochs * frames / batch), in place of steps
    epochs: float = schema_default("evaluate.sim2real.heads.epochs", float)

    def n_steps(self, frames: int) -> int:
        """The Adam steps of one head fitted on ``frames`` frames."""
        return (
            max(1, math.ceil(self.epochs * frames / self.batch)) if self.epochs > 0 else self.steps
        )


def encoder_features(model: FinRayNet, images, batch: int = 256) -> torch.Tensor:
    """The encoder's flattened latent (N, F) of images (N, 1, H, W) in [0, 1]."""
    model.eval()
    x = torch.tensor(np.asarray(images, dtype=np.float32))
    with torch.inference_mode():
        return (
            torch.cat(
                [model.encode(x[i : i + batch])[0].flatten(1) for i in range(0, len(x), batch)]
            )
            if len(x)
            else torch.zeros(0)
        )


@dataclass(frozen=True)
class SimAnchor:
    """Simulated frames fitted beside a rig's context frames: their encoder features
    ``features`` (N, F), forces ``force_N`` (N,, N), the no-context heads ``heads`` (fitted
    on such frames), and how many of them each fit draws (``frames``).

    Why: one or two context objects are all a rig's heads see, and fitted on them alone
    the heads learn those objects' force range rather than the rig. The simulated frames
    hold every training object at every height, their force mapped to the rig's sensor
    by the gain and offset that map the no-context heads' reading of the context frames
    to the sensor (least squares): the heads learn the rig's look from its frames and
    the range of objects from the simulation. A fixed count, not a share of the context
    frames: like a prior's weight, it counts for less as a rig gives more frames. Off in
    the default config: over three trainings it lowered the error on the rig that
    presses at the finger's base and raised it on the others (docs/studies/sim2real.md, "Sim-to-real")."""

    features: torch.Tensor
    force_N: np.ndarray
    heads: tuple
    frames: int

    @classmethod
    def from_file(cls, model: FinRayNet, path, frames: int) -> "SimAnchor | None":
        """The simulated frames and heads of a no-context file
        (:func:`finray.sim2real.experiment.save_no_context`: ``heads``, the heads' state
        dicts, and ``anchor``, the frames' ``features`` and ``force_N``), ``frames`` of them
        fitted beside each fit's context frames; None where ``frames`` is 0."""
        if frames <= 0:
            return None
        saved = check_no_context(model, path)
        if "anchor" not in saved:
            raise CalibrationError(
                f"{path}: no simulated frames (written before sim_replay_frames); "
                "run the no-context fit again"
            )
        if saved["anchor"]["features"].shape[1] != model.force_head[1].in_features:
            raise CalibrationError(f"{path}: its simulated frames are not of this model's encoder")
        return cls(
            saved["anchor"]["features"].float(),
            saved["anchor"]["force_N"].numpy(),
            tuple(head_from_state(model, state) for state in saved["heads"]),
            int(frames),
        )

    def with_context(
        self, model: FinRayNet, features: torch.Tensor, force_N, seed: int
    ) -> tuple[torch.Tensor, np.ndarray]:
        """The context frames followed by ``frames`` simulated ones (drawn with
        ``seed``), their force the rig's sensor's by the context's gain and offset."""
        y = np.asarray(force_N, dtype=np.float64)
        read = head_forces(model, list(self.heads), features).mean(0)
        gain, offset = np.linalg.lstsq(np.c_[read, np.ones_like(read)], y, rcond=None)[0]
        pool = len(self.force_N)
        pick = np.random.default_rng(seed).choice(pool, self.frames, replace=self.frames > pool)
        sim_y = gain * np.asarray(self.force_N, dtype=np.float64)[pick] + offset
        return (
            torch.cat([features, self.features[pick].to(features.dtype)]),
            np.concatenate([y, sim_y]),
        )


def fit_heads(
    model: FinRayNet,
    features: torch.Tensor,
    force_N,
    fit: HeadFit,
    component: int = 0,
    anchor: SimAnchor | None = None,
) -> list[nn.Module]:
    """``fit.members`` copies of the model's force head, reduced to output
    ``component`` (0: along the push), each fitted to ``force_N`` (N,) on
    ``features`` (N, F): its last ``fit.layers`` linear layers (all where 0), the
    layers before them and the batch-norm statistics stay the simulation's. With an
    ``anchor``, its simulated frames are fitted beside them (:class:`SimAnchor`), in as
    many steps as the frames given alone would take."""
    y = torch.tensor(np.asarray(force_N, dtype=np.float32))
    if len(y) != len(features) or not len(y):
        raise ValueError(f"need as many forces as feature rows, got {len(y)} and {len(features)}")
    if not torch.isfinite(y).all():
        raise ValueError("the forces to fit contain NaN")
    steps = fit.n_steps(len(y))
    if anchor is not None and anchor.frames > 0:
        features, force = anchor.with_context(model, features, y.numpy(), fit.seed)
        y = torch.tensor(force.astype(np.float32))
    mean, scale = model.force_mean_N[component], model.force_scale_N[component]
    target = (y - mean) / scale
    template = _single_output(model.force_head, component).eval()  # batch-norm: frozen
    linear = [i for i, mod in enumerate(template) if isinstance(mod, nn.Linear)]
    start = linear[-fit.layers] if 0 < fit.layers < len(linear) else 0
    frozen = template[:start].requires_grad_(False)
    with torch.no_grad():  # the frozen layers' output, once for every member
        z = frozen(features) if start else features.clone()  # (not an inference tensor)
    n, b = len(y), min(fit.batch, len(y))
    gens = [torch.Generator().manual_seed(fit.seed * 1000 + m) for m in range(fit.members)]
    pools = torch.stack(
        [torch.randint(0, n, (n,), generator=g) if fit.bootstrap else torch.arange(n) for g in gens]
    )
    ops, params = _stacked_tail(template[start:], fit.members)
    opt = torch.optim.Adam(params, lr=fit.lr)
    decay = torch.optim.lr_scheduler.CosineAnnealingLR(opt, steps) if fit.lr_decay else None
    rows = torch.arange(fit.members)[:, None]
    for _ in range(steps):  # every member's step at once: (members, batch) frames
        idx = pools[rows, torch.stack([torch.randint(0, n, (b,), generator=g) for g in gens])]
        loss = ((_run_stacked(ops, z[idx])[..., 0] - target[idx]) ** 2).mean(dim=1).sum()
        opt.zero_grad(set_to_none=True)
        loss.backward()
        opt.step()
        if decay is not None:
            decay.step()
    heads = []
    for m in range(fit.members):
        head = nn.Sequential(*copy.deepcopy(frozen), *_member_tail(template[start:], ops, m))
        head.requires_grad_(False)
        heads.append(head)
    return heads


def _stacked_tail(tail: nn.Sequential, members: int) -> tuple[list, list[torch.Tensor]]:
    """The fitted layers of ``members`` heads as stacked tensors, so that one batched
    step fits them all (they share no weight, and the loss is their sum, so each
    member's gradient, and Adam's update, is its own; a Python loop over the members
    spent most of a sim-to-real job in PyTorch's per-step overhead). Returns the
    operations in order and the trainable tensors: each linear layer's weight
    (M, out, in) and bias (M, 1, out), each batch norm's affine (M, 1, C) (its
    statistics stay the simulation's)."""
    ops, params = [], []

    def stack(t: torch.Tensor) -> torch.Tensor:
        out = t.detach().expand(members, *t.shape)
        return (out if out.dim() == 3 else out[:, None]).clone().requires_grad_()

    for mod in tail:
        if isinstance(mod, nn.Linear):
            ops.append(("linear", stack(mod.weight), stack(mod.bias)))
        elif isinstance(mod, nn.BatchNorm1d):
            ops.append(
                (
                    "norm",
                    stack(mod.weight),
                    stack(mod.bias),
                    mod.running_mean.clone(),
                    torch.sqrt(mod.running_var + mod.eps),
                )
            )
        elif isinstance(mod, (nn.ReLU, nn.Sigmoid, nn.Identity)):
            ops.append(("act", mod))
            continue
        elif isinstance(mod, nn.Flatten):  # the features are flat already
            continue
        else:
            raise TypeError(f"cannot fit a head with a {type(mod).__name__} layer")
        params += list(ops[-1][1:3])
    return ops, params


def _run_stacked(ops: list, x: torch.Tensor) -> torch.Tensor:
    """The stacked layers (:func:`_stacked_tail`) on ``x`` (M, B, F)."""
    for op in ops:
        if op[0] == "linear":
            x = torch.baddbmm(op[2], x, op[1].transpose(1, 2))
        elif op[0] == "norm":
            x = (x - op[3]) / op[4] * op[1] + op[2]
        else:
            x = op[1](x)
    return x


def _member_tail(tail: nn.Sequential, ops: list, m: int) -> nn.Sequential:
    """A copy of ``tail`` with member ``m``'s fitted weights (:func:`_stacked_tail`)."""
    tail = copy.deepcopy(tail)
    fitted = iter(op for op in ops if op[0] != "act")
    with torch.no_grad():
        for mod in tail:
            if isinstance(mod, (nn.Linear, nn.BatchNorm1d)):
                op = next(fitted)
                mod.weight.copy_(op[1][m].reshape(mod.weight.shape))
                mod.bias.copy_(op[2][m].reshape(mod.bias.shape))
    return tail


def check_no_context(model: FinRayNet, path) -> dict:
    """The mapping of a no-context file (:func:`finray.sim2real.experiment.save_no_context`),
    checked: tensors and plain data only (:func:`finray.train.export.load_plain`), heads
    that fit ``model``; else a one-line :class:`~finray.errors.BadInput`."""
    from ..train.export import load_plain

    what = "a no-context fit (no_context.pt)"
    saved = load_plain(path, what)
    heads = saved.get("heads")
    if not isinstance(heads, (list, tuple)) or not heads:
        raise CalibrationError(f"{path} is not {what} (no heads)")
    try:
        for state in heads:
            head_from_state(model, state)
    except (TypeError, KeyError, ValueError, RuntimeError, AttributeError) as exc:
        first = (str(exc).strip().splitlines() or [""])[0]
        raise CalibrationError(
            f"{path}: its heads are not of this model's encoder ({type(exc).__name__}: {first})"
        ) from None
    return saved


def head_from_state(model: FinRayNet, state: dict, component: int = 0) -> nn.Module:
    """A head :func:`fit_heads` fitted on ``model``, from its ``state_dict``."""
    head = _single_output(model.force_head, component).eval()
    head.load_state_dict(state)
    return head.requires_grad_(False)


def _single_output(head: nn.Sequential, component: int) -> nn.Sequential:
    """A copy of ``head`` whose last linear layer gives output ``component`` only."""
    head = copy.deepcopy(head)
    last = head[-1]
    one = nn.Linear(last.in_features, 1)
    with torch.no_grad():
        one.weight.copy_(last.weight[component : component + 1])
        one.bias.copy_(last.bias[component : component + 1])
    head[-1] = one
    return head


def head_forces(
    model: FinRayNet, heads: list[nn.Module], features: torch.Tensor, component: int = 0
) -> np.ndarray:
    """Each head's force (M, N) in N on features (N, F)."""
    mean, scale = model.force_mean_N[component], model.force_scale_N[component]
    with torch.inference_mode():
        return torch.stack([h(features)[:, 0] * scale + mean for h in heads]).numpy()


class HeadEnsemble(nn.Module):
    """The simulation's network with the rig's force heads: ``forward`` gives the
    simulation's stress map and the heads' mean force (B, 1) in N, ``force`` that force
    alone, ``members`` each head's (B, M) in N."""

    def __init__(self, model: FinRayNet, heads: list[nn.Module], component: int = 0):
        super().__init__()
        self.model = model
        self.heads = nn.ModuleList(heads)
        self.register_buffer("mean_N", model.force_mean_N[component].detach().clone())
        self.register_buffer("scale_N", model.force_scale_N[component].detach().clone())

    def _members(self, h: torch.Tensor) -> torch.Tensor:
        z = h.flatten(1)
        return torch.cat([head(z) for head in self.heads], dim=1) * self.scale_N + self.mean_N

    def members(self, x: torch.Tensor) -> torch.Tensor:
        return self._members(self.model.encode(x)[0])

    def force(self, x: torch.Tensor) -> torch.Tensor:
        return self.members(x).mean(dim=1, keepdim=True)

    def forward(self, x: torch.Tensor) -> tuple[torch.Tensor, torch.Tensor]:
        h, skips = self.model.encode(x)
        return self.model.decode(h, skips), self._members(h).mean(dim=1, keepdim=True)


def export_ensemble(
    ensemble: HeadEnsemble,
    path: str | Path,
    preprocess: dict,
    info: dict | None = None,
    base_meta: dict | None = None,
) -> None:
    """Trace the ensemble to TorchScript at ``path`` (``forward``, ``force``, ``members``)
    with ``path + '.json'`` as :func:`finray.train.export_torchscript` writes it, plus
    ``ensemble`` (the number of heads) and ``adapted`` (``info``); the base model's
    ``stress_ref_MPa`` and ``trained`` (``base_meta``, its ``model.ts.json``) carried over."""
    ens = copy.deepcopy(ensemble).float().eval()
    c = ens.model.cfg
    example = torch.rand(1, c.in_channels, c.height, c.width)
    with torch.no_grad():
        ts = torch.jit.trace_module(ens, {"forward": example, "force": example, "members": example})
        ts = torch.jit.freeze(ts, preserved_attrs=["force", "members"])
    ts.save(str(path))
    cfg = ens.model.config_dict() | {"n_forces": 1}
    Path(str(path) + ".json").write_text(
        json.dumps(
            {
                **cfg,
                "forces": ["fx_N"],
                "ensemble": len(ens.heads),
                "preprocess": preprocess,
                **{
                    k: base_meta[k] for k in ("stress_ref_MPa", "trained") if k in (base_meta or {})
                },
                "adapted": info or {},
            },
            indent=1,
        )
    )
    from ..train.export import seal

    seal(path)
