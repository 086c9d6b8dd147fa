"""The training-budget study's table: per point and figure the mean and range over seeds,
each point's training CPU time, and the worst condition of the multi-condition experiments."""

import json

import pytest

from finray.benchmarks.budget import budget_table, cpu_seconds, with_worst, write_budget

FIGURES = {
    "default": {
        "s0_auto": {
            "shape | none | camera | force NRMSE %": 1.9,
            "pitch | 0 | pitch | force NRMSE %": 1.0,
            "pitch | 30 | pitch | force NRMSE %": 3.0,
            "sim2real | 2 context | NRMSE %": 3.4,
        },
        "s1_auto": {
            "shape | none | camera | force NRMSE %": 2.1,
            "pitch | 0 | pitch | force NRMSE %": 2.0,
            "pitch | 30 | pitch | force NRMSE %": 1.5,
            "sim2real | 2 context | NRMSE %": 3.2,
        },
    },
    "f4": {
        "s0_auto_f4": {
            "shape | none | camera | force NRMSE %": 2.0,
            "pitch | 0 | pitch | force NRMSE %": 1.2,
            "pitch | 30 | pitch | force NRMSE %": 2.4,
            "sim2real | 2 context | NRMSE %": 3.0,
        }
    },
}
CPU = {
    "default": {
        "s0_auto": {"camera": 2880.0, "pitch": 1200.0},
        "s1_auto": {"camera": 2820.0, "pitch": 1260.0},
    },
    "f4": {"s0_auto_f4": {"camera": 720.0, "pitch": 300.0}},
}


def test_worst_condition_is_the_largest_error_per_predictor():
    w = with_worst(FIGURES["default"]["s0_auto"])
    assert w["pitch | worst | pitch | force NRMSE %"] == 3.0
    assert "shape | worst | camera | force NRMSE %" not in w  # one condition: no worst


def test_budget_table_gives_mean_and_range_over_seeds_and_the_cpu_minutes():
    t = budget_table(FIGURES, CPU)
    r = t.loc[("default", "shape | none | camera | force NRMSE %")]
    assert (r["mean"], r["min"], r["max"], r["n"]) == (pytest.approx(2.0), 1.9, 2.1, 2)
    # the worst pitch of each seed, then over the seeds: 3.0 (seed 0) and 2.0 (seed 1)
    w = t.loc[("default", "pitch | worst | pitch | force NRMSE %")]
    assert (w["min"], w["max"]) == (2.0, 3.0)
    c = t.loc[("default", "train | all models | CPU min")]
    assert (c["min"], c["max"]) == (pytest.approx(68.0), pytest.approx(68.0))
    assert t.loc[("f4", "train | camera | CPU min"), "mean"] == pytest.approx(12.0)
    assert t.loc[("f4", "train | all models | CPU min"), "n"] == 1


def test_write_budget_round_trips_through_json(tmp_path):
    out = {
        k: tmp_path / f"training_budget.{e}"
        for k, e in (("json", "json"), ("csv", "csv"), ("table", "md"), ("figure", "png"))
    }
    write_budget(FIGURES, CPU, {"default": {}, "f4": {"frame_every": 4}}, out, "Test CPU")
    s = json.loads(out["json"].read_text())
    assert s["cpu"] == "Test CPU" and s["points"]["f4"] == {"frame_every": 4}
    f = s["figures"]["sim2real | 2 context | NRMSE %"]
    assert f["f4"] == {"mean": 3.0, "min": 3.0, "max": 3.0, "n": 1}
    assert f["default"]["min"] == 3.2 and f["default"]["max"] == 3.4
    md = out["table"].read_text()
    assert r"| sim2real \| 2 context \| NRMSE % | 3.3 [3.2, 3.4] | 3 |" in md
    assert out["figure"].stat().st_size > 0


def test_cpu_seconds_reads_a_snakemake_benchmark_file(tmp_path):
    p = tmp_path / "b.tsv"
    p.write_text("s\th:m:s\tmax_rss\tcpu_time\n3156.76\t0:52:36\t1759.29\t2866.59\n")
    assert cpu_seconds(p) == 2866.59
