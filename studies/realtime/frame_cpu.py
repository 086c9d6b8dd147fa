"""CPU time per frame of the live loop's `--force-only` work on camera footage: find the
finger, crop, the network's force (ONNX Runtime, one thread) and, where the code has
them, the validity checks. Runs against whichever finray is importable (this tree's,
or an older one's through PYTHONPATH), so that before and after are timed on one
machine with the same frames. CPU time of the calling thread (time.thread_time): the
machine may be shared, its wall time is not a measure.

    python studies/realtime/frame_cpu.py OUT.json [--frames 200]

Frames: the synthetic orange finger of tests/recording_synth.py over a lit grey
background (a camera's view: the grey threshold takes the background), and the same
finger alone on black (a render's look), bent 0-5 mm, at 640x480 and 1280x720 (the
finger ~70 % of the height). New code: ``grey`` the renders' threshold, ``auto`` the
finder learned from the first 5 frames (colour on the camera's view, the threshold on
the render's look), with the validity checks. A
model of the default network (input 64x32, 16 base channels), untrained: its cost is
the trained one's.
"""

import argparse
import json
import sys
import time
from pathlib import Path

import numpy as np
import torch

ROOT = Path(__file__).resolve().parents[2]
sys.path.insert(0, str(ROOT / "tests"))

from recording_synth import background, render_frame  # noqa: E402
from helpers import CAMERA_PREPROCESS as PREPROCESS  # noqa: E402

from finray.model import FinRayNet, NetConfig  # noqa: E402
from finray.predict import Predictor  # noqa: E402
from finray.train import export_onnx, export_torchscript  # noqa: E402


def frames_at(h, w, n=12, render_like=False):
    """``n`` frames (H, W, 3) of the finger bent 0-5 mm: over a lit grey background (a
    camera's view), or, ``render_like``, its true mask in the finger's colour on black
    (the renders' look, where the grey threshold finds the finger)."""
    bg = background((h, w), 0)
    ppm = h / 120.0
    out = []
    for d in np.linspace(0, 5, n):
        img, truth = render_frame(bg, ppm, (0.45 * w, 0.88 * h), d, 0.0)
        out.append(np.where(truth[..., None], img, 12).astype(np.uint8) if render_like else img)
    return out


def time_loop(p, frames, n, new):
    """Median and p90 CPU ms per frame of the force-only loop."""
    cpu = []
    for k in range(n + 10):
        f = frames[k % len(frames)]
        c0 = time.thread_time()
        if new:  # the live loop's steps (finray.predict._predict_loop, --force-only)
            mask, conf = p.find(f)
            box = p.crop_box(mask)
            x = p.network_input(mask, box)
            fv, cv = p.run_force_contact(x)
            row = {"fx_N": float(fv[0, 0])}
            p.check(mask, conf, x, row, box)
        else:  # the loop before: the grey threshold
            x = p.network_input(p.segment(f))
            p.run_force_contact(x) if hasattr(p, "run_force_contact") else p.run_force(x)
        if k >= 10:
            cpu.append((time.thread_time() - c0) * 1e3)
    return {
        "cpu_ms_median": float(np.median(cpu)),
        "cpu_ms_p90": float(np.percentile(cpu, 90)),
        "n": n,
    }


def main():
    ap = argparse.ArgumentParser()
    ap.add_argument("out")
    ap.add_argument("--frames", type=int, default=200)
    args = ap.parse_args()
    torch.manual_seed(0)
    torch.set_num_threads(1)
    net = FinRayNet(NetConfig(in_channels=1, base_channels=16, height=64, width=32)).eval()
    d = Path(args.out).with_suffix(".model")
    d.mkdir(parents=True, exist_ok=True)
    export_torchscript(net, d / "model.ts", PREPROCESS)
    export_onnx(net, d / "model.onnx")
    new = hasattr(Predictor, "find")
    out = {"finray": str(Path(sys.modules["finray"].__file__).parent), "new": new, "runs": {}}
    for h, w in ((480, 640), (720, 1280)):
        for look in ("camera", "render"):
            frames = frames_at(h, w, render_like=look == "render")
            p = Predictor(d / "model.ts", threads=1, backend="onnx")
            runs = {}
            if new:
                from finray.recording.finder import learn_finder

                runs["grey"] = time_loop(p, frames, args.frames, True)
                c0 = time.thread_time()
                p.finder = learn_finder(frames[:5], p.finder)
                runs["learn_cpu_ms"] = (time.thread_time() - c0) * 1e3
                runs["finder"] = p.finder.describe()
                runs["auto"] = time_loop(p, frames, args.frames, True)
            else:
                runs["grey"] = time_loop(p, frames, args.frames, False)
            out["runs"][f"{w}x{h} {look}"] = runs
            print(w, h, look, json.dumps(runs), flush=True)
    Path(args.out).write_text(json.dumps(out, indent=1))


if __name__ == "__main__":
    main()
