"""What a training step costs on this CPU, and where it goes: each variant of the step
(numeric type, memory format, Adam's update, batch size) timed side by side, with its
GFLOP/s and its share of the core's float32 peak; and the numeric type that
``train.bf16: auto`` picks here (finray.train.precision_trial).

The step is the training's own (finray.train.loop): the batch drawn and augmented as
the ``camera`` model's (camera views, occlusion, salt-and-pepper, affine), the loss
of the stress map, the force and the contact height, backward, Adam. The frames are
random (the cost does not depend on their content). The variants take turns step by
step, so a load that drifts during the run weighs on each alike; each variant's time is
the median of its steps' CPU time (this thread's; one intra-op thread, as a training of
the default run). FLOPs: torch.utils.flop_counter on one float32 step (forward and
backward; convolutions and matrix products).

    PYTHONPATH=src python studies/training_speed/step_cost.py --out results/benchmarks/training_speed

The kernels torch uses can be held to a lower instruction set to see what ``auto``
picks there (an emulation of another CPU's kernel path, not that CPU: the memory system
and clocks stay this machine's): ONEDNN_MAX_CPU_ISA=AVX512_CORE_BF16 (AVX-512 BF16
without AMX), ATEN_CPU_CAPABILITY=avx2 ONEDNN_MAX_CPU_ISA=AVX2 (AVX2).
"""

from __future__ import annotations

import argparse
import json
import os
import time
from pathlib import Path

import numpy as np
import torch

from finray.config import load_config, model_augment_settings
from finray.model import NetConfig
from finray.precision import cpu_name, cpu_precision
from finray.train import loop as L
from finray.train.augment import TrainAugment
from finray.train.config import AugmentConfig, TrainConfig
from finray.train.precision_trial import time_precisions

ROOT = Path(__file__).resolve().parents[2]
#: (name, bfloat16, channels_last, Adam's update, batch)
VARIANTS = [
    ("float32", False, True, "per-tensor", 16),
    ("bfloat16", True, True, "per-tensor", 16),
    ("float32, channels first", False, False, "per-tensor", 16),
    ("bfloat16, channels first", True, False, "per-tensor", 16),
    ("float32, fused Adam", False, True, "fused", 16),
    ("bfloat16, fused Adam", True, True, "fused", 16),
    ("float32, batch 32", False, True, "per-tensor", 32),
    ("bfloat16, batch 32", True, True, "per-tensor", 32),
]


def peak_gflops() -> tuple[float, str]:
    """One core's float32 peak: clock x SIMD lanes x 2 (FMA) x 2 FMA units (an
    assumption: the flags do not say how many units a core has)."""
    mhz = float(
        next(
            (line.split(":")[1] for line in open("/proc/cpuinfo") if line.startswith("cpu MHz")),
            "nan",
        )
    )
    isa = torch.backends.cpu.get_cpu_capability()
    lanes = 16 if "AVX512" in isa.upper() else 8
    return mhz * 1e-3 * lanes * 2 * 2, f"{mhz:.0f} MHz x {lanes} lanes x 2 (FMA) x 2 units ({isa})"


def _setup(cfg: dict, n: int, batch: int, bf16: bool, cl: bool, adam: str, seed: int = 0):
    h, w = cfg["train"]["input_size"]
    net = NetConfig(height=h, width=w, base_channels=cfg["train"]["base_channels"], contact=True)
    rng = np.random.default_rng(seed)
    x, c = (rng.random((n, 3, h, w), dtype=np.float32) for _ in range(2))
    s = rng.random((n, 1, h, w), dtype=np.float32)
    f = 5 * rng.random((n, 1), dtype=np.float32)
    y = 70 * rng.random(n, dtype=np.float32)
    tcfg = TrainConfig(batch_size=batch, channels_last=cl, bf16=bf16, progress=False)
    data = L._TrainData.checked(x, s, f, c, np.ones(n, np.float32), y, net, tcfg)
    model, _, _ = L._new_model(net, data, None)
    if cl:
        model = model.to(memory_format=torch.channels_last)
    opt = torch.optim.Adam(
        model.parameters(), lr=tcfg.lr, **({"fused": True} if adam == "fused" else {})
    )
    camera = cfg["train"]["models"]["camera"]
    aug = TrainAugment(AugmentConfig(**model_augment_settings(camera)), None)
    return dict(
        model=model, data=data, opt=opt, aug=aug, cfg=tcfg, gen=torch.Generator().manual_seed(0)
    )


def _step(v: dict, bf16: bool) -> dict:
    """One training step; CPU seconds of its phases."""
    dev = torch.device("cpu")
    t0 = time.thread_time()
    idx = torch.randint(0, v["data"].n, (v["cfg"].batch_size,), generator=v["gen"])
    x, s = v["data"].batch(idx, v["aug"], v["gen"])
    t1 = time.thread_time()
    loss = L._batch_loss(v["model"], v["data"], idx, x, s, v["cfg"], dev, bf16)[0]
    v["opt"].zero_grad(set_to_none=True)
    loss.backward()
    t2 = time.thread_time()
    v["opt"].step()
    t3 = time.thread_time()
    return {"augment": t1 - t0, "forward_backward": t2 - t1, "adam": t3 - t2}


def flops_per_step(cfg: dict, batch: int) -> float:
    from torch.utils.flop_counter import FlopCounterMode

    v = _setup(cfg, 64, batch, False, True, "per-tensor")
    with FlopCounterMode(display=False) as fc:
        _step(v, False)
    return float(fc.get_total_flops())


def flop_split(cfg: dict, batch: int = 16) -> dict[str, float]:
    """Forward GFLOP of a batch per part of the network (the encoder, the U-Net stress
    decoder, the force head, the contact head); backward costs about twice each."""
    from torch.utils.flop_counter import FlopCounterMode

    net = _setup(cfg, 64, batch, False, True, "per-tensor")["model"].eval()
    x = torch.zeros(batch, net.cfg.in_channels, net.cfg.height, net.cfg.width)

    def gflop(fn, *args):
        with torch.no_grad(), FlopCounterMode(display=False) as fc:
            out = fn(*args)
        return out, fc.get_total_flops() / 1e9

    (h, skips), enc = gflop(net.encode, x)
    parts = {"encoder": enc, "stress decoder": gflop(net.decode, h, skips)[1]}
    parts["force head"] = gflop(net.force_head, h)[1]
    if getattr(net, "contact_head", None) is not None:
        parts["contact head"] = gflop(net.contact_head, h)[1]
    return parts


def measure(steps: int, warmup: int, n: int = 4096) -> dict:
    torch.set_num_threads(1)
    cfg = load_config(ROOT / "config" / "config.yaml")
    peak, peak_how = peak_gflops()
    flops = {b: flops_per_step(cfg, b) for b in sorted({v[4] for v in VARIANTS})}
    runs = {name: _setup(cfg, n, b, bf, cl, adam) for name, bf, cl, adam, b in VARIANTS}
    phases: dict[str, list[dict]] = {name: [] for name, *_ in VARIANTS}
    for k in range(warmup + steps):  # the variants take turns, step by step
        for name, bf16, *_ in VARIANTS:
            t = _step(runs[name], bf16)
            if k >= warmup:
                phases[name].append(t)
    rows = []
    for name, bf16, cl, adam, batch in VARIANTS:
        ph = {p: 1e3 * float(np.median([t[p] for t in phases[name]])) for p in phases[name][0]}
        step_ms = 1e3 * float(np.median([sum(t.values()) for t in phases[name]]))
        gflops = flops[batch] / (step_ms * 1e-3) / 1e9
        rows.append(
            {
                "variant": name,
                "bf16": bf16,
                "channels_last": cl,
                "adam": adam,
                "batch": batch,
                "step_cpu_ms": step_ms,
                "ms_per_16_frames": step_ms * 16 / batch,
                **{f"{p}_ms": v for p, v in ph.items()},
                "gflop_per_step": flops[batch] / 1e9,
                "gflops": gflops,
                "share_of_fp32_peak": gflops / peak,
                "fwd_bwd_share_of_fp32_peak": flops[batch]
                / (ph["forward_backward"] * 1e-3)
                / 1e9
                / peak,
            }
        )
    # what train.bf16: auto picks here, by the training's own trial
    hw = cpu_precision()
    trial = None
    if hw.native_bf16:
        v = _setup(cfg, 64, 16, False, True, "per-tensor")
        idx = torch.arange(16)
        x, s = v["data"].x[idx], v["data"].s[idx]
        trial = time_precisions(
            v["model"],
            lambda m, bf16: L._batch_loss(
                m, v["data"], idx, x, s, v["cfg"], torch.device("cpu"), bf16
            )[0],
            lr=v["cfg"].lr,
        )
    return {
        "cpu": cpu_name(),
        "kernels": hw.describe(),
        "env": {k: os.environ.get(k) for k in ("ATEN_CPU_CAPABILITY", "ONEDNN_MAX_CPU_ISA")},
        "peak_gflops_fp32": peak,
        "peak_how": peak_how,
        "steps": steps,
        "forward_gflop_by_part": flop_split(cfg),
        "rows": rows,
        "auto": (
            {"picks": "bfloat16" if trial.bf16 else "float32", **trial.as_dict()}
            if trial
            else {
                "picks": "float32",
                "why": "no bfloat16 hardware on the kernels torch uses: not timed",
            }
        ),
    }


def table(r: dict) -> str:
    lines = [
        f"{r['cpu']}; {r['kernels']}; float32 peak {r['peak_gflops_fp32']:.0f} GFLOP/s "
        f"({r['peak_how']}); median of {r['steps']} steps each, taken in turns",
        "",
        "| variant | CPU ms / step | ms per 16 frames | augment | forward+backward | Adam | GFLOP/s | share of fp32 peak (step / fwd+bwd) |",
        "|---|--:|--:|--:|--:|--:|--:|--:|",
    ]
    for w in r["rows"]:
        lines.append(
            f"| {w['variant']} | {w['step_cpu_ms']:.1f} | {w['ms_per_16_frames']:.1f} | "
            f"{w['augment_ms']:.1f} | {w['forward_backward_ms']:.1f} | {w['adam_ms']:.1f} | "
            f"{w['gflops']:.0f} | {100 * w['share_of_fp32_peak']:.0f} % / "
            f"{100 * w['fwd_bwd_share_of_fp32_peak']:.0f} % |"
        )
    split = r["forward_gflop_by_part"]
    total = sum(split.values())
    lines += [
        "",
        "Forward FLOPs of a batch of 16 by part: "
        + ", ".join(f"{k} {v:.3f} GFLOP ({100 * v / total:.1f} %)" for k, v in split.items()),
    ]
    a = r["auto"]
    lines += [
        "",
        f"train.bf16: auto picks {a['picks']}"
        + (
            f" (trial: float32 {a['float32_ms']:.1f} ms, bfloat16 {a['bfloat16_ms']:.1f} ms)"
            if "float32_ms" in a
            else f" ({a['why']})"
        ),
    ]
    return "\n".join(lines)


def study_args(doc: str, warmup: int) -> argparse.Namespace:
    """The study scripts' command line: --out, --steps, --warmup."""
    p = argparse.ArgumentParser(description=doc.split("\n\n")[0])
    p.add_argument("--out", type=Path, required=True, help="writes <out>.json and <out>.md")
    p.add_argument("--steps", type=int, default=30)
    p.add_argument("--warmup", type=int, default=warmup)
    return p.parse_args()


def write_report(out: Path, r: dict, table) -> None:
    """``r`` as <out>.json and ``table(r)`` as <out>.md, and printed."""
    out.parent.mkdir(parents=True, exist_ok=True)
    out.with_suffix(".json").write_text(json.dumps(r, indent=1))
    out.with_suffix(".md").write_text(table(r) + "\n")
    print(table(r))


def main() -> None:
    a = study_args(__doc__, warmup=5)
    write_report(a.out, measure(a.steps, a.warmup), table)


if __name__ == "__main__":
    main()
