"""Every rule asks a cluster for memory and time; the run comparison catches differences."""
import importlib.util
import json
import sys
from pathlib import Path

import numpy as np
import pytest

ROOT = Path(__file__).resolve().parents[1]
SLURM = ROOT / "workflow" / "profiles" / "slurm"


def load(name):
    spec = importlib.util.spec_from_file_location(name, SLURM / f"{name}.py")
    mod = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(mod)
    return mod


def test_every_rule_declares_mem_mb_and_runtime():
    res = load("resources")
    blocks = res.rule_blocks()
    assert len(blocks) > 30 and "fea_scene" in blocks and "manuscript" in blocks
    missing = [n for n, t in blocks.items()
               if set(res.declared(t)) != {"mem_mb", "runtime"} or min(res.declared(t).values()) < 1]
    assert missing == []


def test_measured_resources_from_benchmark_files(tmp_path):
    res = load("resources")
    bench = tmp_path / "benchmarks" / "fea"
    bench.mkdir(parents=True)
    head = "s\th:m:s\tmax_rss\tmax_vms\tmax_uss\tmax_pss\tio_in\tio_out\tmean_load\tcpu_time\n"
    (bench / "a_steel_h20.tsv").write_text(head + "11.1\t0:00:11\t268.7\t1\t1\t1\t0\t0\t0\t7\n")
    (bench / "b_steel_h30.tsv").write_text(head + "95.0\t0:01:35\t401.0\t1\t1\t1\t0\t0\t0\t90\n")
    got = res.measured(tmp_path, res.rule_blocks())["fea_scene"]
    assert (got["jobs"], got["mem_mb"], got["runtime"]) == (2, 700, 4)  # 601.5 -> 700; 190 s -> 4


def make_run(root, fx, timing):
    (root / "results" / "fea").mkdir(parents=True)
    (root / "results" / "logs").mkdir()
    (root / "results" / "logs" / "x.log").write_text(str(timing))  # logs are not compared
    (root / "results" / "fea" / "forces.csv").write_text(f"frame,fx_N,solve_s\n0,{fx!r},{timing}\n")
    (root / "results" / "m.json").write_text(json.dumps({"mae_N": fx, "wall_s": timing}))
    np.savez(root / "results" / "r.npz", u=np.array([fx, 2.0]))


@pytest.mark.parametrize("fx_b, ok", [(1.0 + 1e-12, True), (1.0 + 1e-6, False)])
def test_compare_runs_tolerance_and_timings(tmp_path, capsys, fx_b, ok):
    cmp = load("compare_runs")
    make_run(tmp_path / "a", 1.0, 3.0)
    make_run(tmp_path / "b", fx_b, 4.5)
    assert cmp.main([str(tmp_path / "a"), str(tmp_path / "b")]) == (0 if ok else 1)
    out = capsys.readouterr().out
    if ok:  # solve_s and wall_s are timings: listed, not compared
        assert "results/m.json: timings differ: wall_s" in out
        assert "results/fea/forces.csv: timings differ: solve_s" in out
    else:
        assert "MISMATCH results/fea/forces.csv: column fx_N: max |diff| 1e-06" in out
        assert "MISMATCH results/m.json: mae_N: 1.0 vs 1.000001\n" in out
        assert "MISMATCH results/r.npz: u" in out


def test_compare_runs_missing_file(tmp_path, capsys):
    cmp = load("compare_runs")
    make_run(tmp_path / "a", 1.0, 3.0)
    make_run(tmp_path / "b", 1.0, 3.0)
    (tmp_path / "b" / "results" / "r.npz").unlink()
    assert cmp.main([str(tmp_path / "a"), str(tmp_path / "b")]) == 1
    assert f"MISMATCH only in {tmp_path / 'a'}: results/r.npz" in capsys.readouterr().out
