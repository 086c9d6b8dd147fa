"""The learned finger finder on emulated rigs drawn from the full config's ranges
(finray.emulator.rigs: finger colours, backgrounds, lenses, distances), none of which a test
was tuned to: per rig, the finder ``auto`` chooses from the first 5 frames and the IoU of
its masks with the emulator's true masks (every 5th frame), and the masks' confidence.

    python studies/realtime/finder_on_rigs.py WORK_DIR [--rigs 8]

The finger is the synthetic FEA result of tests/helpers.py (a short take:
smoke.yaml's motion), the frames 640x360; the takes are emulated, not recordings.
"""

import argparse
import sys
from pathlib import Path

import numpy as np

ROOT = Path(__file__).resolve().parents[2]
sys.path.insert(0, str(ROOT / "tests"))

from helpers import write_synthetic_fea_result  # noqa: E402

from finray.config import load_config  # noqa: E402
from finray.emulator.emulate import emulate_take  # noqa: E402
from finray.emulator.rigs import draw_rig  # noqa: E402
from finray.media import video_frames  # noqa: E402
from finray.recording.finder import FingerFinder, learn_finder  # noqa: E402

GREY = {
    "threshold": "isodata",
    "foreground": "bright",
    "min_object_frac": 1e-3,
    "max_hole_frac": 2e-4,
    "keep_largest": True,
}


def main() -> None:
    ap = argparse.ArgumentParser()
    ap.add_argument("work", type=Path)
    ap.add_argument("--rigs", type=int, default=8)
    args = ap.parse_args()
    args.work.mkdir(parents=True, exist_ok=True)
    res = write_synthetic_fea_result(
        args.work / "result.npz", n_frames=11, max_displacement_mm=10.0, size_mm=1.0
    )
    lab = load_config(ROOT / "config" / "config.yaml")["lab"]
    lab["motion"] = load_config(ROOT / "config" / "smoke.yaml")["lab"]["motion"]
    grey = FingerFinder.grey(GREY, 4)
    for i in range(1, args.rigs + 1):
        rig = draw_rig(lab, i)
        rig["camera"]["size_px"] = [640, 360]
        take = args.work / f"rig{i}"
        emulate_take(
            res,
            take,
            rig,
            object_name="cylinder",
            height_mm=30.0,
            extrusion_mm=20.0,
            seed=i,
            log=lambda m: None,
        )
        frames = [f.image for f in video_frames(take / "take.mp4")]
        bits = np.load(take / "truth" / "masks.npz")["bits"]
        truth = np.unpackbits(bits, axis=-1)[..., : frames[0].shape[1]].astype(bool)
        finder = learn_finder(frames[:5], grey)
        ious, confs = [], []
        for k in range(0, len(frames), 5):
            mask, conf = finder.find(frames[k])
            t = truth[k]
            ious.append(0.0 if mask is None else (mask & t).sum() / max((mask | t).sum(), 1))
            confs.append(conf)
        print(
            f"rig{i}: finger RGB {np.round(rig['scene']['finger_rgb'], 2).tolist()}, background "
            f"{rig['scene']['background_rgb'][0]:.2f}: {finder.describe()}; IoU min "
            f"{min(ious):.3f}, median {np.median(ious):.3f}; confidence min {min(confs):.2f}",
            flush=True,
        )


if __name__ == "__main__":
    main()
