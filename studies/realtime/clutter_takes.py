"""Uncalibrated ``finray predict`` on emulated takes with clutter (issue 52, item 3): the
configured rig's take of one FEA result, emulated again with nothing added, with a
still object of the finger's colour, with a still hand, and with a hand passing behind
the finger (a moving background, ``lab.look.clutter[].velocity_mm_s``); each through
``finray predict`` with the camera model, its colour learned from the first frames.

    python studies/realtime/clutter_takes.py RESULTS OUT_DIR [--take cylinder_h30] [--model camera]

RESULTS: a full run's results folder (read only): ``lab/fea/<take>/result.npz`` and
``train/<model>/model.ts``. OUT_DIR gets each variant's take (``<variant>/take``), its
predict output (``<variant>/predict``), and ``summary.json`` / ``summary.md``: per
variant the frames flagged (by check), the Fx NRMSE of every frame and of the frames not
flagged against the emulator's true force (% of the take's largest), and the flagged
frames' share while the clutter is in view. The takes are emulated (finray.emulator),
not recordings.
"""

import argparse
import json
import sys
from pathlib import Path

import pandas as pd

from finray.config import load_config
from finray.emulator.emulate import emulate_take
from finray.evaluate.metrics import force_metrics
from finray.predict import predict_files

ROOT = Path(__file__).resolve().parents[2]


def variants(duration_s: float) -> dict[str, list[dict]]:
    """The clutter of each variant (FEA plane mm; the finger spans x 0-30, y 0-80 and
    z -10-10, the back wall is at z -150)."""
    v = 240.0 / duration_s  # crosses from x = -120 to +120 mm in the take's time
    return {
        "plain": [],
        "object": [{"kind": "object", "centre_mm": [75.0, 45.0], "size_mm": [16.0, 22.0]}],
        "hand": [{"kind": "hand", "centre_mm": [-60.0, 75.0], "size_mm": [45.0, 28.0]}],
        "moving_hand": [
            {
                "kind": "hand",
                "centre_mm": [-120.0, 45.0],
                "size_mm": [45.0, 28.0],
                "z_mm": -60.0,
                "velocity_mm_s": [v, 0.0],
            }
        ],
    }


def score(pred: pd.DataFrame, truth: pd.DataFrame) -> dict:
    """Flags and errors of one variant's predict output against the true force."""
    t = pred.merge(truth, on="frame")
    ok = t["valid"] == "ok"
    checks = t.loc[~ok, "valid"].str.split("+").explode().value_counts().to_dict()
    out = {
        "frames": int(len(t)),
        "flagged": int((~ok).sum()),
        "by_check": {k: int(v) for k, v in sorted(checks.items())},
        "all_frames": force_metrics(t["true_N"], t["fx_N"]),
    }
    if ok.any():
        out["unflagged"] = force_metrics(t.loc[ok, "true_N"], t.loc[ok, "fx_N"])
    return out


def main() -> int:
    ap = argparse.ArgumentParser()
    ap.add_argument("results", type=Path)
    ap.add_argument("out", type=Path)
    ap.add_argument("--take", default="cylinder_h30")
    ap.add_argument("--model", default="camera")
    args = ap.parse_args()
    model = args.results / "train" / args.model / "model.ts"
    result = args.results / "lab" / "fea" / args.take / "result.npz"
    for f in (model, result):
        if not f.is_file():
            print(f"missing {f}", file=sys.stderr)
            return 2
    cfg = load_config(ROOT / "config" / "config.yaml")
    lab = {k: cfg["lab"][k] for k in ("motion", "camera", "look", "sensor")}
    obj, height = args.take.rsplit("_h", 1)
    summary = {"model": str(model), "take": args.take, "emulated": True, "variants": {}}
    for name, clutter in variants(float(lab["motion"]["duration_s"])).items():
        take = args.out / name / "take"
        spec = {**lab, "look": {**lab["look"], "clutter": clutter}}
        if not (take / "take.mp4").is_file():
            emulate_take(
                result,
                take,
                spec,
                object_name=obj,
                height_mm=float(height),
                extrusion_mm=float(cfg["finger"]["extrusion_mm"]),
                seed=int(cfg["lab"]["seed"]),
                log=lambda m: None,
            )
        res = predict_files(
            model, take / "take.mp4", args.out / name / "predict", force_only=True, overwrite=True
        )
        pred = pd.read_csv(args.out / name / "predict" / "forces.csv")
        pred["frame"] = pred["frame"].str.rsplit("_", n=1).str[-1].astype(int)
        truth = pd.read_csv(take / "truth" / "frames.csv")
        truth = truth[["frame", "force_N"]].rename(columns={"force_N": "true_N"})
        summary["variants"][name] = {"finder": res["finder"], **score(pred, truth)}
        print(name, json.dumps(summary["variants"][name]), flush=True)
    (args.out / "summary.json").write_text(json.dumps(summary, indent=1))
    lines = [
        "| variant | frames | flagged | checks | Fx NRMSE, every frame (%) | Fx NRMSE, frames not flagged (%) |",
        "|---|--:|--:|---|--:|--:|",
    ]
    for name, r in summary["variants"].items():
        checks = ", ".join(f"{k} {v}" for k, v in r["by_check"].items()) or "-"
        unflagged = r.get("unflagged", {}).get("nrmse_pct")
        lines.append(
            f"| {name} | {r['frames']} | {r['flagged']} | {checks} | "
            f"{r['all_frames']['nrmse_pct']:.1f} | "
            + (f"{unflagged:.1f} |" if unflagged is not None else "- |")
        )
    (args.out / "summary.md").write_text("\n".join(lines) + "\n")
    print("\n".join(lines))
    return 0


if __name__ == "__main__":
    sys.exit(main())
