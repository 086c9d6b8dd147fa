"""Uncalibrated ``finray predict`` on every emulated rig's takes against the sim-to-real
no-context path on the same frames (issue 52's acceptance): per rig, the Fx NRMSE of
both against the sensor, how many frames each takes, the frames predict flags, and
whether any take reads as a constant while the sensor moves.

    python studies/realtime/predict_vs_sim2real.py RESULTS OUT_DIR [--model camera]

RESULTS: a full run's results folder (read only): ``lab/<take>/take.mp4`` (the
configured rig) and ``lab/rigs/<rig>/<take>/take.mp4`` (the drawn ones), their
``evaluate/sim2real[/rigs/<rig>]/frames.csv`` (the no-context rows, context_objects 0:
``pred_N`` calibrated by the simulation with the rig prior, ``net_mean_N`` its
network force: the model's own head since 33a89b4, the refitted heads' mean before) and ``train/<model>/model.ts``. OUT_DIR gets each take's
``finray predict`` output, ``frames.csv`` (every frame of both paths beside the sensor)
and ``summary.json`` / ``summary.md`` (per rig). The takes are emulated (finray.emulator),
not recordings.

A model exported before the training's ranges were saved with it (``model.ts.json``
without ``trained``) is copied into OUT_DIR/model with the ranges of the run's training
split (``dataset/manifest.csv``'s ``train`` shards, validation scenes included) and the
shards' stress reference, so that every check runs.
"""

import argparse
import json
import sys
from pathlib import Path

import numpy as np
import pandas as pd

from finray.evaluate.metrics import force_metrics
from finray.predict import Predictor, predict_files


def rig_takes(results: Path) -> dict[str, tuple[list[Path], Path]]:
    """rig -> (its take folders, its sim2real frames.csv)."""
    lab = results / "lab"
    out = {
        "default": (
            sorted(p.parent for p in lab.glob("*/take.mp4")),
            results / "evaluate" / "sim2real" / "frames.csv",
        )
    }
    for rig in sorted((lab / "rigs").glob("rig*")):
        out[rig.name] = (
            sorted(p.parent for p in rig.glob("*/take.mp4")),
            results / "evaluate" / "sim2real" / "rigs" / rig.name / "frames.csv",
        )
    return out


def with_ranges(model: Path, results: Path, out: Path) -> Path:
    """``model`` itself where its export has the training's ranges, else a copy in
    ``out`` with those of the run's training split (see the module's text)."""
    import shutil

    from finray.train.data import load_split, shard_stress_ref
    from finray.validity import training_ranges

    meta = json.loads(Path(str(model) + ".json").read_text())
    if "trained" in meta:
        return model
    manifest = pd.read_csv(results / "dataset" / "manifest.csv", usecols=["shard", "split"])
    shards = sorted(
        results.parent / s for s in manifest.loc[manifest["split"] == "train", "shard"].unique()
    )
    size = (meta["height"], meta["width"])
    try:
        data = load_split(shards, size, camera=True)
        seen = [data["images"], data["camera_images"]]
    except (KeyError, ValueError):
        data = load_split(shards, size)
        seen = [data["images"]]
    meta["trained"] = training_ranges(
        seen,
        data["force_N"][:, :1],
        ["fx_N"],
        data["contact_mm"] if meta.get("contact") else None,
        float(meta.get("contact_min_force_N") or 0.0),
    )
    meta.setdefault("stress_ref_MPa", shard_stress_ref(shards))
    out.mkdir(parents=True, exist_ok=True)
    for f in model.parent.glob(model.stem + ".*"):
        if f.suffix in (".ts", ".onnx"):
            shutil.copy(f, out / f.name)
    (out / (model.name + ".json")).write_text(json.dumps(meta, indent=1))
    print(
        f"{model}: no training ranges; {out / model.name} has those of {len(shards)} "
        f"training shards ({meta['trained']['n_frames']} frames)",
        flush=True,
    )
    return out / model.name


def same_inputs(model: Path, take: Path, pred_dir: Path, every: int = 10) -> dict:
    """Whether predict and ingest see the same network input (one segmentation): every
    ``every``-th frame of the take through the predictor with the run's finder
    (``segmentation.json``) against the ingested shard's input of that frame; the
    largest difference (of 255) and the share of frames identical."""
    from finray.media import video_frames
    from finray.recording.finder import finder_from_spec

    p = Predictor(
        model,
        threads=1,
        backend="torchscript",
        finder=finder_from_spec(str(pred_dir / "segmentation.json")),
    )
    key = f"input_{p.size[0]}x{p.size[1]}"
    with np.load(take.parent / "ingest" / take.name / "shard.npz") as f:
        if key not in f.files:
            return {}
        shard = dict(zip(f["frame"].tolist(), f[key]))
    diffs = []
    for fr in video_frames(take / "take.mp4"):
        if fr.image is None or fr.index % every or fr.index not in shard:
            continue
        mask, _ = p.find(fr.image)
        x = np.rint(p.network_input(mask)[0, 0] * 255).astype(int)
        diffs.append(int(np.abs(x - shard[fr.index].astype(int)).max()))
    return {
        "frames_compared": len(diffs),
        "input_max_diff_255": max(diffs, default=0),
        "input_identical_frames_pct": 100 * float(np.mean([d == 0 for d in diffs]))
        if diffs
        else None,
    }


def main() -> int:
    ap = argparse.ArgumentParser()
    ap.add_argument("results", type=Path)
    ap.add_argument("out", type=Path)
    ap.add_argument("--model", default="camera")
    args = ap.parse_args()
    model = args.results / "train" / args.model / "model.ts"
    if not model.is_file():
        print(f"no model at {model}", file=sys.stderr)
        return 2
    model = with_ranges(model, args.results, args.out / "model")
    rows, summary = [], {"model": str(model), "emulated": True, "rigs": {}}
    for rig, (takes, sim_csv) in rig_takes(args.results).items():
        if not takes:
            continue
        sim = pd.read_csv(sim_csv) if sim_csv.is_file() else None
        if sim is not None:
            sim = sim[sim["context_objects"] == 0]
        per_rig, inputs = [], []
        for take in takes:
            out = args.out / rig / take.name
            res = predict_files(model, take / "take.mp4", out, force_only=True, overwrite=True)
            pred = pd.read_csv(out / "forces.csv")
            pred["frame"] = pred["frame"].str.rsplit("_", n=1).str[-1].astype(int)
            ingest = take.parent / "ingest" / take.name / "frames.csv"
            labels = pd.read_csv(ingest)[["frame", "force_N", "status"]]
            t = pred.merge(labels, on="frame", how="left").assign(
                rig=rig, take=take.name, finder=res["finder"]
            )
            if sim is not None:
                # sim-to-real names a take <object>_lab_h<h>_p<pitch>_<take folder>
                named = (sim["take"] == take.name) | sim["take"].str.endswith("_" + take.name)
                s = sim[named][["frame", "pred_N", "net_mean_N"]]
                t = t.merge(
                    s.rename(columns={"pred_N": "sim2real_N", "net_mean_N": "sim2real_net_N"}),
                    on="frame",
                    how="left",
                )
            per_rig.append(t)
            same = same_inputs(model, take, out)
            inputs.append(same)
            print(f"{rig}/{take.name}: {res['finder']}; inputs vs ingest's {same}", flush=True)
        table = pd.concat(per_rig, ignore_index=True)
        rows.append(table)
        both = table.dropna(subset=["force_N"])
        r = {
            "takes": len(takes),
            "frames": int(len(table)),
            "flagged": int((table["valid"] != "ok").sum()),
            "finders": sorted(set(table["finder"])),
            "predict_vs_sensor": force_metrics(both["force_N"], both["fx_N"]),
            "input_max_diff_255": max(
                (i.get("input_max_diff_255", 0) for i in inputs), default=None
            ),
            "inputs": inputs,
        }
        if "sim2real_N" in both:
            same = both.dropna(subset=["sim2real_N"])
            r["same_frames"] = int(len(same))
            r["predict_vs_sensor_same_frames"] = force_metrics(same["force_N"], same["fx_N"])
            r["sim2real_vs_sensor"] = force_metrics(same["force_N"], same["sim2real_N"])
            r["sim2real_net_vs_sensor"] = force_metrics(same["force_N"], same["sim2real_net_N"])
            r["predict_vs_sim2real_net_rmse_N"] = float(
                np.sqrt(np.mean((same["fx_N"] - same["sim2real_net_N"]) ** 2))
            )
        # a constant read while the sensor moves: the prediction's spread against the sensor's
        spread = both.groupby("take").agg(pred_sd=("fx_N", "std"), sensor_sd=("force_N", "std"))
        r["constant_takes"] = sorted(spread.index[spread["pred_sd"] < 0.05 * spread["sensor_sd"]])
        summary["rigs"][rig] = r
        print(
            rig,
            json.dumps(
                {
                    k: (v["nrmse_pct"] if isinstance(v, dict) and "nrmse_pct" in v else v)
                    for k, v in r.items()
                }
            ),
            flush=True,
        )
    args.out.mkdir(parents=True, exist_ok=True)
    pd.concat(rows, ignore_index=True).to_csv(
        args.out / "frames.csv", index=False, float_format="%.6g"
    )
    (args.out / "summary.json").write_text(json.dumps(summary, indent=1))
    lines = [
        "| rig | takes | frames | flagged | predict Fx NRMSE (%) | sim2real no-context NRMSE (%) "
        "| its heads' mean, NRMSE (%) | constant takes |",
        "|---|---|---|---|---|---|---|---|",
    ]
    for rig, r in summary["rigs"].items():
        p = r.get("predict_vs_sensor_same_frames", r["predict_vs_sensor"])["nrmse_pct"]
        s = r.get("sim2real_vs_sensor", {}).get("nrmse_pct", float("nan"))
        n = r.get("sim2real_net_vs_sensor", {}).get("nrmse_pct", float("nan"))
        lines.append(
            f"| {rig} | {r['takes']} | {r['frames']} | {r['flagged']} | {p:.1f} | {s:.1f} "
            f"| {n:.1f} | {len(r['constant_takes'])} |"
        )
    (args.out / "summary.md").write_text("\n".join(lines) + "\n")
    print("\n".join(lines))
    return 0


if __name__ == "__main__":
    sys.exit(main())
