"""``train.bf16: auto`` on a CPU chosen by measurement: a few training steps in each
numeric type, timed side by side, and the faster kept.

The CPU's flags say which types it can compute, not which is faster: on an Intel Xeon
with AVX-512 BF16 but no AMX a bfloat16 step took longer than a float32 one, on one with
AMX far less (the step times per CPU: docs/studies/run-cost.md). The trial runs the
training's own step (loss, backward, Adam) on a copy of the new network and a fixed
batch of training frames, without augmentation, so the training itself (its weights,
batches and draws) is that of a run without the trial. Steps of the two types alternate,
so a load that changes during the trial weighs on both alike; each type's time is the
median of its steps' CPU time (the thread's: the training's cost, less load-dependent
than wall time). bfloat16 is kept only when it is clearly faster (``MARGIN``):
float32 is the exact type, and a near tie would otherwise flip between two runs of the
same job.
"""

from __future__ import annotations

import copy
import time
from collections.abc import Callable
from dataclasses import dataclass

import numpy as np
import torch

#: bfloat16 is chosen only when its step takes at most (1 - MARGIN) of float32's
MARGIN = 0.05
#: untimed steps of each type first (oneDNN builds its kernels on the first calls)
WARMUP = 3
#: timed steps of each type, alternating
STEPS = 8


@dataclass(frozen=True)
class PrecisionTrial:
    """Median CPU time of a training step in each type (ms) and the choice."""

    float32_ms: float
    bfloat16_ms: float
    steps: int

    @property
    def bf16(self) -> bool:
        return self.bfloat16_ms <= (1.0 - MARGIN) * self.float32_ms

    def describe(self) -> str:
        kind = "bfloat16 autocast" if self.bf16 else "float32"
        return (
            f"{kind} (train.bf16: auto; measured, {self.steps} steps each: float32 "
            f"{self.float32_ms:.1f} ms, bfloat16 {self.bfloat16_ms:.1f} ms of CPU per step; "
            f"bfloat16 taken when at least {MARGIN:.0%} faster)"
        )

    def as_dict(self) -> dict:
        return {"float32_ms": self.float32_ms, "bfloat16_ms": self.bfloat16_ms, "steps": self.steps}


def time_precisions(
    model: torch.nn.Module,
    step: Callable[[torch.nn.Module, bool], torch.Tensor],
    lr: float,
    warmup: int = WARMUP,
    steps: int = STEPS,
) -> PrecisionTrial:
    """Time ``step(model, bf16) -> loss`` (forward and loss of one batch) with its
    backward and an Adam update, on a copy of ``model`` per type (``model`` is left as
    it is), alternating the types; the median CPU time of each (ms)."""
    copies = {bf16: copy.deepcopy(model).train() for bf16 in (False, True)}
    opts = {bf16: torch.optim.Adam(m.parameters(), lr=lr) for bf16, m in copies.items()}
    times: dict[bool, list[float]] = {False: [], True: []}
    for k in range(warmup + steps):
        for bf16 in (False, True):
            t = time.thread_time()
            loss = step(copies[bf16], bf16)
            opts[bf16].zero_grad(set_to_none=True)
            loss.backward()
            opts[bf16].step()
            if k >= warmup:
                times[bf16].append(time.thread_time() - t)
    f32, bf = (1e3 * float(np.median(times[b])) for b in (False, True))
    return PrecisionTrial(float32_ms=f32, bfloat16_ms=bf, steps=steps)
