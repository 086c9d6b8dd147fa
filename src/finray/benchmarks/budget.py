"""The training-budget study: CPU time per model against every error.

Training is most of the full run's cost. The study (``benchmarks.training_budget``,
``studies/training_budget/``, through the seeds study's rules) retrains every model at each *point* (train keys that
differ from the run's train section; the run's own is the point ``default``) with each
seed, and runs every experiment and sim-to-real on each (a spread variant
``s<seed>_<type>_<point>``). This module puts them side by side:

- :func:`budget_table` -- per point and figure the mean, min, max over seeds, with each
  point's training CPU minutes per model
- :func:`pareto_figure` -- error against CPU minutes, one panel per experiment
- :func:`write_budget` -- ``training_budget.{json,csv,md,png}``
"""

from __future__ import annotations

import json
import re
from pathlib import Path

import numpy as np
import pandas as pd

#: the figures a point is judged on: (panel, regular expression on the headline name)
PANELS = (
    ("held-out shapes", r"^shape \| [^|]+ \| (plain|camera) \| force NRMSE %$"),
    ("materials", r"^material \| [^|]+ \| (plain|camera) \| force NRMSE %$"),
    ("occlusion", r"^occlusion \| worst \| occlusion \| force NRMSE %$"),
    ("pitch (augmentation)", r"^pitch \| worst \| pitch \| force NRMSE %$"),
    ("viewpoint (pyvista renders)", r"^viewpoint \| worst \| (camera|pitch) \| force NRMSE %$"),
    ("sim-to-real (emulated rig)", r"^sim2real \| [02] context \| NRMSE %$"),
)


def cpu_seconds(benchmark_tsv: str | Path) -> float:
    """Job CPU time (s) of a benchmarked job (:func:`finray.benchmarks.timing.job_cpu_s`)."""
    from .timing import job_cpu_s

    return job_cpu_s(benchmark_tsv)[0]


def with_worst(figures: dict[str, float]) -> dict[str, float]:
    """``figures`` plus, per experiment and predictor with several conditions, the worst
    condition's force NRMSE: ``<experiment> | worst | <predictor> | force NRMSE %``."""
    worst: dict[str, float] = {}
    for name, v in figures.items():
        m = re.match(r"^(occlusion|pitch|viewpoint) \| [^|]+ \| ([^|(]+?) \| force NRMSE %$", name)
        if m:
            key = f"{m[1]} | worst | {m[2]} | force NRMSE %"
            worst[key] = max(worst.get(key, -np.inf), v)
    return figures | worst


def budget_table(
    figures: dict[str, dict[str, dict[str, float]]], cpu_s: dict[str, dict[str, dict[str, float]]]
) -> pd.DataFrame:
    """``figures``: point -> variant (seed) -> headline figures
    (:func:`finray.evaluate.spread.headline_figures`); ``cpu_s``: point -> variant ->
    model -> training job CPU (s). Rows (point, figure) with ``mean``, ``min``, ``max``,
    ``n`` over the seeds; each point also gets ``train | <model> | CPU min`` and
    ``train | all models | CPU min`` (their sum)."""
    rows = []
    for point, variants in figures.items():
        per = {v: with_worst(f) for v, f in variants.items()}
        for v, models in cpu_s.get(point, {}).items():
            for model, s in models.items():
                per.setdefault(v, {})[f"train | {model} | CPU min"] = s / 60
            per[v]["train | all models | CPU min"] = sum(models.values()) / 60
        df = pd.DataFrame(per)
        vals = df.to_numpy(dtype=float)
        for name, row in zip(df.index, vals):
            ok = row[np.isfinite(row)]
            rows.append(
                {
                    "point": point,
                    "figure": name,
                    "mean": ok.mean() if len(ok) else np.nan,
                    "min": ok.min() if len(ok) else np.nan,
                    "max": ok.max() if len(ok) else np.nan,
                    "n": len(ok),
                }
            )
    return pd.DataFrame(rows).set_index(["point", "figure"]).sort_index()


def pareto_figure(table: pd.DataFrame, path) -> None:
    """Each panel: the figures of :data:`PANELS` (mean over seeds, the range as a bar)
    against the point's training CPU minutes (all models, mean over seeds)."""
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    points = list(dict.fromkeys(table.index.get_level_values("point")))
    cost = {
        p: table.loc[(p, "train | all models | CPU min"), "mean"]
        if (p, "train | all models | CPU min") in table.index
        else np.nan
        for p in points
    }
    fig, axes = plt.subplots(2, 3, figsize=(12, 6.5), sharex=True)
    for ax, (title, pattern) in zip(axes.flat, PANELS):
        names = sorted({f for f in table.index.get_level_values("figure") if re.match(pattern, f)})
        for j, name in enumerate(names):
            xs, ys, lo, hi = [], [], [], []
            for p in points:
                if (p, name) in table.index and np.isfinite(cost[p]):
                    r = table.loc[(p, name)]
                    xs.append(cost[p]), ys.append(r["mean"]), lo.append(r["mean"] - r["min"])
                    hi.append(r["max"] - r["mean"])
            order = np.argsort(xs)
            x, y = np.asarray(xs)[order], np.asarray(ys)[order]
            err = np.array([np.asarray(lo)[order], np.asarray(hi)[order]])
            label = " | ".join(s for s in name.split(" | ")[1:-1] if s != "worst")
            ax.errorbar(
                x, y, yerr=err, marker="o", ms=4, capsize=3, color=f"C{j % 10}", label=label
            )
        for p in points:
            if np.isfinite(cost[p]):
                ax.annotate(
                    p, (cost[p], ax.get_ylim()[1]), fontsize=6, ha="center", va="top", color="0.4"
                )
        ax.set_title(title, fontsize=9)
        ax.set_ylabel("force NRMSE (% of the largest force)", fontsize=7)
        ax.tick_params(labelsize=7)
        ax.grid(lw=0.3)
        if names:
            ax.legend(fontsize=6)
    for ax in axes[-1]:
        ax.set_xlabel("training CPU time, all models (min; mean over seeds)", fontsize=7)
    fig.suptitle(
        "Training budget: error against CPU time (mean over seeds, bars the range; "
        "sim-to-real on the EMULATED rig)",
        fontsize=9,
    )
    fig.tight_layout()
    fig.savefig(path, dpi=150)
    plt.close(fig)


def _markdown(table: pd.DataFrame, cpu_name: str) -> str:
    points = list(dict.fromkeys(table.index.get_level_values("point")))
    names = sorted(set(table.index.get_level_values("figure")))
    lines = [
        f"Training CPU from the Snakemake benchmark files ({cpu_name}); every other "
        "figure is the mean over seeds, [min, max] after it. Sim-to-real is on the "
        "EMULATED lab rig.",
        "",
        "| figure | " + " | ".join(points) + " |",
        "|---" + "|--:" * len(points) + "|",
    ]
    for name in names:
        cells = []
        for p in points:
            if (p, name) not in table.index:
                cells.append("–")
                continue
            r = table.loc[(p, name)]
            cells.append(
                f"{r['mean']:.4g}"
                if r["n"] < 2 or r["min"] == r["max"]
                else f"{r['mean']:.4g} [{r['min']:.4g}, {r['max']:.4g}]"
            )
        lines.append(f"| {name.replace('|', chr(92) + '|')} | " + " | ".join(cells) + " |")
    return "\n".join(lines) + "\n"


def write_budget(figures, cpu_s, settings: dict, out: dict, cpu_name: str = "") -> pd.DataFrame:
    """``out``: paths ``json``, ``csv``, ``table`` (Markdown) and ``figure``;
    ``settings``: point -> its train keys (written to the JSON)."""
    table = budget_table(figures, cpu_s)
    table.to_csv(out["csv"], float_format="%.6g")
    Path(out["table"]).write_text(_markdown(table, cpu_name))
    js = {"cpu": cpu_name, "points": settings, "figures": {}}
    for (p, name), r in table.iterrows():
        js["figures"].setdefault(name, {})[p] = {
            c: (float(r[c]) if np.isfinite(r[c]) else None) for c in ("mean", "min", "max")
        } | {"n": int(r["n"])}
    Path(out["json"]).write_text(json.dumps(js, indent=1))
    pareto_figure(table, out["figure"])
    return table
