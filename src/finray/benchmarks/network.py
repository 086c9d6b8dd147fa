"""Run time against error of the network: input size x width (Pareto study).

Each variant (input ``H x W``, ``base`` channels) is trained the same way on a subset
of the training shards (every k-th frame, a few epochs, no augmentation; the epoch
with the best validation loss kept, as in the real training) and scored on the
frames of held-out scenes (the same scenes :func:`finray.train.train_from_shards`
holds out): force RMSE (N), force NRMSE (RMSE over the validation forces' range) and
stress MSE (log-stress units). Costs: training seconds per epoch (and per frame), and
the network's latency per frame at batch 1 on one thread in ONNX Runtime, force only
and full (stress map too). The short training is a ranking, not the final errors:
every variant gets the same frames, epochs and seed.

The default: among the variants whose network (force path, CPU time) fits
``budget_ms`` (the 2 ms per-frame target minus the preprocessing), the fastest whose
force RMSE is within ``tolerance`` of the best of them; the summary also says whether
the configured default (``train.input_size`` x ``train.base_channels``) is that
variant and on the front.
"""

from __future__ import annotations

import tempfile
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from .pareto import pareto_front
from .timing import Stopwatch, time_calls
from ..schema import schema_default

COLUMNS = [
    "input",
    "height",
    "width",
    "base_channels",
    "parameters",
    "n_train",
    "n_val",
    "epochs",
    "train_s_per_epoch",
    "train_ms_per_frame",
    "train_cpu_s_per_epoch",
    "infer_force_ms",
    "infer_full_ms",
    "infer_force_cpu_ms",
    "infer_full_cpu_ms",
    "val_force_rmse_N",
    "val_force_nrmse",
    "val_stress_mse",
    "pareto",
    "chosen",
    "configured",
]


@dataclass(frozen=True)
class Variant:
    height: int
    width: int
    base_channels: int

    @property
    def label(self) -> str:
        return f"{self.height}x{self.width} b{self.base_channels}"


def network_latency(model, n_calls: int = 200, repeats: int = 3) -> dict:
    """Median latency (ms) of the network alone at batch 1, one thread, ONNX Runtime:
    ``force`` (encoder + force head) and ``full`` (with the stress decoder), wall time,
    and ``force_cpu``, ``full_cpu``: the calling thread's CPU time (ONNX Runtime runs a
    one-thread session in it), which a machine shared with other jobs inflates less."""
    import onnxruntime as ort

    from ..train import export_onnx, force_onnx_path

    c = model.cfg
    x = np.random.default_rng(0).random((1, c.in_channels, c.height, c.width)).astype(np.float32)
    opts = ort.SessionOptions()
    opts.intra_op_num_threads = 1
    opts.inter_op_num_threads = 1
    out = {}
    with tempfile.TemporaryDirectory() as tmp:
        path = Path(tmp) / "model.onnx"
        export_onnx(model, path)
        for key, f in (("force", force_onnx_path(path)), ("full", path)):
            sess = ort.InferenceSession(str(f), opts, providers=["CPUExecutionProvider"])
            t = time_calls(
                lambda k: sess.run(None, {"image": x}), n_calls, repeats, warmup=20, cpu="thread"
            )
            out[key] = t.wall_s * 1e3
            out[f"{key}_cpu"] = t.cpu_s * 1e3
    return out


def choose_default(
    cost: np.ndarray, error: np.ndarray, tolerance: float, budget: float = np.inf
) -> int:
    """Index of the cheapest variant whose error is at most ``(1 + tolerance)`` x the
    best error among the variants that cost at most ``budget`` (all of them if none
    does)."""
    cost, error = np.asarray(cost, float), np.asarray(error, float)
    pool = np.flatnonzero(cost <= budget)
    if len(pool) == 0:
        pool = np.arange(len(cost))
    ok = pool[error[pool] <= (1.0 + tolerance) * error[pool].min()]
    return int(ok[np.argmin(cost[ok])])


def run_time_vs_error(
    shards,
    out_csv,
    out_png,
    out_md,
    sizes,
    bases,
    configured,
    epochs: int = 3,
    every: int = 6,
    tolerance: float = 0.1,
    budget_ms: float = 1.0,
    latency_calls: int = 200,
    val_fraction: float = schema_default("train.val_fraction"),
    batch_size: int = schema_default("train.batch_size"),
    lr: float = 1e-4,
    seed: int = 0,
    bf16: bool | str = schema_default("train.bf16"),
    channels_last: bool = schema_default("train.channels_last"),
    schedule: dict | None = None,
    log=print,
):
    """Train and time every ``sizes x bases`` variant; write the table (CSV), the
    Pareto figure (PNG) and a summary (Markdown); returns the table (DataFrame).

    ``configured``: ``(height, width, base)`` of the configured default model;
    ``schedule``: the training's ``schedule``, ``warmup_frac``, ``bn_frames``, ``keep`` and
    ``ema_decay`` (:class:`finray.train.TrainConfig`; default: its defaults).
    """
    import pandas as pd
    import torch

    from ..model import NetConfig, count_parameters
    from ..train import TrainConfig, evaluate, load_split, train, validation_scenes

    torch.set_num_threads(1)
    rows = []
    # a CPU cost study (one thread, as its latencies): on the CPU whatever the machine has
    # the networks without the contact head (contact_weight 0), as measured before it
    cfg = TrainConfig(
        epochs=epochs,
        batch_size=batch_size,
        lr=lr,
        seed=seed,
        threads=1,
        bf16=bf16,
        device="cpu",
        channels_last=channels_last,
        progress=False,
        contact_weight=0.0,
        **(schedule or {}),
    )
    for h, w in sizes:
        data = load_split(shards, (h, w), every)
        val_ids = validation_scenes(data["scene_id"], val_fraction, seed)
        is_val = np.isin(data["scene_id"], list(val_ids))
        if not is_val.any() or is_val.all():
            raise ValueError("the study needs at least two training scenes (one held out)")
        tr = {k: v[~is_val] for k, v in data.items()}
        va = {k: v[is_val] for k, v in data.items()}
        for base in bases:
            v = Variant(h, w, base)
            log(f"{v.label}: {len(tr['images'])} training frames, {len(va['images'])} validation")
            net = NetConfig(in_channels=1, base_channels=base, height=h, width=w)
            # the kept epoch, the schedule and batch-norm as in the real training
            with Stopwatch(cpu="thread") as clock:
                model, hist = train(
                    tr["images"],
                    tr["stress"],
                    tr["fx_N"],
                    (va["images"], va["stress"], va["fx_N"]),
                    net,
                    cfg,
                    log=log,
                )
            cpu_seconds = clock.cpu_s  # with the validation passes
            seconds = hist.wall_time_s[-1]  # the loop, before the last validation pass
            ev = evaluate(
                model,
                torch.as_tensor(va["images"]),
                torch.as_tensor(va["stress"]),
                torch.as_tensor(va["fx_N"]),
                cfg,
            )
            f_range = float(va["fx_N"].max() - va["fx_N"].min())
            lat = network_latency(model, latency_calls)
            rows.append(
                {
                    "input": f"{h}x{w}",
                    "height": h,
                    "width": w,
                    "base_channels": base,
                    "parameters": count_parameters(model),
                    "n_train": len(tr["images"]),
                    "n_val": len(va["images"]),
                    "epochs": epochs,
                    "train_s_per_epoch": seconds / epochs,
                    "train_ms_per_frame": 1e3 * seconds / (epochs * len(tr["images"])),
                    "train_cpu_s_per_epoch": cpu_seconds / epochs,
                    "infer_force_ms": lat["force"],
                    "infer_full_ms": lat["full"],
                    "infer_force_cpu_ms": lat["force_cpu"],
                    "infer_full_cpu_ms": lat["full_cpu"],
                    "val_force_rmse_N": ev["force_rmse_N"],
                    "val_force_nrmse": ev["force_rmse_N"] / max(f_range, 1e-12),
                    "val_stress_mse": ev["stress_mse"],
                }
            )
            log(f"{v.label}: {rows[-1]}")
    return finish_table(
        pd.DataFrame(rows), out_csv, out_png, out_md, configured, tolerance, budget_ms
    )


def finish_table(
    table, out_csv, out_png, out_md, configured, tolerance: float = 0.1, budget_ms: float = 1.0
):
    """Mark the Pareto front, the chosen and the configured variants of the measured
    ``table``; write the CSV, the figure and the summary; return the table."""
    cost, err = table["infer_force_cpu_ms"].to_numpy(), table["val_force_rmse_N"].to_numpy()
    table["pareto"] = pareto_front(cost, err)
    chosen = choose_default(cost, err, tolerance, budget_ms)
    table["chosen"] = np.arange(len(table)) == chosen
    table["configured"] = [
        (r.height, r.width, r.base_channels) == tuple(configured) for r in table.itertuples()
    ]
    table = table[COLUMNS]
    table.to_csv(out_csv, index=False, float_format="%.6g")
    pareto_figure(table, out_png, budget_ms)
    Path(out_md).write_text(summary_markdown(table, tolerance, configured, budget_ms))
    return table


def pareto_figure(table, path, budget_ms: float | None = None) -> None:
    """Validation force RMSE against the network's latency (force path and full), the
    Pareto front joined, the chosen and the configured variants marked."""
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    fig, ax = plt.subplots(1, 2, figsize=(9, 3.6))
    for a, col, title in (
        (ax[0], "infer_force_cpu_ms", "force only"),
        (ax[1], "infer_full_cpu_ms", "force + stress map"),
    ):
        a.plot(table[col], table["val_force_rmse_N"], "o", color="0.5")
        front = table[table["pareto"]].sort_values(col)
        a.plot(
            front[col],
            front["val_force_rmse_N"],
            "-",
            color="C0",
            label="Pareto front (force path)",
        )
        for r in table.itertuples():
            a.annotate(
                f"{r.input} b{r.base_channels}",
                (getattr(r, col), r.val_force_rmse_N),
                fontsize=7,
                xytext=(4, 3),
                textcoords="offset points",
            )
        ch = table[table["chosen"]]
        a.plot(ch[col], ch["val_force_rmse_N"], "*", ms=14, color="C3", label="chosen")
        cf = table[table["configured"]]
        a.plot(
            cf[col],
            cf["val_force_rmse_N"],
            "s",
            ms=10,
            mfc="none",
            color="k",
            label="configured default",
        )
        a.set_xlabel(f"network CPU time per frame, {title} (ms)")
        a.set_ylabel("validation force RMSE (N)")
        a.set_xlim(0, None)
    if budget_ms is not None and np.isfinite(budget_ms):
        ax[0].axvline(budget_ms, color="C2", ls="--", lw=1, label="latency budget")
    ax[0].legend(fontsize=7)
    fig.suptitle(
        "input size x width: batch 1, one thread, ONNX Runtime; held-out scenes", fontsize=9
    )
    fig.tight_layout()
    fig.savefig(path, dpi=130)
    plt.close(fig)


def summary_markdown(table, tolerance: float, configured, budget_ms: float = np.inf) -> str:
    """The table and the choice, in words."""
    ch = table[table["chosen"]].iloc[0]
    best = table.loc[table["val_force_rmse_N"].idxmin()]
    cf = table[table["configured"]]
    n_train, epochs = int(table["n_train"].iloc[0]), int(table["epochs"].iloc[0])
    lines = [
        "# Network: run time against error (input size x width)",
        "",
        f"Each variant trained {epochs} epoch(s) on the same {n_train} training frames "
        "(a subset of the training shards, no augmentation, same seed), scored on "
        f"{int(table['n_val'].iloc[0])} frames of held-out scenes. Latencies: the network "
        "alone at batch 1, one thread, ONNX Runtime, median wall and CPU time (`_cpu_`: the "
        "cost axis, less inflated by other jobs on a shared machine); preprocessing adds "
        "the same for every variant, see inference_latency.json. Training: s per epoch, one "
        "thread. "
        "One seed and a short schedule: the costs are firm, small error differences "
        "(tens of %) are within the run-to-run variation of such a training.",
        "",
        table.to_markdown(index=False, floatfmt=".4g"),
        "",
        f"Best force RMSE: {best['input']} base {int(best['base_channels'])} "
        f"({best['val_force_rmse_N']:.4g} N).",
        "",
        f"**Chosen default: {ch['input']} base {int(ch['base_channels'])}** (force RMSE "
        f"{ch['val_force_rmse_N']:.4g} N, force path {ch['infer_force_cpu_ms']:.3g} ms CPU): "
        f"among the variants whose network fits the latency budget ({budget_ms:g} ms: the "
        "2 ms per frame target minus the preprocessing), the fastest whose force RMSE is "
        f"within {100 * tolerance:g} % of the best of them.",
    ]
    h, w, b = configured
    lines.append("")
    if len(cf):
        c = cf.iloc[0]
        same = bool(c["chosen"])
        lines.append(
            f"Configured default (train.input_size {h}x{w}, base_channels {b}): "
            + (
                "the chosen variant."
                if same
                else f"force RMSE {c['val_force_rmse_N']:.4g} N at {c['infer_force_cpu_ms']:.3g} ms CPU, "
                f"{'on' if c['pareto'] else 'off'} the Pareto front; the study would choose "
                f"{ch['input']} base {int(ch['base_channels'])}."
            )
        )
    else:
        lines.append(f"Configured default ({h}x{w}, base {b}) is not among the variants.")
    lines += [
        "",
        "Pareto front (force path): "
        + ", ".join(f"{r.input} b{r.base_channels}" for r in table.itertuples() if r.pareto)
        + ".",
        "",
    ]
    return "\n".join(lines)


def train_time_table(models, histories, benchmarks):
    """Training time of each model of the full config: from its ``history.json``
    (epochs, frames, seconds in the training loop, numeric type, measured step time,
    CPU, best validation force RMSE) and
    Snakemake's benchmark ``.tsv`` of the job (wall seconds, peak RSS MB) and its log
    (CPU seconds, :func:`~.timing.job_cpu_s`)."""
    import json

    from .timing import job_cpu_s

    import pandas as pd

    rows = []
    for name, hist_path, tsv in zip(models, histories, benchmarks):
        h = json.loads(Path(hist_path).read_text())
        b = pd.read_csv(tsv, sep="\t").iloc[-1]
        epochs = len(h["epoch"])
        meta_path = Path(hist_path).parent / "model.ts.json"
        meta = json.loads(meta_path.read_text()) if meta_path.is_file() else {}
        row = {
            "model": name,
            "input": f"{meta.get('height')}x{meta.get('width')}",
            "base_channels": meta.get("base_channels"),
            "epochs": epochs,
            "n_train": h.get("n_train"),
            "n_val": h.get("n_val"),
            "train_loop_s": h.get("train_seconds"),
            "s_per_epoch": h.get("train_seconds", float("nan")) / max(epochs, 1),
            "job_wall_s": float(b["s"]),
            "job_cpu_s": job_cpu_s(tsv)[0],  # the job's own figure (its log), not a sample
            "max_rss_MB": float(b["max_rss"]),
            "precision": h.get("precision", ""),
            "step_ms": h.get("step_ms"),
            "step_cpu_ms": h.get("step_cpu_ms"),
            "cpu": h.get("cpu", ""),
            "best_val_force_rmse_N": min(h["val_force_rmse_N"])
            if h.get("val_force_rmse_N")
            else None,
        }
        row["ms_per_frame"] = 1e3 * row["s_per_epoch"] / max(row["n_train"] or 1, 1)
        rows.append(row)
    return pd.DataFrame(rows)
