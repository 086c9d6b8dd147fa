"""QA of the emulated lab takes: ingest against the emulator's truth, and the plain model
on them.

Per take (``finray ingest`` output against the take's ``truth/``): the clock offset's
error (ms, and in frames), the colour mask's IoU with the true mask on every frame, the
frames ingest kept, and its time. Per take and over all: the force metrics of a model
(through the shard path, as the other experiments) with the sensor as truth (the label
ingest wrote: gain error and offsets included) and with the true push force.
These are emulated takes: the numbers measure the pipeline on a stand-in for a rig.
"""

from __future__ import annotations

import json
from pathlib import Path

import numpy as np
import pandas as pd

from .metrics import force_metrics


def _unpack(npz) -> tuple[np.ndarray, dict]:
    """A bit-packed mask file: the masks (F, H, W) bool and its other arrays."""
    with np.load(npz) as f:
        rest = {k: f[k] for k in f.files if k != "bits"}
        bits = f["bits"]
    return np.unpackbits(bits, axis=-1)[..., : int(rest["shape"][-1])].astype(bool), rest


def mask_iou(ingest_dir, take_dir) -> pd.DataFrame:
    """Per frame: IoU of ingest's colour mask with the true mask (``masks.npz`` of both)."""
    got, meta = _unpack(Path(ingest_dir) / "masks.npz")
    frames = meta["frame"]
    true = _unpack(Path(take_dir) / "truth" / "masks.npz")[0][frames]
    inter = (got & true).sum(axis=(1, 2))
    union = (got | true).sum(axis=(1, 2))
    return pd.DataFrame(
        {
            "frame": frames,
            "iou": inter / np.maximum(union, 1),
            "true_px": true.sum(axis=(1, 2)),
            "mask_px": got.sum(axis=(1, 2)),
        }
    )


def take_qa(take_dir, ingest_dir) -> tuple[dict, pd.DataFrame]:
    """One take's QA (dict) and its per-frame table (frame, t_s, iou, true force, label)."""
    take_dir, ingest_dir = Path(take_dir), Path(ingest_dir)
    truth = json.loads((take_dir / "truth" / "truth.json").read_text())
    summary = json.loads((ingest_dir / "ingest.json").read_text())
    frames = pd.read_csv(ingest_dir / "frames.csv")
    true_frames = pd.read_csv(take_dir / "truth" / "frames.csv")
    iou = mask_iou(ingest_dir, take_dir)
    table = (
        frames[["frame", "t_s", "status", "force_N"]]
        .rename(columns={"force_N": "sensor_label_N"})
        .merge(
            true_frames[["frame", "push_mm", "force_N"]].rename(
                columns={"force_N": "true_force_N"}
            ),
            on="frame",
            how="left",
        )
        .merge(iou[["frame", "iou"]], on="frame", how="left")
    )
    err = summary["sync"]["offset_s"] - truth["offset_s"]
    qa = {
        "take": take_dir.name,
        "frames": int(truth["n_frames"]),
        "frames_kept": int(summary["frames"]["ok"]),
        "frame_rate_hz": float(summary["frame_rate_hz"]),
        "offset_true_s": truth["offset_s"],
        "offset_s": summary["sync"]["offset_s"],
        "offset_uncertainty_s": summary["sync"]["uncertainty_s"],
        "offset_error_ms": 1e3 * err,
        "offset_error_frames": err / truth["frame_interval_s"],
        "offset_drift_ms": 1e3 * abs(truth["offset_end_s"] - truth["offset_start_s"]),
        "iou_min": float(iou["iou"].min()),
        "iou_median": float(iou["iou"].median()),
        "iou_min_frame": int(iou.loc[iou["iou"].idxmin(), "frame"]),
        "ingest_wall_s": summary["wall_s"],
        "ingest_cpu_s": summary["cpu_s"],
        "force_max_true_N": truth["force_max_N"],
    }
    return qa, table


def model_forces(shards: dict, model_path, size) -> pd.DataFrame:
    """A model's force (N) on every frame of lab shards ``{take: shard}`` (shard path):
    take, frame, pred_N."""
    from ..dataset import load_frames
    from ..predictor import Predictor
    from .predictions import predict_images

    net = Predictor(model_path, threads=1, backend="torchscript", roi_stride=1)
    parts = []
    for take, shard in shards.items():
        a, table = load_frames([shard], tuple(size))
        pred, _ = predict_images(net, a["images"])
        parts.append(
            pd.DataFrame({"take": take, "frame": table["frame"].to_numpy(), "pred_N": pred[:, 0]})
        )  # fx: the sensor's push force
    return pd.concat(parts, ignore_index=True)


def lab_qa(
    take_dirs,
    ingest_dirs,
    model_path,
    size,
    model_name: str = "plain",
    other_models: dict[str, str] | None = None,
):
    """QA of every take: (per-take table, per-frame table, summary dict). ``other_models``
    (name -> model.ts) are scored on the same frames too: ``summary["other_models"]``
    and ``pred_<name>_N`` in the per-frame table."""
    rows, frames = [], []
    for take_dir, ingest_dir in zip(take_dirs, ingest_dirs):
        qa, table = take_qa(take_dir, ingest_dir)
        rows.append(qa)
        frames.append(table.assign(take=qa["take"]))
    per_take = pd.DataFrame(rows)
    per_frame = pd.concat(frames, ignore_index=True)
    pred = model_forces(
        {q: Path(d) / "shard.npz" for q, d in zip(per_take["take"], ingest_dirs)}, model_path, size
    )
    per_frame = per_frame.merge(pred, on=["take", "frame"], how="left")
    scored = per_frame.dropna(subset=["pred_N", "sensor_label_N"])
    for col, what in (("sensor_label_N", "sensor"), ("true_force_N", "true")):
        m = {t: force_metrics(g[col], g["pred_N"]) for t, g in scored.groupby("take")}
        per_take[f"{model_name}_mse_N2_vs_{what}"] = per_take["take"].map(lambda t: m[t]["mse_N2"])
        per_take[f"{model_name}_nrmse_pct_vs_{what}"] = per_take["take"].map(
            lambda t: m[t]["nrmse_pct"]
        )
    summary = {
        "emulated": True,
        "n_takes": int(len(per_take)),
        "model": model_name,
        "offset_error_ms_max": float(per_take["offset_error_ms"].abs().max()),
        "offset_error_frames_max": float(per_take["offset_error_frames"].abs().max()),
        "iou_min": float(per_take["iou_min"].min()),
        "iou_min_take": str(per_take.loc[per_take["iou_min"].idxmin(), "take"]),
        "iou_median": float(per_frame["iou"].median()),
        "ingest_wall_s_max": float(per_take["ingest_wall_s"].max()),
        "ingest_cpu_s_max": float(per_take["ingest_cpu_s"].max()),
        "frames_kept": int(per_take["frames_kept"].sum()),
        "frames": int(per_take["frames"].sum()),
        "force_vs_sensor": force_metrics(scored["sensor_label_N"], scored["pred_N"]),
        "force_vs_true": force_metrics(scored["true_force_N"], scored["pred_N"]),
        "sensor_vs_true": force_metrics(scored["true_force_N"], scored["sensor_label_N"]),
    }
    # the frames without contact (true force below 1 % of the largest): what the model
    # makes of the unloaded finger
    rest = scored["true_force_N"] < 0.01 * scored["true_force_N"].max()
    summary["rest_frames"] = int(rest.sum())
    summary["rest_pred_mean_N"] = float(scored.loc[rest, "pred_N"].mean()) if rest.any() else None
    sq = (scored["pred_N"] - scored["true_force_N"]) ** 2
    summary["rest_share_of_squared_error_pct"] = (
        float(100 * sq[rest].sum() / sq.sum()) if sq.sum() > 0 else None
    )
    summary["contact_vs_true"] = (
        force_metrics(scored.loc[~rest, "true_force_N"], scored.loc[~rest, "pred_N"])
        if (~rest).any()
        else None
    )
    summary["other_models"] = {}
    shards = {q: Path(d) / "shard.npz" for q, d in zip(per_take["take"], ingest_dirs)}
    for name, path in (other_models or {}).items():
        pred = model_forces(shards, path, size).rename(columns={"pred_N": f"pred_{name}_N"})
        per_frame = per_frame.merge(pred, on=["take", "frame"], how="left")
        sc = per_frame.dropna(subset=[f"pred_{name}_N", "sensor_label_N"])
        r = sc["true_force_N"] < 0.01 * sc["true_force_N"].max()
        summary["other_models"][name] = {
            "force_vs_sensor": force_metrics(sc["sensor_label_N"], sc[f"pred_{name}_N"]),
            "force_vs_true": force_metrics(sc["true_force_N"], sc[f"pred_{name}_N"]),
            "rest_pred_mean_N": float(sc.loc[r, f"pred_{name}_N"].mean()) if r.any() else None,
        }
    return per_take, per_frame, summary


def qa_figure(path, per_take: pd.DataFrame, per_frame: pd.DataFrame, title: str) -> None:
    """Per take: the sensor's label, the true force and the model's prediction against
    time (left), and the mask IoU per frame (right column, all takes)."""
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    takes = list(per_take["take"])
    n = len(takes)
    cols = min(3, n)
    rows = int(np.ceil(n / cols))
    fig = plt.figure(figsize=(4.2 * cols + 4.5, 2.6 * rows + 0.6))
    gs = fig.add_gridspec(rows, cols + 1)
    for i, take in enumerate(takes):
        ax = fig.add_subplot(gs[i // cols, i % cols])
        g = per_frame[per_frame["take"] == take]
        ax.plot(g["t_s"], g["sensor_label_N"], color="0.5", lw=1.0, label="sensor (label)")
        ax.plot(g["t_s"], g["true_force_N"], color="k", lw=0.6, ls="--", label="true")
        ax.plot(g["t_s"], g["pred_N"], color="C3", lw=1.0, label="model")
        q = per_take[per_take["take"] == take].iloc[0]
        ax.set_title(f"{take}: offset err {q['offset_error_ms']:+.1f} ms", fontsize=8)
        ax.tick_params(labelsize=7)
        if i % cols == 0:
            ax.set_ylabel("push force (N)", fontsize=8)
        if i // cols == rows - 1:
            ax.set_xlabel("camera time (s)", fontsize=8)
        if i == 0:
            ax.legend(fontsize=6)
    ax = fig.add_subplot(gs[:, cols])
    for take in takes:
        g = per_frame[per_frame["take"] == take]
        ax.plot(g["t_s"], g["iou"], lw=0.8, label=take)
    ax.set_xlabel("camera time (s)", fontsize=8)
    ax.set_ylabel("mask IoU with the true mask", fontsize=8)
    ax.legend(fontsize=6)
    ax.tick_params(labelsize=7)
    fig.suptitle(title, fontsize=10)
    fig.tight_layout()
    fig.savefig(path, dpi=110)
    plt.close(fig)
