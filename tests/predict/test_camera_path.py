"""The camera path of an experiment: rendered full frames through the Predictor, scored
against the FEA beside the shard path on the same frames (finray.evaluate.camera)."""

import json

import numpy as np
import pandas as pd
import pytest

from finray.evaluate.camera import camera_test_set, rendered_subset
from finray.evaluate.experiments import run_experiment
from finray.evaluate.metrics import force_metrics
from finray.evaluate.predictions import load_test_set
from finray.evaluate.summary import camera_agreement, experiment_summary
from finray.predict import Predictor
from finray.render.imageio import read_png, write_png

SIZE = (64, 32)  # the size of the scene fixture (conftest.py)


def test_camera_rows_beside_the_shard_rows(scene, tmp_path):
    out = tmp_path / "shape"
    m = run_experiment(
        out,
        scene["shards"],
        SIZE,
        {"plain": str(scene["model"])},
        group_col="object",
        render_indices=scene["indices"],
        log=lambda *_: None,
    )
    allrows = m[m["group"] == "all"].set_index(["path", "frames"])
    assert set(allrows.index) == {("shard", "all"), ("shard", "rendered"), ("camera", "rendered")}
    assert allrows.loc[("shard", "all"), "n"] == 10
    assert allrows.loc[("camera", "rendered"), "n"] == 6  # 3 files per view, 2 views
    assert allrows.loc[("shard", "rendered"), "n"] == 6
    # at pitch 0 the base-anchored crop is the shards' window: the same inputs, same forces
    for col in ("mse_N2", "nrmse_pct", "stress_mse_log"):
        assert allrows.loc[("camera", "rendered"), col] == pytest.approx(
            allrows.loc[("shard", "rendered"), col], rel=1e-5, abs=1e-9
        )
    frames = pd.read_csv(out / "frames.csv")
    cam = frames[frames["path"] == "camera"]
    assert sorted(cam["frame"].unique()) == [0, 2, 4]
    assert len(frames[frames["path"] == "shard"]) == 10
    summary = json.loads((out / "metrics.json").read_text())["all"]
    assert {"plain", "plain/camera", "plain/shard_rendered"} <= set(summary)
    assert summary["plain/camera"]["n"] == 6
    s = experiment_summary(out)["all"]["plain"]
    assert s["all"]["n"] == 10 and s["camera"]["all"]["n"] == 6
    assert s["camera"]["groups"]["ellipse_16x9"]["n"] == 6
    agree = camera_agreement(out)["all"]["plain"]
    assert agree["n_frames"] == 6 and agree["max_abs_diff_N"] < 1e-4
    assert set(camera_agreement(out)["all"]) == {"plain"}  # fx only, not pred_fy_*
    # the force vector: fy and the magnitude scored from frames.csv's columns
    shard = frames[frames["path"] == "shard"]
    want = force_metrics(shard["fy_N"], shard["pred_fy_plain"])
    assert s["all"]["fy_mse_N2"] == pytest.approx(want["mse_N2"])
    mag = force_metrics(
        np.hypot(shard["fx_N"], shard["fy_N"]),
        np.hypot(shard["pred_plain"], shard["pred_fy_plain"]),
    )
    assert s["all"]["mag_nrmse_pct"] == pytest.approx(mag["nrmse_pct"])
    assert s["camera"]["all"]["fy_rmse_N"] >= 0


def test_camera_path_reads_the_rendered_images(scene, tmp_path):
    """A changed PNG changes the camera path's input and force, not the shard's: the
    camera rows do come from the images, through the Predictor's own crop."""
    import shutil

    d = tmp_path / "h20" / "p0"
    shutil.copytree(scene["indices"][0].parent, d)
    index = json.loads((d / "index.json").read_text())
    name = index["frames"][-1]["image"]
    rgb = read_png(d / name)
    # the same frame seen by another camera: 37 px more background above and 11 px
    # left, 5 px below the base (the crop follows the finger)
    bg = rgb[0, 0]
    big = np.broadcast_to(bg, (rgb.shape[0] + 42, rgb.shape[1] + 11, 3)).copy()
    big[37 : 37 + rgb.shape[0], 11:] = rgb
    write_png(d / name, big)
    p = Predictor(scene["model"], backend="torchscript")
    moved, _ = camera_test_set([d / "index.json"], p)
    orig, _ = camera_test_set([scene["indices"][0]], p)
    np.testing.assert_array_equal(moved["images"], orig["images"])
    # a frame with the top half of the finger erased
    rgb_cut = rgb.copy()
    rgb_cut[: rgb.shape[0] // 2] = bg
    write_png(d / name, rgb_cut)
    cut, table = camera_test_set([d / "index.json"], p)
    assert (cut["images"][-1] != orig["images"][-1]).any()
    np.testing.assert_array_equal(cut["images"][:-1], orig["images"][:-1])
    shard_arrays, shard_table = load_test_set(scene["shards"][:1], SIZE)
    sel = rendered_subset(shard_table, table)
    np.testing.assert_array_equal(shard_arrays["images"][sel][:-1], cut["images"][:-1])


def test_renders_and_shards_of_different_runs_are_refused(scene):
    p = Predictor(scene["model"], backend="torchscript")
    _, table = camera_test_set(scene["indices"], p)
    _, shard_table = load_test_set(scene["shards"], SIZE)
    other = shard_table.copy()
    other.loc[other["frame"] == 4, "fx_N"] += 0.5
    with pytest.raises(
        ValueError,
        match=r"FEA force of frame 4 of ellipse_16x9_steel_h\d+_p0 "
        r"differs .* by 0\.5 N",
    ):
        rendered_subset(other, table)
    with pytest.raises(
        ValueError, match="rendered frame 0 of ellipse_16x9_steel_h20_p0 is not in the test shards"
    ):
        rendered_subset(shard_table[shard_table["height_mm"] == 30.0], table)


def test_a_frame_without_finger_names_its_file(scene, tmp_path):
    import shutil

    d = tmp_path / "p0"
    shutil.copytree(scene["indices"][0].parent, d)
    name = json.loads((d / "index.json").read_text())["frames"][0]["image"]
    write_png(d / name, np.zeros((336, 160, 3), np.uint8))
    with pytest.raises(ValueError, match=rf"{name}: no finger found"):
        camera_test_set([d / "index.json"], Predictor(scene["model"], backend="torchscript"))
