"""The spread study's table: each figure's default, mean and range over the variants."""

import json

import numpy as np
import pytest

from finray.sim2real.rigs import rigs_summary, rigs_table
from finray.evaluate.spread import (
    manuscript_rows,
    rig_figures,
    run_figures,
    spread_table,
    write_spread,
    write_spread_rigs,
)

from helpers import DATA


FIGURES = {
    "s0_auto": {
        "shape | none | camera | force NRMSE %": 1.5,
        "sim2real | 2 context | coverage %": 90.0,
    },
    "s1_auto": {
        "shape | none | camera | force NRMSE %": 2.5,
        "sim2real | 2 context | coverage %": 80.0,
    },
    "s2_auto": {"shape | none | camera | force NRMSE %": 2.0},
}


def test_spread_table_gives_default_mean_and_range_per_figure():
    t = spread_table(FIGURES, default="s1_auto")
    r = t.loc["shape | none | camera | force NRMSE %"]
    assert (r["default"], r["mean"], r["min"], r["max"], r["n"]) == (2.5, 2.0, 1.5, 2.5, 3)
    assert r["range"] == pytest.approx(1.0)
    c = t.loc["sim2real | 2 context | coverage %"]  # a figure one variant lacks
    assert (c["mean"], c["n"], c["range"]) == (85.0, 2, 10.0) and np.isnan(c["s2_auto"])
    assert np.isnan(spread_table(FIGURES, default="s9_auto")["default"]).all()


def test_write_spread_round_trips_through_json(tmp_path):
    out = {
        k: tmp_path / f"spread.{e}"
        for k, e in (("json", "json"), ("csv", "csv"), ("table", "md"), ("figure", "png"))
    }
    write_spread(FIGURES, "s0_auto", out)
    s = json.loads(out["json"].read_text())
    assert s["variants"] == list(FIGURES) and s["default"] == "s0_auto"
    f = s["figures"]["sim2real | 2 context | coverage %"]
    assert (f["default"], f["min"], f["max"], f["s2_auto"]) == (90.0, 80.0, 90.0, None)
    # the names' bars escaped: one cell each
    assert (
        r"| shape \| none \| camera \| force NRMSE % | 1.5 | 2 | 1.5 | 2.5 | 1 |"
        in out["table"].read_text()
    )
    assert out["figure"].stat().st_size > 0


def test_run_figures_names_a_finished_runs_summary_as_the_variants():
    run = json.loads((DATA / "summary_full.json").read_text())
    f = run_figures(run)
    assert (
        f["shape | all | camera | force NRMSE %"]
        == run["experiments"]["shape"]["all"]["camera"]["all"]["nrmse_pct"]
    )
    assert (
        f["viewpoint | 30 | camera | force NRMSE %"]
        == run["experiments"]["viewpoint"]["30"]["camera"]["all"]["nrmse_pct"]
    )
    assert (
        f["sim2real | 2 context | coverage %"] == run["sim2real"]["by_context"]["2"]["coverage_pct"]
    )
    assert not any(k.startswith("train |") for k in f)  # no histories in a summary


def test_manuscript_rows_take_each_variants_worst_pitch_before_the_range(tmp_path):
    """The viewpoint row: each variant's worst pitch first (s0: 4 at 30 deg, s1: 3 at
    0 deg), then the mean and range over the variants; a figure no variant has is no row."""
    figures = {
        "s0_auto": {
            "viewpoint | 0 | camera | force NRMSE %": 2.0,
            "viewpoint | 30 | camera | force NRMSE %": 4.0,
            "shape | all | camera | force NRMSE %": 1.0,
            "sim2real | 2 context | coverage %": 90.0,
        },
        "s1_fp32": {
            "viewpoint | 0 | camera | force NRMSE %": 3.0,
            "viewpoint | 30 | camera | force NRMSE %": 2.5,
            "shape | all | camera | force NRMSE %": 2.0,
            "sim2real | 2 context | coverage %": 86.0,
        },
    }
    out = {
        k: tmp_path / f"spread.{e}"
        for k, e in (("json", "json"), ("csv", "csv"), ("table", "md"), ("figure", "png"))
    }
    runs = {"s0_auto": {"camera": {"precision": "bfloat16", "device": "cpu (Zen 4)", "cpu": "x"}}}
    write_spread(figures, "s0_auto", out, runs=runs)
    s = json.loads(out["json"].read_text())
    assert s["runs"] == runs
    rows = {r["label"]: r for r in manuscript_rows(s)}
    vp = rows["camera: viewpoint, worst pitch, force NRMSE %"]
    assert (vp["default"], vp["min"], vp["max"], vp["mean"], vp["n"]) == (4.0, 3.0, 4.0, 3.5, 2)
    assert rows["camera: held-out shapes, force NRMSE %"]["range"] == pytest.approx(1.0)
    assert rows["sim-to-real, 2 context objects, coverage %"]["mean"] == pytest.approx(88.0)
    assert not any(r.startswith("plain") for r in rows)


def _rigs(per_rig: dict[str, tuple[list, list, int]]) -> dict:
    """A rigs summary (finray.sim2real.rigs) from rig -> (NRMSE per context count, coverage, frames)."""
    table = rigs_table(
        {
            r: {
                "by_context": {
                    str(k): {"nrmse_pct": e, "mse_N2": 0.0, "coverage_pct": c, "n_frames": n}
                    for k, (e, c) in enumerate(zip(errs, covs))
                }
            }
            for r, (errs, covs, n) in per_rig.items()
        }
    )
    return rigs_summary(table, 0.9)


def test_rig_figures_name_each_rig_and_context_count():
    f = rig_figures(
        _rigs({"default": ([9, 4, 2], [95, 90, 85], 100), "rig1": ([8, 6, 5.5], [99, 80, 70], 300)})
    )
    assert f["sim2real rigs | rig1 | 2 context | NRMSE %"] == 5.5
    assert f["sim2real rigs | default | 0 context | coverage %"] == 95
    assert f["sim2real rigs | pooled | 1 context | coverage %"] == pytest.approx(
        (90 * 100 + 80 * 300) / 400
    )


def test_spread_over_rigs_judges_each_rig_on_the_mean_and_counts_the_variants(tmp_path):
    """rig1 rises from 1 to 2 objects in s0 (5 -> 6) but falls in s1 (7 -> 3): on the mean
    (6 -> 4.5) it falls, in 1 of 2 variants; its mean with 2 objects (4.5) is within 5 %,
    as s1's is and s0's is not."""
    by_variant = {
        "s0_auto": _rigs(
            {"default": ([9, 4, 2], [95, 90, 85], 100), "rig1": ([8, 5, 6], [99, 80, 70], 100)}
        ),
        "s1_auto": _rigs(
            {"default": ([7, 3, 2.5], [85, 80, 95], 100), "rig1": ([9, 7, 3], [91, 90, 90], 100)}
        ),
    }
    out = {
        k: tmp_path / f"rigs.{e}"
        for k, e in (("json", "json"), ("csv", "csv"), ("table", "md"), ("figure", "png"))
    }
    write_spread_rigs(by_variant, "s0_auto", out)
    s = json.loads(out["json"].read_text())
    assert s["emulated"] and s["variants"] == ["s0_auto", "s1_auto"]
    a = s["acceptance"]
    assert a["rigs"] == ["default", "rig1"]
    r = a["per_rig"]["rig1"]
    assert r["nrmse_pct_mean"] == [8.5, 6.0, 4.5] and (r["nrmse_pct_min"], r["nrmse_pct_max"]) == (
        [8, 5, 3],
        [9, 7, 6],
    )
    assert (
        r["falls_on_mean"],
        r["falls_in"],
        r["within_target_on_mean"],
        r["within_target_in"],
        r["n"],
    ) == (True, 1, True, 1, 2)
    assert a["per_rig"]["default"]["falls_in"] == 2
    c = a["coverage_pct_pooled"]["0"]  # s0: (95 + 99) / 2, s1: (85 + 91) / 2
    assert (c["mean"], c["min"], c["max"]) == (92.5, 88.0, 97.0)
    md = out["table"].read_text()
    assert "EMULATED" not in md and "emulated" in md
    assert (
        "| rig1 | 8.50 (8.00-9.00) | 6.00 (5.00-7.00) | 4.50 (3.00-6.00) | yes / 1 of 2 | yes / 1 of 2 |"
        in md
    )
    assert out["figure"].stat().st_size > 0
