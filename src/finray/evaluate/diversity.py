"""Training on procedurally generated objects (config ``generated``): one model trained on
the paper's objects only and on the paper's objects plus the generated ones, both scored
on the paper's held-out test sets by :func:`~finray.evaluate.experiments.run_experiment`
(shard path, all frames). ``results/evaluate/diversity/`` holds each test set's experiment
(``<test>/metrics.csv`` ...), ``table.csv`` (one row per test set and group: n, each
metric of both models and the difference) and ``summary.json`` (the summary's
``diversity`` key)."""

from __future__ import annotations

import json
from pathlib import Path

import pandas as pd

from .experiments import run_experiment
from .summary import training_summary

#: The compared models, as the outputs name them.
PAPER, GENERATED = "paper_objects", "with_generated"
#: Metrics compared: force MSE (N²), NRMSE (%), R², log-stress MSE, SSIM.
METRICS = ("mse_N2", "nrmse_pct", "r2", "stress_mse_log", "ssim")
#: Metrics where larger is better (the others: smaller is better).
HIGHER_IS_BETTER = frozenset({"r2", "ssim"})


def comparison_table(metrics: dict[str, pd.DataFrame]) -> pd.DataFrame:
    """Per test set (name -> its ``metrics.csv`` table) and group (``all`` first): ``n``,
    ``<metric>_paper_objects``, ``<metric>_with_generated`` and ``<metric>_diff``
    (with_generated - paper_objects) of the shard path on all frames."""
    rows = []
    for test, m in metrics.items():
        if "path" in m:
            m = m[(m["path"] == "shard") & (m["frames"] == "all")]
        for group, g in m.groupby(m["group"].astype(str), sort=False):
            by = g.set_index("predictor")
            missing = {PAPER, GENERATED} - set(by.index)
            if missing:
                raise ValueError(f"{test}/{group}: no metrics of {sorted(missing)}")
            a, b = by.loc[PAPER], by.loc[GENERATED]
            if int(a["n"]) != int(b["n"]):
                raise ValueError(
                    f"{test}/{group}: the models were scored on {int(a['n'])} and {int(b['n'])} frames"
                )
            row = {"test": test, "group": group, "n": int(a["n"])}
            for k in METRICS:
                row[f"{k}_{PAPER}"], row[f"{k}_{GENERATED}"] = float(a[k]), float(b[k])
                row[f"{k}_diff"] = float(b[k]) - float(a[k])
            rows.append(row)
    return pd.DataFrame(rows)


def _node(row: dict) -> dict:
    """One table row as ``{n, paper_objects: {..}, with_generated: {..}, diff: {..},
    better: {metric: with_generated is better}}`` (a tie is not better)."""
    diff = {k: row[f"{k}_diff"] for k in METRICS}
    return {
        "n": int(row["n"]),
        PAPER: {k: row[f"{k}_{PAPER}"] for k in METRICS},
        GENERATED: {k: row[f"{k}_{GENERATED}"] for k in METRICS},
        "diff": diff,
        "better": {k: bool(d > 0 if k in HIGHER_IS_BETTER else d < 0) for k, d in diff.items()},
    }


def diversity_summary(table: pd.DataFrame, trainings: dict[str, dict], setup: dict) -> dict:
    """The summary's ``diversity`` key: ``setup`` (model names, object counts), the two
    models' training (``trainings``: :func:`~finray.evaluate.summary.training_summary` by
    PAPER / GENERATED) and per test set ``{"all": node, "groups": {group: node}}``."""
    tests: dict = {}
    for r in table.to_dict("records"):
        t = tests.setdefault(r["test"], {"groups": {}})
        if r["group"] == "all":
            t["all"] = _node(r)
        else:
            t["groups"][r["group"]] = _node(r)
    return {**setup, "training": trainings, "tests": tests}


def run_diversity(
    out_dir,
    test_sets: dict[str, dict],
    size,
    models: dict[str, str],
    histories: dict[str, str],
    setup: dict,
    log=print,
) -> dict:
    """Score ``models`` (PAPER and GENERATED -> TorchScript) on every test set (name ->
    ``{"shards": [...], "group_col": str}``) into ``out_dir/<test>/``; write
    ``table.csv`` and ``summary.json`` (returned). ``histories``: each model's
    ``history.json``; ``setup``: what the summary states of the set-up."""
    if set(models) != {PAPER, GENERATED} or set(histories) != set(models):
        raise ValueError(
            f"need the models {PAPER} and {GENERATED}, got {sorted(models)} and {sorted(histories)}"
        )
    out_dir = Path(out_dir)
    metrics = {
        t: run_experiment(
            out_dir / t, ts["shards"], tuple(size), models, None, group_col=ts["group_col"], log=log
        )
        for t, ts in test_sets.items()
    }
    table = comparison_table(metrics)
    table.to_csv(out_dir / "table.csv", index=False, float_format="%.10g")
    log(table.to_string(index=False, float_format=lambda v: f"{v:.4g}"))
    trainings = {k: training_summary(json.loads(Path(p).read_text())) for k, p in histories.items()}
    s = diversity_summary(table, trainings, setup)
    (out_dir / "summary.json").write_text(json.dumps(s, indent=1))
    return s
