"""Every rule asks a cluster for memory and time; the run comparison catches differences."""

import importlib.util
import json

import numpy as np
import pytest

from helpers import ROOT

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
    missing = [
        n
        for n, t in blocks.items()
        if set(res.declared(t)) != {"mem_mb", "runtime"} or min(res.declared(t).values()) < 1
    ]
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


def _pair(tmp_path, name, a, b):
    for side, text in (("a", a), ("b", b)):
        (tmp_path / side / "results").mkdir(parents=True, exist_ok=True)
        (tmp_path / side / "results" / name).write_text(text)
    return [str(tmp_path / "a"), str(tmp_path / "b")]


MD = "| case | fx (N) | job time (s) | FEA s/scene |\n|---|--:|--:|--:|\n| a | {fx} | {t} | {t} |\n"
HTML = (
    "<table>\n<thead>\n<tr>\n<th>case</th>\n<th>fx (N)</th>\n<th>wall (s)</th>\n</tr>\n</thead>\n"
    "<tbody>\n<tr>\n<td>a</td>\n<td>{fx}</td>\n<td>{t}</td>\n</tr>\n</tbody>\n</table>\n"
)


@pytest.mark.parametrize("template", [MD, HTML])
def test_compare_runs_masks_timing_columns_only(tmp_path, capsys, template):
    """A table's timing columns may differ (padding too); its force column may not."""
    cmp = load("compare_runs")
    name = "t.md" if template is MD else "t.html"
    args = _pair(
        tmp_path, name, template.format(fx=8.241, t=10.84), template.format(fx=8.241, t=7.4)
    )
    assert cmp.main(args) == 0
    args = _pair(
        tmp_path / "2", name, template.format(fx=8.241, t=10.84), template.format(fx=8.242, t=10.84)
    )
    assert cmp.main(args) == 1 and f"MISMATCH results/{name}" in capsys.readouterr().out


def test_compare_runs_masks_numbers_with_a_time_unit(tmp_path, capsys):
    cmp = load("compare_runs")
    assert (
        cmp.main(
            _pair(
                tmp_path, "m.md", "the FEA takes 10.9 s, 8.24 N\n", "the FEA takes 9.7 s, 8.24 N\n"
            )
        )
        == 0
    )
    assert (
        cmp.main(
            _pair(
                tmp_path / "2",
                "m.md",
                "the FEA takes 10.9 s, 8.24 N\n",
                "the FEA takes 10.9 s, 8.25 N\n",
            )
        )
        == 1
    )


def test_compare_runs_checkpoints(tmp_path, capsys):
    """Checkpoints: the weights must be bit-identical, the training's times may differ."""
    import torch

    cmp = load("compare_runs")
    w = {"w": torch.arange(4.0)}
    for side, (ww, t) in {"a": (w, 1.0), "b": (w, 2.0)}.items():
        (tmp_path / side / "results").mkdir(parents=True)
        torch.save(
            {"state_dict": ww, "history": {"wall_time_s": [t], "loss": [0.5]}},
            tmp_path / side / "results" / "model.pt",
        )
    assert cmp.main([str(tmp_path / "a"), str(tmp_path / "b")]) == 0
    torch.save(
        {
            "state_dict": {"w": torch.arange(4.0) + 1e-7},
            "history": {"wall_time_s": [1.0], "loss": [0.5]},
        },
        tmp_path / "b" / "results" / "model.pt",
    )
    assert cmp.main([str(tmp_path / "a"), str(tmp_path / "b")]) == 1
    assert "MISMATCH results/model.pt: .state_dict.w: tensor differs" in capsys.readouterr().out
