"""The Snakemake DAG on the smoke config: lint, dry run of the full config, a real run."""
import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest
import yaml

from finray.geometry.mesh import TriMesh, quality

ROOT = Path(__file__).resolve().parents[1]
SNAKEMAKE = [sys.executable, "-m", "snakemake", "-s", str(ROOT / "Snakefile")]


def snakemake(*args, cwd=ROOT):
    return subprocess.run([*SNAKEMAKE, *args], cwd=cwd, capture_output=True, text=True)


def test_dry_run_full_config_plans_every_object_and_height():
    r = snakemake("-n", "--cores", "2", "--quiet", "rules")
    assert r.returncode == 0, r.stderr
    full = yaml.safe_load((ROOT / "config" / "config.yaml").read_text())
    n_objects = len(full["objects"]) * len(full["heights_mm"])
    r = snakemake("-n", "--cores", "2", "--forceall", "--summary")
    assert r.returncode == 0, r.stderr
    planned = [line.split("\t")[0] for line in r.stdout.splitlines()]
    for name in full["objects"]:
        for h in full["heights_mm"]:
            assert f"results/geometry/objects/{name}_h{h:g}.npz" in planned
    assert sum("results/geometry/objects/" in p and p.endswith(".npz") for p in planned) == n_objects


def test_bad_config_stops_before_any_job(tmp_path):
    bad = tmp_path / "bad.yaml"
    bad.write_text("objects:\n  c: {type: circle, diameter_mm: 5}\nfinger: {base_thickness_mm: -2}\n")
    r = snakemake("-n", "--configfile", str(bad))
    assert r.returncode != 0
    assert "finger.base_thickness_mm" in r.stderr


@pytest.fixture(scope="module")
def smoke_run(tmp_path_factory):
    work = tmp_path_factory.mktemp("smoke")
    r = snakemake("--cores", "2", "--configfile", str(ROOT / "config" / "smoke.yaml"),
                  "--directory", str(work), cwd=work)
    assert r.returncode == 0, r.stderr[-3000:]
    return work


def test_smoke_geometry_outputs(smoke_run):  # noqa: D103
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
    import json

    cfg = yaml.safe_load((ROOT / "config" / "smoke.yaml").read_text())
    n = 0
    for name, spec in cfg["objects"].items():
        for mat in spec.get("materials", ["steel"]):
            for h in cfg["heights_mm"]:
                d = smoke_run / "results" / "fea" / name / mat / f"h{h:g}"
                s = json.loads((d / "summary.json").read_text())
                assert s["converged"] and s["min_gap_mm"] > 0  # never interpenetrates
                assert s["equilibrium_max_rel_error"] < 5e-3  # object force = base reaction
                forces = np.loadtxt(d / "forces.csv", delimiter=",", skiprows=1)
                assert np.isfinite(forces).all() and forces[-1, 0] == pytest.approx(10.0, abs=1e-4)
                assert forces[-1, 1] > 0  # the finger pushes back
                assert (d / "finger.pvd").is_file()
                n += 1
    assert n == 10


def test_smoke_dataset_and_training(smoke_run):
    import json

    import pandas as pd

    man = pd.read_csv(smoke_run / "results" / "dataset" / "manifest.csv")
    assert set(man.split) == {"train", "shape", "material", "pitch"}
    assert sorted(man[man.split == "pitch"].pitch_deg.unique()) == [0, 5, 10, 15, 20, 25, 30]
    assert man.fx_N.notna().all()
    for model in ("plain", "occlusion"):
        d = smoke_run / "results" / "train" / model
        hist = json.loads((d / "history.json").read_text())
        assert len(hist["train_loss"]) == 2 and np.isfinite(hist["train_loss"]).all()
        assert (d / "model.ts").is_file() and (d / "curves.png").is_file()


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
