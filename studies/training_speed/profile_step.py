"""Where a training step's CPU goes: the camera model's step (step_cost.py's set-up:
augmentation, loss of stress, force and contact, backward, Adam; batch 16, one thread)
under torch.profiler, by phase, by kind of operation, and each convolution's forward and
backward by the resolution of its output map, with its GFLOP/s against the core's float32
peak (FLOPs from the shapes: 2 x batch x C_out x H x W x C_in x kh x kw forward, twice
that backward, once where the layer's input needs no gradient).

    PYTHONPATH=src python studies/training_speed/profile_step.py --out results/benchmarks/training_profile
    ONEDNN_MAX_CPU_ISA=AVX512_CORE_BF16 PYTHONPATH=src python ... # the kernels of AVX-512 without AMX

Writes <out>.json and <out>.md. Profiling adds about 10 % to the step; the shares, not
the absolute times, are the point (step_cost.py gives the step's time).
"""

from __future__ import annotations

import math
import os
import sys
from collections import defaultdict
from pathlib import Path

import torch
from torch.profiler import ProfilerActivity, profile, record_function

sys.path.insert(0, str(Path(__file__).parent))
import step_cost as S

from finray.config import load_config
from finray.precision import cpu_name, cpu_precision
from finray.train import loop as L

PHASES = ("augment", "forward", "backward", "adam")


def _shapes(ev) -> list:
    return [s for s in ev.input_shapes if isinstance(s, list)]


def _step(v: dict, bf16: bool) -> None:
    dev = torch.device("cpu")
    with record_function("augment"):
        idx = torch.randint(0, v["data"].n, (v["cfg"].batch_size,), generator=v["gen"])
        x, s = v["data"].batch(idx, v["aug"], v["gen"])
    with record_function("forward"):
        loss = L._batch_loss(v["model"], v["data"], idx, x, s, v["cfg"], dev, bf16)[0]
    with record_function("backward"):
        v["opt"].zero_grad(set_to_none=True)
        loss.backward()
    with record_function("adam"):
        v["opt"].step()


def profile_step(bf16: bool, steps: int, warmup: int, frames: int = 2048) -> dict:
    """One variant's profile (``frames`` random training frames to draw batches from):
    ms per step by phase, by operation and by conv resolution."""
    torch.set_num_threads(1)
    cfg = load_config(S.ROOT / "config" / "config.yaml")
    v = S._setup(cfg, frames, 16, bf16, True, "per-tensor")
    for _ in range(warmup):
        _step(v, bf16)
    with profile(activities=[ProfilerActivity.CPU], record_shapes=True) as prof:
        for _ in range(steps):
            _step(v, bf16)
    events = prof.key_averages(group_by_input_shape=True)
    per = 1e-3 / steps  # profiler us summed over steps -> ms per step
    phase = {e.key: e.cpu_time_total * per for e in events if e.key in PHASES}
    ops = defaultdict(float)
    for e in events:
        if e.key not in PHASES:
            ops[e.key] += e.self_cpu_time_total * per
    # backward events carry (grad_out, input, weight): the output map, and each layer's
    # FLOPs; the forward's mkldnn_convolution matches them by (input, weight). Layers of
    # the same shapes fall into one event group: ``count`` per step says how many.
    net = v["model"].cfg
    first_in = [net.in_channels, net.height, net.width]  # the network's input, per frame
    layers: dict[tuple, dict] = {}
    for e in events:
        if e.key == "aten::convolution_backward":
            g, x, w = _shapes(e)[:3]
            n = e.count // steps
            fwd_flop = n * 2 * math.prod(g) * math.prod(w[1:])
            layers[(tuple(x), tuple(w))] = {
                "out": g[2:],
                "layers": n,
                "channels": f"{w[1]}->{w[0]} ({w[2]}x{w[3]})",
                "backward_ms": e.cpu_time_total * per,
                # the network's input needs no gradient: its layer computes the weights' only
                "backward_flop": fwd_flop * (1 if x[1:] == first_in else 2),
                "forward_flop": fwd_flop,
                "forward_ms": 0.0,
            }
    for e in events:
        if e.key == "aten::mkldnn_convolution":
            x, w = _shapes(e)[:2]
            if (tuple(x), tuple(w)) in layers:
                layers[(tuple(x), tuple(w))]["forward_ms"] += e.cpu_time_total * per
    by_res: dict[str, dict] = defaultdict(lambda: defaultdict(float))
    for lay in layers.values():
        r = by_res["x".join(map(str, lay["out"]))]
        for k in ("forward_ms", "backward_ms", "forward_flop", "backward_flop", "layers"):
            r[k] += lay[k]
    total = sum(phase.get(p, 0.0) for p in PHASES)
    return {
        "bf16": bf16,
        "step_ms": total,
        "phases_ms": phase,
        "top_ops_ms": dict(sorted(ops.items(), key=lambda kv: -kv[1])[:15]),
        "conv_by_output": {k: dict(r) for k, r in by_res.items()},
        "conv_layers": list(layers.values()),
    }


def table(r: dict) -> str:
    peak = r["peak_gflops_fp32"]
    lines = [
        f"{r['cpu']}; {r['kernels']}; float32 peak "
        f"{peak:.0f} GFLOP/s; {r['steps']} profiled steps each",
        "",
    ]
    for p in r["variants"]:
        name = "bfloat16 autocast" if p["bf16"] else "float32"
        ph = p["phases_ms"]
        conv = sum(c["forward_ms"] + c["backward_ms"] for c in p["conv_by_output"].values())
        lines += [
            f"**{name}**: {p['step_ms']:.1f} ms per step (profiled): "
            + ", ".join(f"{k} {ph.get(k, 0):.1f}" for k in PHASES)
            + f"; convolutions {conv:.1f} ms, everything else {p['step_ms'] - conv:.1f} ms",
            "",
            "| output map | layers | forward ms | backward ms | GFLOP | GFLOP/s | share of fp32 peak |",
            "|---|--:|--:|--:|--:|--:|--:|",
        ]
        for res, c in sorted(p["conv_by_output"].items(), key=lambda kv: -int(kv[0].split("x")[0])):
            ms = c["forward_ms"] + c["backward_ms"]
            gf = (c["forward_flop"] + c["backward_flop"]) / 1e9
            rate = gf / (ms * 1e-3) if ms else float("nan")
            lines.append(
                f"| {res} | {c['layers']:.0f} | {c['forward_ms']:.2f} | {c['backward_ms']:.2f} | "
                f"{gf:.3f} | {rate:.0f} | {100 * rate / peak:.0f} % |"
            )
        lines += [
            "",
            "Largest operations (self ms per step): "
            + ", ".join(f"{k} {t:.2f}" for k, t in list(p["top_ops_ms"].items())[:10]),
            "",
        ]
    return "\n".join(lines)


def main() -> None:
    a = S.study_args(__doc__, warmup=10)
    r = {
        "cpu": cpu_name(),
        "kernels": cpu_precision().describe(),
        "isa": os.environ.get("ONEDNN_MAX_CPU_ISA"),
        "peak_gflops_fp32": S.peak_gflops()[0],
        "steps": a.steps,
        "variants": [profile_step(bf16, a.steps, a.warmup) for bf16 in (False, True)],
    }
    S.write_report(a.out, r, table)


if __name__ == "__main__":
    main()
