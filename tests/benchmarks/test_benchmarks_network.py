"""The network's run-time/error study: Pareto front, the default's choice, the tables."""

import json

import numpy as np
import pandas as pd

from finray.benchmarks.network import COLUMNS, choose_default, summary_markdown, train_time_table
from finray.benchmarks.pareto import pareto_front


def test_choose_default_is_the_cheapest_within_tolerance():
    cost = np.array([0.4, 1.4, 1.5, 4.6])
    err = np.array([0.30, 0.25, 0.26, 0.24])
    assert choose_default(cost, err, 0.1) == 1  # 0.25 <= 1.1 x 0.24; 0.30 is not
    assert choose_default(cost, err, 0.3) == 0
    assert choose_default(cost, err, 0.0) == 3
    assert choose_default(cost, err, 0.1, budget=1.45) == 1  # 1.5 and 4.6 ms do not fit
    assert choose_default(cost, err, 0.1, budget=1.0) == 0
    assert choose_default(cost, err, 0.1, budget=0.1) == 1  # none fits: all compete


def test_summary_names_the_chosen_and_the_configured_variant():
    rows = []
    for k, (size, base, ms, rmse) in enumerate(
        [
            ("64x32", 16, 0.4, 0.30),
            ("64x32", 32, 1.4, 0.25),
            ("128x64", 16, 1.5, 0.26),
            ("128x64", 32, 4.6, 0.24),
        ]
    ):
        h, w = map(int, size.split("x"))
        rows.append(
            {
                "input": size,
                "height": h,
                "width": w,
                "base_channels": base,
                "parameters": 1,
                "n_train": 100,
                "n_val": 10,
                "epochs": 3,
                "train_s_per_epoch": 1.0,
                "train_ms_per_frame": 10.0,
                "train_cpu_s_per_epoch": 1.0,
                "infer_force_ms": ms,
                "infer_full_ms": 2 * ms,
                "infer_force_cpu_ms": ms,
                "infer_full_cpu_ms": 2 * ms,
                "val_force_rmse_N": rmse,
                "val_force_nrmse": rmse / 8,
                "val_stress_mse": 0.1,
            }
        )
    t = pd.DataFrame(rows)
    t["pareto"] = pareto_front(t["infer_force_ms"], t["val_force_rmse_N"])
    t["chosen"] = np.arange(4) == choose_default(t["infer_force_ms"], t["val_force_rmse_N"], 0.1)
    t["configured"] = np.arange(4) == 0
    md = summary_markdown(t[COLUMNS], 0.1, (64, 32, 16), 2.0)
    assert "Chosen default: 64x32 base 32" in md
    assert "on the Pareto front; the study would choose 64x32 base 32" in md


def test_train_time_table(tmp_path):
    d = tmp_path / "plain"
    d.mkdir()
    (d / "history.json").write_text(
        json.dumps(
            {
                "epoch": [1, 2],
                "val_force_rmse_N": [0.3, 0.2],
                "n_train": 1000,
                "n_val": 100,
                "train_seconds": 50.0,
                "precision": "float32",
                "step_ms": 80.0,
                "step_cpu_ms": 78.0,
                "cpu": "AMD EPYC",
            }
        )
    )
    (d / "model.ts.json").write_text(json.dumps({"height": 64, "width": 32, "base_channels": 16}))
    tsv = tmp_path / "plain.tsv"
    tsv.write_text(
        "s\th:m:s\tmax_rss\tmax_vms\tmax_uss\tmax_pss\tio_in\tio_out\tmean_load\tcpu_time\n"
        "60.5\t0:01:00\t1300.0\t1900\t1200\t1250\t10\t1\t95\t58.0\n"
    )
    t = train_time_table(["plain"], [d / "history.json"], [tsv])
    r = t.iloc[0]
    assert r["input"] == "64x32" and r["base_channels"] == 16
    assert r["s_per_epoch"] == 25.0 and r["ms_per_frame"] == 25.0
    assert r["job_wall_s"] == 60.5 and r["job_cpu_s"] == 58.0 and r["best_val_force_rmse_N"] == 0.2
    assert (r["precision"], r["step_ms"], r["step_cpu_ms"], r["cpu"]) == (
        "float32",
        80.0,
        78.0,
        "AMD EPYC",
    )
