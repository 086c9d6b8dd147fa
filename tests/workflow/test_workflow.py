"""The Snakemake DAG on the smoke config: lint, dry run of the full config, a real run."""

import json
import re
import subprocess
import sys

import numpy as np
import pytest
import yaml

from finray.geometry.mesh import TriMesh, quality

from helpers import DATA, ROOT

pytestmark = [pytest.mark.slow, pytest.mark.workflow]  # not in `pytest -m "not slow"`

SNAKEMAKE = [sys.executable, "-m", "snakemake", "-s", str(ROOT / "workflow" / "Snakefile")]


def snakemake(*args, cwd=ROOT):
    return subprocess.run([*SNAKEMAKE, *args], cwd=cwd, capture_output=True, text=True)


def test_dry_run_full_config_plans_every_object_and_height():
    r = snakemake("-n", "--cores", "2", "--quiet", "rules")
    assert r.returncode == 0, r.stderr
    from finray.config import load_config, object_heights

    full = load_config(ROOT / "config" / "config.yaml")
    # every object at the paper's heights and at the face heights of its split
    n_objects = sum(len(object_heights(full, name)) for name in full["objects"])
    assert n_objects > len(full["objects"]) * len(full["heights_mm"])
    r = snakemake("-n", "--cores", "2", "--forceall", "--summary")
    assert r.returncode == 0, r.stderr
    planned = [line.split("\t")[0] for line in r.stdout.splitlines()]
    for name in full["objects"]:
        for h in object_heights(full, name):
            assert f"results/geometry/objects/{name}_h{h:g}.npz" in planned
    assert (
        sum("results/geometry/objects/" in p and p.endswith(".npz") for p in planned) == n_objects
    )


def test_bad_config_stops_before_any_job(tmp_path):
    bad = tmp_path / "bad.yaml"
    bad.write_text(
        "objects:\n  c: {type: circle, diameter_mm: 5}\nfinger: {base_thickness_mm: -2}\n"
    )
    r = snakemake("-n", "--configfile", str(bad))
    assert r.returncode != 0
    assert "finger.base_thickness_mm" in r.stderr


@pytest.fixture(scope="module")
def smoke_run(tmp_path_factory):
    work = tmp_path_factory.mktemp("smoke")
    r = snakemake(
        "--cores",
        "2",
        "--configfile",
        str(ROOT / "config" / "smoke.yaml"),
        "--directory",
        str(work),
        cwd=work,
    )
    assert r.returncode == 0, r.stderr[-3000:]
    return work


def test_smoke_geometry_outputs(smoke_run):
    cfg = yaml.safe_load((ROOT / "config" / "smoke.yaml").read_text())
    geo = smoke_run / "results" / "geometry"
    finger = TriMesh.load(geo / "finger.npz")
    q = quality(finger)
    assert q["min_angle_deg"] >= 20 and q["n_inverted"] == 0
    for name, spec in cfg["objects"].items():
        for h in cfg["heights_mm"]:
            obj = TriMesh.load(geo / "objects" / f"{name}_h{h:g}.npz")
            assert obj.meta["reference_point_mm"][1] == pytest.approx(h)
            meshed = len(obj.triangles) > 0
            assert meshed == (spec.get("materials", ["steel"]) != ["steel"])
            assert np.isfinite(obj.points).all()
    assert (geo / "gallery.pdf").stat().st_size > 0
    assert (geo / "finger_surface.ply").stat().st_size > 0


def test_smoke_fea_outputs(smoke_run):
    cfg = yaml.safe_load((ROOT / "config" / "smoke.yaml").read_text())
    n = 0
    for name, spec in cfg["objects"].items():
        for mat in spec.get("materials", ["steel"]):
            for h in cfg["heights_mm"]:
                d = smoke_run / "results" / "fea" / name / mat / f"h{h:g}"
                s = json.loads((d / "summary.json").read_text())
                assert s["converged"] and s["min_gap_mm"] > 0  # never interpenetrates
                assert s["equilibrium_max_rel_error"] <= s["equilibrium_tol"]  # force = reaction
                assert s["residual_max_rel"] <= s["residual_tol"]  # Newton's force balance
                assert s["line_search_failures"] >= 0 and s["gradient_fallbacks"] >= 0
                forces = np.loadtxt(d / "forces.csv", delimiter=",", skiprows=1)
                assert np.isfinite(forces).all() and forces[-1, 0] == pytest.approx(10.0, abs=1e-4)
                assert forces[-1, 1] > 0  # the finger pushes back
                assert (d / "finger.pvd").is_file()
                n += 1
    assert n == 10
    assert not (smoke_run / "results" / "fea" / "failed").exists()  # no failure reports


def test_smoke_dataset_and_training(smoke_run):
    import pandas as pd

    man = pd.read_csv(smoke_run / "results" / "dataset" / "manifest.csv")
    assert set(man.split) == {"train", "shape", "material", "pitch"}
    assert sorted(man[man.split == "pitch"].pitch_deg.unique()) == [0, 5, 10, 15, 20, 25, 30]
    assert man.fx_N.notna().all()
    # the FEA's contact heights reach the shards (NaN at rest), on the finger's face
    assert man.contact_y_mm.notna().any() and man.contact_y_mm.dropna().between(0, 85).all()
    # train.epochs is 2; the occlusion model is fine-tuned from plain's weights for its own 1
    for model, epochs, start in (
        ("plain", 2, None),
        ("occlusion", 1, "plain"),
        ("camera", 2, None),
    ):
        d = smoke_run / "results" / "train" / model
        hist = json.loads((d / "history.json").read_text())
        assert len(hist["train_loss"]) == epochs and np.isfinite(hist["train_loss"]).all()
        # the contact head (train.contact_weight's default) trained on pushed frames
        assert hist["n_contact_frames"] > 0 and np.isfinite(hist["val_contact_rmse_mm"]).all()
        assert json.loads((d / "model.ts.json").read_text())["contact"] is True
        assert hist["start_from"] == (None if start is None else f"results/train/{start}/model.pt")
        assert (d / "model.ts").is_file() and (d / "curves.png").is_file()


def test_smoke_spread(smoke_run):
    """The spread study on the smoke config's two seeds: its two models (camera, plain)
    retrained per seed, every headline figure per variant, the experiments that compare
    one of them only; the default seed's variant is the run itself
    (training is deterministic), so its figures are the run's own. The training-budget
    study beside it: its default point is the spread's seed 0, its point f2 trains on
    every other frame."""
    r = snakemake(
        "--cores",
        "2",
        "--configfile",
        str(ROOT / "config" / "smoke.yaml"),
        "--directory",
        str(smoke_run),
        "results/evaluate/spread/summary.json",
        "results/benchmarks/training_budget.md",
        "results/evaluate/spread/rigs/summary.json",
        cwd=smoke_run,
    )
    assert r.returncode == 0, r.stderr[-3000:]
    spread = smoke_run / "results" / "evaluate" / "spread"
    s = json.loads((spread / "summary.json").read_text())
    assert s["variants"] == ["s0_auto", "s1_auto"] and s["default"] == "s0_auto"
    run = json.loads((smoke_run / "results" / "summary.json").read_text())
    f = s["figures"]
    for model in ("plain", "camera"):
        shape = f[f"shape | all | {model} | force NRMSE %"]
        assert shape["s0_auto"] == pytest.approx(
            run["experiments"]["shape"]["all"][model]["all"]["nrmse_pct"]
        )
        assert (
            shape["min"] <= shape["mean"] <= shape["max"] and shape["s1_auto"] != shape["s0_auto"]
        )
    vp = f["viewpoint | 30 | camera | force NRMSE %"]
    assert vp["s0_auto"] == pytest.approx(run["viewpoint"]["nrmse_pct"]["camera"]["30"])
    cov = f["sim2real | 1 context | coverage %"]
    assert cov["s0_auto"] == pytest.approx(run["sim2real"]["by_context"]["1"]["coverage_pct"])
    h = json.loads((spread / "s1_auto" / "train" / "camera" / "history.json").read_text())
    assert h["train_config"]["seed"] == 1 and len(h["val_force_rmse_running_bn_N"]) == 2
    assert r"| sim2real \| 0 context \| NRMSE % |" in (spread / "spread.md").read_text()
    assert (spread / "spread.png").stat().st_size > 1000
    b = json.loads((smoke_run / "results" / "benchmarks" / "training_budget.json").read_text())
    assert b["points"] == {"default": {}, "f2": {"epochs": 1, "frame_every": 2}}
    shape = b["figures"]["shape | all | camera | force NRMSE %"]
    assert shape["default"]["mean"] == pytest.approx(
        f["shape | all | camera | force NRMSE %"]["s0_auto"]
    )
    assert shape["f2"]["n"] == 1 and shape["f2"]["mean"] != shape["default"]["mean"]
    assert sorted(p.name for p in (spread / "s1_auto" / "train").iterdir()) == ["camera", "plain"]
    assert s["runs"]["s1_auto"]["camera"]["precision"] in ("float32", "bfloat16")
    full = json.loads((spread / "s0_auto" / "train" / "plain" / "history.json").read_text())
    half = json.loads((spread / "s0_auto_f2" / "train" / "plain" / "history.json").read_text())
    assert (half["frame_every"], len(half["epoch"])) == (2, 1)
    assert full["n_train"] / 2 <= half["n_train"] <= full["n_train"] / 2 + 10  # ceil per scene
    cpu = b["figures"]["train | all models | CPU min"]
    assert 0 < cpu["f2"]["mean"] and 0 < cpu["default"]["mean"]
    assert "worst" in "".join(b["figures"])  # the worst pitch and occlusion level
    assert (smoke_run / "results" / "benchmarks" / "training_budget.png").stat().st_size > 1000
    # the rigs over the variants: seed 0's are the run's own rigs' figures
    rigs = json.loads((spread / "rigs" / "summary.json").read_text())
    own = json.loads(
        (smoke_run / "results" / "evaluate" / "sim2real" / "rigs" / "summary.json").read_text()
    )
    assert rigs["emulated"] and rigs["acceptance"]["rigs"] == own["rigs"] == ["default", "rig1"]
    for k, e in enumerate(own["per_rig"]["rig1"]["nrmse_pct"]):
        got = rigs["figures"][f"sim2real rigs | rig1 | {k} context | NRMSE %"]
        assert got["s0_auto"] == pytest.approx(e) and got["min"] <= got["mean"] <= got["max"]
    assert rigs["acceptance"]["per_rig"]["rig1"]["n"] == 2
    assert "| rig1 |" in (spread / "rigs" / "rigs.md").read_text()


def test_smoke_renders_are_pixel_aligned(smoke_run):
    """Every front-view frame of the smoke run: the segmented camera image and the
    stress map's support (the pixels it is defined on: finger coverage >= 1/2; the
    stress itself is 0 in the undeformed frame) cover the same pixels (IoU >= 0.98)."""
    from finray.dataset import segment
    from finray.render.scene import load_render_index, read_render_frame

    dirs = sorted((smoke_run / "results" / "render").glob("*/*/*/p0"))
    assert dirs
    worst = 1.0
    for d in dirs:
        index = load_render_index(d)
        for k in range(index["n_frames"]):
            if index["frames"][k]["image"] is None:  # no files (render.files_per_scene)
                continue
            rgb, maps = read_render_frame(d, k, index)
            mask = segment(rgb)
            support = maps["coverage"] >= 0.5
            assert not (maps["stress"][~support]).any()  # no stress outside the support
            iou = (mask & support).sum() / (mask | support).sum()
            worst = min(worst, iou)
    assert worst >= 0.98, worst
    # every frame, with or without files: the shards record the lowest IoU
    from finray.dataset import load_shard

    shards = sorted((smoke_run / "results" / "dataset" / "shards").glob("*/*/*/p0.npz"))
    assert len(shards) == len(dirs)
    for s in shards:
        assert load_shard(s)["meta"]["support_iou_min"] >= 0.98, s


def test_smoke_evaluation_summary_and_paper(smoke_run):
    """Every experiment has its table, figure and headline numbers; the manuscript
    carries the numbers of results/summary.json and no unfilled placeholder."""

    s = json.loads((smoke_run / "results" / "summary.json").read_text())
    exps = s["experiments"]
    assert set(exps) == {"shape", "material", "occlusion", "pitch", "viewpoint"}
    shape = exps["shape"]["all"]["plain"]["all"]
    assert shape["mse_N2"] == pytest.approx(shape["rmse_N"] ** 2, rel=1e-6)
    assert shape["nrmse_pct"] == pytest.approx(
        100 * shape["rmse_N"] / shape["max_true_N"], rel=1e-6
    )
    assert shape["r2"] <= 1 and np.isfinite(shape["stress_mse_log"]) and -1 <= shape["ssim"] <= 1
    assert set(exps["shape"]["all"]) == {"plain", "camera", "occlusion", "pitch", "baseline"}
    assert shape["fy_nrmse_pct"] > 0 and shape["mag_nrmse_pct"] > 0  # the force vector
    # the viewpoint experiment: perspective renders of the held-out shape, three models
    vp = s["viewpoint"]
    assert set(vp["nrmse_pct"]) == {"plain", "pitch", "camera", "baseline"}
    assert [float(p) for p in vp["nrmse_pct"]["camera"]] == [0, 5, 10, 15, 20, 25, 30]
    assert (
        vp["distances_mm"] == [200.0, 350.0] and vp["n_frames_per_pitch"] == 2 * 2 * 2
    )  # heights, distances, frames
    assert set(s["camera_model"]) == {"shape", "material"}
    assert list(exps["occlusion"]) == ["none", "low", "medium", "high"]
    assert set(exps["occlusion"]["high"]) == {"plain", "occlusion", "baseline"}
    assert [float(p) for p in exps["pitch"]] == [0, 5, 10, 15, 20, 25, 30]
    # the camera model is scored on the pitch series beside the plain and pitch models
    assert all(set(c) == {"plain", "pitch", "camera", "baseline"} for c in exps["pitch"].values())
    assert set(exps["material"]["all"]["plain"]["groups"]) == {"steel", "neoprene"}
    # the camera path (rendered frames through the Predictor) beside the shard path
    import pandas as pd

    for exp in ("shape", "material"):
        m = pd.read_csv(smoke_run / "results" / "evaluate" / exp / "metrics.csv")
        cam = m[(m["path"] == "camera") & (m["group"] == "all")].set_index("predictor")
        same = m[
            (m["path"] == "shard") & (m["frames"] == "rendered") & (m["group"] == "all")
        ].set_index("predictor")
        models = (
            {"plain", "camera", "occlusion", "pitch"} if exp == "shape" else {"plain", "camera"}
        )
        assert set(cam.index) == models | {"baseline"} and (cam["n"] > 0).all()
        assert (cam["n"] == same["n"]).all()
        assert exps[exp]["all"]["plain"]["camera"]["all"]["n"] == cam.loc["plain", "n"]
        assert s["camera_path"][exp]["all"]["plain"]["n_frames"] == cam.loc["plain", "n"]
    assert set(s["speed"]["stages"]) >= {"geometry", "fea", "render", "train", "evaluate"}
    # sim-to-real on the one emulated take: its halves stand in for objects (0 and 1 context)
    r = s["sim2real"]
    assert set(r["by_context"]) == {"0", "1"} and r["emulated"] is True
    assert [f["context_objects"] for f in r["fits"]] == [0, 1, 1]
    noise = {"log_sigma_N", "log_rho", "log_kappa", "log_nu"}
    law = {"relax_fast", "relax_slow", "softening"}
    for f in r["fits"]:
        d = f["diagnostics"]
        # gain and offset held at 1 and 0 (their prior sd 0): the noise terms are sampled,
        # and with context takes (their times) the print's law; without, the simulation's
        # frames have no history
        assert d["steps"] >= d["walkers"]
        assert set(d["tau_steps"]) == (noise | law if f["context_objects"] else noise)
    # the takes' phases apart (the one take's first cycle and its second)
    phases = r["by_context"]["1"]["per_phase"]
    assert {"loading", "hold", "unloading", "second cycle"} <= set(phases)
    assert all(m["n"] > 0 and np.isfinite(m["nrmse_pct"]) for m in phases.values())
    # the no-context intervals' rig gain: the rig prior's FEA (one scene in the smoke config)
    prior = json.loads(
        (
            smoke_run / "results" / "evaluate" / "sim2real" / "rig_prior" / "rig_prior.json"
        ).read_text()
    )
    assert set(prior["gains"]) == {"circle_d10_h20"} and len(prior["gains"]["circle_d10_h20"]) == 5
    assert (
        prior["gains"]["circle_d10_h20"]["t0.15"] > prior["gains"]["circle_d10_h20"]["t0.075"] > 1
    )
    assert prior["gains"]["circle_d10_h20"]["mu0.6"] > 1 and prior["gain_log_sd"] > 0
    assert r["config"]["rig_prior"]["gain_log_mean"] == prior["gain_log_mean"]
    m = pd.read_csv(smoke_run / "results" / "evaluate" / "sim2real" / "metrics.csv")
    one = m[(m["context_objects"] == 1) & (m["context"] == "all") & (m["test"] == "all")].iloc[0]
    assert one["n"] == r["by_context"]["1"]["n_frames"] and 0 <= one["coverage_pct"] <= 100
    assert (smoke_run / "results" / "evaluate" / "sim2real" / "corner.pdf").stat().st_size > 1000
    # each frame flagged near_base as finray predict would, the others scored apart
    fr = pd.read_csv(smoke_run / "results" / "evaluate" / "sim2real" / "frames.csv")
    zero = fr[fr["context_objects"] == 0]
    assert {"near_base", "contact_mm"} <= set(fr.columns)
    assert r["by_context"]["0"]["n_near_base"] == int(zero["near_base"].sum())
    ok = r["by_context"]["0"]["unflagged"]
    assert ok["n"] == len(zero) - int(zero["near_base"].sum())
    sub = zero[~zero["near_base"]]
    rmse = np.sqrt(((sub["sensor_N"] - sub["pred_N"]) ** 2).mean())  # frames.csv: 6 digits
    assert ok["rmse_N"] == pytest.approx(rmse, rel=1e-4)
    # sim-to-real on the smoke config's one drawn emulated rig, beside the configured one
    rigs = json.loads(
        (smoke_run / "results" / "evaluate" / "sim2real" / "rigs" / "summary.json").read_text()
    )
    assert rigs["emulated"] and rigs["rigs"] == ["default", "rig1"]
    assert set(rigs["by_context"]) == set(r["by_context"])
    assert "emulated" in rigs["settings"]["rig1"]["camera"]["model"]
    for name in (
        "shape_generalisation",
        "material_generalisation",
        "occlusion",
        "viewpoint",
        "speed",
        "sim2real",
        "sim2real_rigs",
    ):
        for ext in ("pdf", "png"):
            assert (smoke_run / "paper" / "figures" / f"{name}.{ext}").stat().st_size > 1000
    html = (smoke_run / "paper" / "manuscript.html").read_text()
    assert "{{" not in html and "{%" not in html
    # the full config's summary (the fixture tests/workflow/test_manuscript.py renders) has the
    # same keys as this one, up to condition, group and stage names: else it is stale
    # (less the nodes of studies, which the default run does not build: STUDY_NODES)
    from finray.evaluate.summary import STUDY_NODES, key_structure

    full = json.loads((DATA / "summary_full.json").read_text())
    full = {k: v for k, v in full.items() if k not in STUDY_NODES}
    assert key_structure({k: v for k, v in s.items() if k not in STUDY_NODES}) == key_structure(
        full
    ), "tests/data/summary_full.json is stale: refresh it with tests/data/make_summary_full.py"
    assert f"{shape['nrmse_pct']:.1f} %" in html
    assert 'src="figures/shape_generalisation.png"' in html
    assert "Through the camera path" in html


def test_smoke_calibrate_and_predict_a_take(smoke_run, tmp_path, capsys):
    """`finray calibrate` on the smoke run's emulated take and `finray predict
    --calibration` on its video: a force with an interval for every frame."""
    import pandas as pd

    from finray.cli import main

    take = smoke_run / "results" / "lab" / "cylinder_h30"
    out = tmp_path / "rig" / "calibration.json"
    rc = main(
        [
            "calibrate",
            str(take),
            "--model",
            str(smoke_run / "results" / "train" / "camera" / "model.pt"),
            "--out",
            str(out),
            "--config",
            str(ROOT / "config" / "smoke.yaml"),
        ]
    )
    cal, printed = json.loads(out.read_text()), capsys.readouterr().out
    # the smoke network barely varies on the take, so the chain may not converge: then
    # calibrate says so and exits 1, writing everything
    assert rc == (0 if cal["diagnostics"]["ok"] else 1), printed[-2000:]
    # gain and offset held at 1 and 0 (the config's priors), and said so
    assert cal["fixed"] == {"gain": 1.0, "offset_N": 0.0}
    assert "gain: 1 (fixed)" in printed and "offset_N: 0 (fixed)" in printed
    assert cal["model"] == "calibration.model.ts" and len(cal["posterior"]["samples"]) > 0
    assert (tmp_path / "rig" / "calibration.corner.png").stat().st_size > 1000
    rc = main(
        [
            "predict",
            "--calibration",
            str(out),
            str(take / "take.mp4"),
            "--out",
            str(tmp_path / "pred"),
            "--force-only",
        ]
    )
    assert rc == 0
    f = pd.read_csv(tmp_path / "pred" / "forces.csv")
    shard = pd.read_csv(smoke_run / "results" / "lab" / "ingest" / "cylinder_h30" / "frames.csv")
    assert (
        len(f) == len(shard)
        and (f["lo_N"] <= f["force_N"]).all()
        and (f["force_N"] <= f["hi_N"]).all()
    )


def test_one_figure_builds_only_what_it_needs(tmp_path):
    """`snakemake paper/figures/shape_generalisation.pdf` plans the models it compares
    (all four on the held-out shapes) and the shape evaluation, not the other
    experiments or figures."""
    r = snakemake(
        "-n",
        "--configfile",
        str(ROOT / "config" / "smoke.yaml"),
        "--directory",
        str(tmp_path),
        "paper/figures/shape_generalisation.pdf",
        cwd=tmp_path,
    )
    assert r.returncode == 0, r.stderr
    jobs = dict(
        line.split()[:2]
        for line in r.stdout.splitlines()
        if len(line.split()) == 2 and line.split()[1].isdigit()
    )
    assert jobs["train_model"] == "4" and jobs["evaluate_experiment"] == "1"
    assert jobs["figure_shape_generalisation"] == "1"
    assert not {"figure_speed", "summary", "manuscript", "fea_pareto"} & set(jobs)


#: each study's own target (studies/<name>/) and rules whose jobs only the studies plan
STUDY_RULES = {
    "fea_cost": {"fea_pareto"},
    "fea_stability": {"fea_stability"},
    "fea_sweep": {"fea_sweep_batch", "fea_sweep_summary"},
    "render_throughput": {"render_benchmark"},
    "network_size": {"train_pareto"},
    "realtime": {"realtime_benchmark"},
    "seeds": {
        "spread_train",
        "spread_experiment",
        "spread_sim2real",
        "spread_summary",
        "spread_rigs",
    },
    "training_budget": {"spread_train", "training_budget"},
}


def _planned(tmp_path, *targets):
    """The rules a dry run of the smoke config plans for ``targets`` (none: rule all)."""
    return set(_planned_jobs(tmp_path, *targets))


def _planned_jobs(tmp_path, *targets) -> dict[str, int]:
    """Jobs per rule of a dry run of the smoke config for ``targets`` (none: rule all)."""
    r = snakemake(
        "-n",
        "--configfile",
        str(ROOT / "config" / "smoke.yaml"),
        "--directory",
        str(tmp_path),
        *targets,
        cwd=tmp_path,
    )
    assert r.returncode == 0, r.stderr
    return {
        line.split()[0]: int(line.split()[1])
        for line in r.stdout.splitlines()
        if len(line.split()) == 2 and line.split()[1].isdigit() and line.split()[0] != "total"
    }


def _rule_paths(directive: str) -> dict[str, str]:
    """Rule -> the first path of its ``directive`` (``benchmark`` or ``log``), read from
    the workflow's and the studies' rule files (``use rule ... as <name>`` included)."""
    files = sorted((ROOT / "workflow").rglob("*.smk")) + sorted((ROOT / "studies").rglob("*.smk"))
    paths, rule, want = {}, None, False
    for f in [*files, ROOT / "workflow" / "Snakefile"]:
        for line in f.read_text().splitlines():
            m = re.match(r"(?:rule|checkpoint) (\w+)|use rule \w+ .*as (\w+)", line)
            if m:
                rule, want = m.group(1) or m.group(2), False
            elif re.match(rf"\s+{directive}:", line):
                want = True
            elif want and line.strip():
                paths.setdefault(rule, line.strip().rstrip(","))
                want = False
    return paths


def _benchmarked_rules() -> set[str]:
    """The rules with a ``benchmark:`` directive (read from the rule files)."""
    return set(_rule_paths("benchmark"))


def test_every_benchmarked_job_logs_beside_its_benchmark_file():
    """A job's CPU time is its log's last line (finray.logs.log_to), found from its
    benchmark file's path (finray.benchmarks.timing.benchmark_log): the two mirror each
    other under results/benchmarks and results/logs."""
    bench, logs = _rule_paths("benchmark"), _rule_paths("log")
    assert len(bench) > 20
    for rule, path in bench.items():
        expected = path.replace("/benchmarks/", "/logs/", 1).replace(".tsv", ".log")
        assert logs.get(rule) == expected, rule


def test_the_speed_job_waits_for_every_benchmarked_job(tmp_path):
    """speed.json counts the DAG's benchmark files: every benchmarked job of the product
    is upstream of it, so its count does not depend on the order the scheduler picks."""
    bench = _benchmarked_rules()
    assert {"fea_scene", "train_model", "lab_take", "sim2real"} <= bench
    every = {r: n for r, n in _planned_jobs(tmp_path).items() if r in bench}
    speed = _planned_jobs(tmp_path, "results/evaluate/speed/speed.json")
    assert every == {r: n for r, n in speed.items() if r in bench}


def test_default_run_plans_no_study_and_each_study_has_its_target(tmp_path):
    """`snakemake` builds the product (the experiments, the models, the manuscript) and
    plans no study job; each study's target plans its rules, `studies` all of them."""
    every = set().union(*STUDY_RULES.values())
    product = _planned(tmp_path)
    assert {"train_model", "evaluate_experiment", "summary", "manuscript"} <= product
    assert not every & product
    for name, rules in STUDY_RULES.items():
        assert rules <= _planned(tmp_path, name), name
    assert every <= _planned(tmp_path, "studies")


def test_pitch_augmentation_matches_the_pitched_renders(smoke_run):
    """The pitch augmentation applied to the front-view inputs of the pitch scene gives
    the silhouettes that the 3D renderer draws at that pitch (IoU >= 0.9 per frame;
    without it the pitch-0 silhouette is far off)."""
    import torch

    from finray.dataset import load_shard
    from finray.dataset.pitch import pitch_silhouette
    from finray.train import pitch_geometry

    cfg = yaml.safe_load((ROOT / "config" / "smoke.yaml").read_text())
    from finray.config import validate_config

    cfg = validate_config(cfg, base_dir=ROOT)
    series = sorted((smoke_run / "results" / "dataset" / "shards").glob("*/*/*/p30.npz"))
    assert len(series) == 1
    d0 = load_shard(series[0].with_name("p0.npz"))
    x0 = torch.from_numpy(d0["input_128x64"][:, None].astype(np.float32) / 255.0)
    geo = pitch_geometry(cfg["dataset"], cfg["render"], 128, cfg["finger"]["extrusion_mm"])
    for pitch in (10, 30):
        true = load_shard(series[0].with_name(f"p{pitch}.npz"))["input_128x64"] >= 128
        aug = (
            pitch_silhouette(
                x0,
                torch.full((len(x0),), float(pitch)),
                geo["mm_per_px"],
                geo["pitch_centre_row"],
                geo["extrusion_mm"],
            )[:, 0].numpy()
            >= 0.5
        )
        iou = (aug & true).sum((1, 2)) / (aug | true).sum((1, 2))
        front = d0["input_128x64"] >= 128
        iou0 = (front & true).sum((1, 2)) / (front | true).sum((1, 2))
        assert iou.min() >= 0.9 and iou0.mean() < 0.8, (pitch, iou.min(), iou0.mean())


def test_an_interrupted_run_resumes_with_the_readme_command(tmp_path):
    """Ctrl-C in the middle of a job, then the README's `snakemake --cores 2` again: the
    default profile (workflow/profiles/default, copied verbatim beside a one-rule
    Snakefile that ends the rate limit's timers as the workflow does) is picked up and its
    rerun-incomplete reruns the interrupted job."""
    import os
    import shutil
    import signal
    import time

    wf = tmp_path / "workflow"
    shutil.copytree(ROOT / "workflow" / "profiles" / "default", wf / "profiles" / "default")
    (wf / "Snakefile").write_text(
        "from finray.scheduler_timers import end_timers_at_exit\n\nend_timers_at_exit()\n\n"
        'rule a:\n    output: "a.txt"\n'
        '    shell: "echo start > {output}; sleep ${{TOY_SLEEP:-0}}; echo done >> {output}"\n'
    )
    cmd = [sys.executable, "-m", "snakemake", "--cores", "2"]
    first = subprocess.Popen(  # in its own process group, as a terminal's job is
        cmd,
        cwd=tmp_path,
        env={**os.environ, "TOY_SLEEP": "60"},
        stderr=subprocess.PIPE,
        text=True,
        start_new_session=True,
        # a pytest-xdist worker ignores SIGINT, and a child inherits that
        preexec_fn=lambda: signal.signal(signal.SIGINT, signal.SIG_DFL),
    )
    for _ in range(600):  # the job has started once its output exists
        if (tmp_path / "a.txt").exists():
            break
        time.sleep(0.1)
    os.killpg(first.pid, signal.SIGINT)  # Ctrl-C: the signal goes to the whole group
    first.communicate(timeout=60)
    assert first.returncode != 0 and (tmp_path / "a.txt").read_text() == "start\n"
    again = subprocess.run(cmd, cwd=tmp_path, capture_output=True, text=True)
    assert again.returncode == 0, again.stderr[-2000:]
    assert "workflow specific profile workflow/profiles/default" in again.stderr
    assert (tmp_path / "a.txt").read_text() == "start\ndone\n"
