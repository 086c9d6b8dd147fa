"""One training epoch and the batch-1 latency on the device torch finds (or the one
asked for): what a GPU buys, and the same figures on a CPU for comparison.

    python -m finray.benchmarks.device --out results/benchmarks/device.json \\
        [--model results/train/plain/model.pt] [--device auto|cpu|cuda]

Training: one epoch of :func:`finray.train.train`, the real loop (the plain model's
augmentation on the CPU, the batch moved to the device, ``train.bf16: auto``, Adam), on
synthetic frames of the real input (``(1, H, W)`` images in [0, 1], log-stress maps and
two force components; the step's cost does not depend on the pixel values): ``--frames``
of them, at the config's batch size and learning rate (16, 1e-4). The epoch's wall time,
the median step and the step time scaled to a real epoch (``--full-frames``: the full
config's 18,204 training frames) are written.

Inference: the network alone at batch 1 through :class:`finray.predict.Predictor` as
``finray predict`` runs it on that device (ONNX Runtime on the CPU, TorchScript on a
GPU), force only and full (with the stress map), outputs copied back to the host (which
waits for the GPU); the segmentation and crop run on the CPU on any device and are
timed by ``results/benchmarks/inference_latency.json``.

The network is the one of ``--model`` (a ``model.pt`` checkpoint) or, without it, a
freshly initialised one of the config's size (64 x 32, base 16, two forces): its
weights do not change its cost. Timings, not correctness: run on a quiet machine.
"""

from __future__ import annotations

import argparse
import json
import os
import sys
import tempfile
from pathlib import Path

import numpy as np

from .timing import time_calls
from ..schema import schema_default

#: Training frames of the full config (41 of the 45 training scenes x 444 frames; 4
#: scenes held out for validation), for the per-epoch estimate.
FULL_TRAIN_FRAMES = 18204


def synthetic_frames(n: int, size: tuple[int, int], n_forces: int = 2, seed: int = 0) -> dict:
    """``n`` random training frames at ``size`` (H, W): ``images`` (n, 1, H, W) in [0, 1],
    ``stress`` (n, 1, H, W) log-stress, ``force_N`` (n, n_forces), float32."""
    rng = np.random.default_rng(seed)
    h, w = size
    return {
        "images": rng.random((n, 1, h, w), dtype=np.float32),
        "stress": rng.normal(1.0, 0.5, (n, 1, h, w)).astype(np.float32),
        "force_N": rng.normal(0.0, 1.0, (n, n_forces)).astype(np.float32),
    }


def time_epoch(
    net_cfg,
    device: str = schema_default("train.device"),
    frames: int = 1024,
    batch_size: int = schema_default("train.batch_size"),
    lr: float = 1e-4,
    threads: int = 1,
    full_frames: int = FULL_TRAIN_FRAMES,
    log=None,
) -> dict:
    """One training epoch on synthetic frames (:func:`synthetic_frames`) with the plain
    model's augmentation: wall seconds of the epoch, the median step (ms, wall and host
    CPU) and the epoch of ``full_frames`` frames estimated from the step (s)."""
    from ..train import AugmentConfig, TrainAugment, TrainConfig, train

    data = synthetic_frames(frames, (net_cfg.height, net_cfg.width), net_cfg.n_forces)
    cfg = TrainConfig(
        epochs=1,
        batch_size=batch_size,
        lr=lr,
        threads=threads,
        device=device,
        progress=False,
        log_every_s=3600.0,
        contact_weight=0.0,
    )
    lines: list[str] = []
    _, hist = train(
        data["images"],
        data["stress"],
        data["force_N"],
        None,
        net_cfg,
        cfg,
        TrainAugment(AugmentConfig()),
        log=log or lines.append,
    )
    return {
        "device": hist.device,
        "precision": hist.precision,
        "precision_reason": hist.precision_reason,
        "frames": frames,
        "batch_size": batch_size,
        "lr": lr,
        "threads": threads,
        "epoch_s": hist.epoch_time_s[0],
        "step_ms": hist.step_ms,
        "step_cpu_ms": hist.step_cpu_ms,
        "full_frames": full_frames,
        "full_epoch_estimate_s": hist.step_ms * (full_frames // batch_size) / 1e3,
    }


def time_inference(
    model,
    device: str = schema_default("train.device"),
    n_calls: int = 200,
    repeats: int = 3,
    threads: int = 1,
) -> dict:
    """Median latency (ms) of the network at batch 1 through :class:`Predictor` on
    ``device`` (exported to a temporary folder as training exports it): ``force_ms``
    (encoder and force head), ``full_ms`` (with the stress decoder), wall and the
    calling thread's CPU time, and the 90th percentile of the wall time."""
    from ..predictor import Predictor
    from ..train import export_onnx, export_torchscript

    c = model.cfg
    x = np.random.default_rng(0).random((1, c.in_channels, c.height, c.width), dtype=np.float32)
    with tempfile.TemporaryDirectory() as tmp:
        path = Path(tmp) / "model.ts"
        export_torchscript(model, path)
        export_onnx(model, path.with_suffix(".onnx"))
        p = Predictor(path, threads=threads, device=device)
        out = {
            "backend": p.backend,
            "device": str(p.device),
            "threads": threads,
            "n_calls": n_calls * repeats,
        }
        for key, fn in (("force", p.run_force), ("full", p.run)):
            t = time_calls(lambda k: fn(x), n_calls, repeats, warmup=20, cpu="thread")
            out[f"{key}_ms"] = t.wall_s * 1e3
            out[f"{key}_cpu_ms"] = t.cpu_s * 1e3
            out[f"{key}_p90_ms"] = t.p90_wall_s * 1e3
    return out


def run(
    out: str | Path,
    model_path: str | Path | None = None,
    device: str = schema_default("train.device"),
    frames: int = 1024,
    batch_size: int = schema_default("train.batch_size"),
    lr: float = 1e-4,
    calls: int = 200,
    repeats: int = 3,
    threads: int = 1,
    full_frames: int = FULL_TRAIN_FRAMES,
    log=print,
) -> dict:
    """Time an epoch and the batch-1 latency (:func:`time_epoch`, :func:`time_inference`)
    and write them, with the device's name, to ``out`` (JSON)."""
    import torch

    from ..model import FinRayNet, NetConfig
    from ..precision import device_name, resolve_device
    from ..train import load_checkpoint

    dev = resolve_device(device, "--device")  # before any work
    if model_path is not None:
        model, _ = load_checkpoint(model_path)
    else:
        model = FinRayNet(
            NetConfig(in_channels=1, base_channels=16, height=64, width=32, n_forces=2)
        )
    torch.set_num_threads(threads)
    load_before = os.getloadavg()
    log(f"device: {device_name(dev)}; training one epoch of {frames} synthetic frames")
    train_t = time_epoch(model.cfg, device, frames, batch_size, lr, threads, full_frames)
    log(
        f"epoch {train_t['epoch_s']:.1f} s, step {train_t['step_ms']:.1f} ms "
        f"({train_t['precision']}); full epoch ~{train_t['full_epoch_estimate_s']:.0f} s"
    )
    infer_t = time_inference(model, device, calls, repeats, threads)
    log(
        f"batch 1 ({infer_t['backend']}): force {infer_t['force_ms']:.3f} ms, "
        f"full {infer_t['full_ms']:.3f} ms"
    )
    result = {
        "device": str(dev),
        "device_name": device_name(dev),
        "device_setting": device,
        "torch": torch.__version__,
        "cuda": torch.version.cuda,
        "model": str(model_path) if model_path else None,
        "model_note": (
            "checkpoint"
            if model_path
            else "freshly initialised (no --model): the cost does not depend on the weights"
        ),
        "net": model.config_dict(),
        "data": "synthetic frames at the network's input size (random images, "
        "log-stress maps and forces)",
        "cpu_count": os.cpu_count(),
        "load_average_before": list(load_before),
        "load_average_after": list(os.getloadavg()),
        "train": train_t,
        "inference": infer_t,
    }
    Path(out).parent.mkdir(parents=True, exist_ok=True)
    Path(out).write_text(json.dumps(result, indent=1))
    return result


def main(argv: list[str] | None = None) -> int:
    ap = argparse.ArgumentParser(
        prog="python -m finray.benchmarks.device", description=__doc__.split("\n\n")[0]
    )
    ap.add_argument("--out", type=Path, required=True, help="JSON file to write")
    ap.add_argument(
        "--model",
        type=Path,
        default=None,
        help="model.pt checkpoint (default: a freshly initialised network)",
    )
    ap.add_argument("--device", choices=["auto", "cpu", "cuda"], default="auto")
    ap.add_argument("--frames", type=int, default=1024, help="synthetic training frames (1024)")
    ap.add_argument("--batch-size", type=int, default=16, help="the config's (16)")
    ap.add_argument("--lr", type=float, default=1e-4, help="the config's (1e-4)")
    ap.add_argument("--calls", type=int, default=200, help="timed batch-1 calls per repeat (200)")
    ap.add_argument("--repeats", type=int, default=3)
    ap.add_argument("--threads", type=int, default=1, help="intra-op CPU threads (1)")
    ap.add_argument(
        "--full-frames",
        type=int,
        default=FULL_TRAIN_FRAMES,
        help=f"frames of a real epoch, for the estimate ({FULL_TRAIN_FRAMES})",
    )
    args = ap.parse_args(argv)
    if args.frames < 2 * args.batch_size:
        print(
            f"finray.benchmarks.device: --frames must be at least two batches "
            f"({2 * args.batch_size})",
            file=sys.stderr,
        )
        return 2
    if args.model is not None and not args.model.is_file():
        print(f"finray.benchmarks.device: no model checkpoint at {args.model}", file=sys.stderr)
        return 2
    from ..precision import DeviceError

    try:
        run(
            args.out,
            args.model,
            args.device,
            args.frames,
            args.batch_size,
            args.lr,
            args.calls,
            args.repeats,
            args.threads,
            args.full_frames,
        )
    except DeviceError as exc:
        print(f"finray.benchmarks.device: {exc}", file=sys.stderr)
        return 2
    return 0


if __name__ == "__main__":
    sys.exit(main())
