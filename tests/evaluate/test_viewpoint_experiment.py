"""The camera views in the shards (a far, square-on camera sees the front view) and the
viewpoint experiment: perspective renders through the predictor, scored against the
shards' forces and canonical stress maps, one condition per pitch, groups by distance."""

import json

import numpy as np
import pandas as pd
import pytest
import torch

from finray.dataset import DatasetParams, load_frames, load_shard, render_shard
from finray.evaluate.experiments import run_viewpoint
from finray.evaluate.metrics import force_metrics
from finray.evaluate.summary import viewpoint_summary
from finray.model import FinRayNet, NetConfig
from finray.render import RenderParams
from finray.render.camera_views import VIEW_COLUMNS, CameraViews
from finray.render.viewpoint import render_viewpoint
from finray.train import export_torchscript
from helpers import PREPROCESS, write_synthetic_fea_result

SIZE = (64, 32)
SCENE = {"object": "ellipse_16x9", "material": "steel", "split": "shape"}
VIEW = {
    "distances_mm": [200.0, 300.0],
    "frames_per_scene": 2,
    "size_px": [240, 426],
    "hfov_deg": 69.4,
    "yaw_deg": 4.0,
    "roll_deg": 1.0,
    "principal_offset_px": [3.5, -2.0],
    "target_mm": [15.0, 40.0],
    "supersample": 2,
}


@pytest.fixture(scope="module")
def scenes(tmp_path_factory):
    """Two heights of the fixture scene: shards (with camera views), viewpoint renders."""
    tmp = tmp_path_factory.mktemp("vp")
    res = write_synthetic_fea_result(tmp / "result.npz", n_frames=5)
    rp = RenderParams(frames_per_scene=5, files_per_scene=0)
    shards, indices = [], []
    for h in (20.0, 30.0):
        sc = dict(SCENE, height_mm=h)
        render_shard(
            res,
            tmp / f"h{h:g}",
            tmp / f"h{h:g}.npz",
            0.0,
            render_params=rp,
            params=DatasetParams(sizes=(SIZE,)),
            scene=sc,
            camera_views=CameraViews(),
        )
        shards.append(tmp / f"h{h:g}.npz")
        index = render_viewpoint(
            res, tmp / "vp" / f"h{h:g}", VIEW, [0.0, 20.0], params=rp, scene=sc
        )
        indices.append(tmp / "vp" / f"h{h:g}" / "index.json")
        assert len(index["frames"]) == 2 * 2 * 2  # distances x pitches x frames
    torch.manual_seed(0)
    net = FinRayNet(
        NetConfig(in_channels=1, base_channels=4, height=SIZE[0], width=SIZE[1], n_forces=2)
    )
    net.set_force_normalisation([3.0, -0.5], [2.0, 0.4])
    net.eval()
    export_torchscript(net, tmp / "model.ts", dict(PREPROCESS, base_band=0.03), ["fx_N", "fy_N"])
    return {
        "tmp": tmp,
        "result": res,
        "shards": shards,
        "indices": indices,
        "model": tmp / "model.ts",
    }


def test_shards_hold_one_replayable_camera_view_per_frame(scenes):
    d = load_shard(scenes["shards"][0])
    assert (
        d["camera_input_64x32"].shape == (5, 64, 32) and d["camera_input_64x32"].dtype == np.uint8
    )
    assert d["meta"]["camera_view_columns"] == list(VIEW_COLUMNS)
    sid = d["meta"]["scene"]["scene_id"]
    for k in range(5):  # the stored view is the one the seed gives
        np.testing.assert_array_equal(d["camera_view"][k], CameraViews().sample(sid, k)[1])
    a, _ = load_frames([scenes["shards"][0]], SIZE, camera=True)
    assert a["camera_images"].shape == (5, 64, 32)
    assert (a["camera_images"] != a["images"]).any()  # perspective views are not the front view


def test_a_far_square_on_camera_sees_the_front_view(scenes, tmp_path):
    """5 m away with a long lens (4 px/mm, as the renders), no pitch, yaw or roll: the
    camera view's soft input is the front view's, registered to the pixel: the summed
    absolute difference is a small part of the silhouette (a one-pixel shift makes it
    more than half; the rest: thin ribs at the 128 level, and the morphology's hole
    limit, a fraction of the frame: the camera's frame is larger than the render's)."""
    far = CameraViews(
        pitch_deg=(0, 0),
        yaw_deg=(0, 0),
        roll_deg=(0, 0),
        distance_mm=(5000, 5000),
        hfov_deg=(2 * np.degrees(np.arctan(240 / 20000)),) * 2,
        frames_px=((480, 320),),
        principal_offset_px=0.0,
        target_jitter_mm=0.0,
    )
    render_shard(
        scenes["result"],
        tmp_path / "r",
        tmp_path / "far.npz",
        0.0,
        render_params=RenderParams(frames_per_scene=5, files_per_scene=0),
        params=DatasetParams(sizes=(SIZE,)),
        scene=dict(SCENE, height_mm=20.0),
        camera_views=far,
    )
    d = load_shard(tmp_path / "far.npz")
    front, cam = d["input_64x32"].astype(float), d["camera_input_64x32"].astype(float)
    l1 = np.abs(front - cam).sum((1, 2)) / front.sum((1, 2))
    assert l1.max() <= 0.2, l1
    shifted = np.abs(np.roll(front, 1, axis=1) - cam).sum((1, 2)) / front.sum((1, 2))
    assert shifted.min() > 2 * l1.max()
    assert cam.sum() / front.sum() == pytest.approx(1.0, abs=0.08)


def test_viewpoint_experiment(scenes, tmp_path):
    out = tmp_path / "viewpoint"
    m = run_viewpoint(
        out,
        scenes["indices"],
        scenes["shards"],
        SIZE,
        {"camera": str(scenes["model"])},
        log=lambda *_: None,
    )
    allrows = m[m["group"] == "all"]
    assert list(allrows["condition"]) == ["0", "20"]
    assert set(m["group"]) == {"all", "200.0", "300.0"}
    assert (allrows["n"] == 2 * 2 * 2).all() and (
        m["path"] == "camera"
    ).all()  # heights x distances x frames
    frames = pd.read_csv(out / "frames.csv")
    assert {"pred_camera", "pred_fy_camera", "fy_N", "distance_mm"} <= set(frames.columns)
    # the forces are the FEA's of the shards' frames, scored as force_metrics does
    f0 = frames[frames["condition"] == 0]
    row = allrows[allrows["condition"] == "0"].iloc[0]
    assert row["mse_N2"] == pytest.approx(force_metrics(f0["fx_N"], f0["pred_camera"])["mse_N2"])
    assert np.isfinite(row["stress_mse_log"]) and np.isfinite(row["fy_nrmse_pct"])
    s = viewpoint_summary(out, 5.0)
    assert s["distances_mm"] == [200.0, 300.0] and s["n_frames_per_pitch"] == 8
    assert list(s["nrmse_pct"]["camera"]) == ["0", "20"]
    assert set(s["usable_deg_by_distance"]["camera"]) == {"200.0", "300.0"}
    assert json.loads((out / "metrics.json").read_text())["20"]["camera"]["n"] == 8


def test_viewpoint_renders_of_another_run_are_refused(scenes, tmp_path):
    index = json.loads(scenes["indices"][0].read_text())
    index["frames"][0]["fx_N"] += 0.5
    bad = tmp_path / "bad"
    bad.mkdir()
    for fr in index["frames"]:
        (bad / fr["image"]).write_bytes((scenes["indices"][0].parent / fr["image"]).read_bytes())
    (bad / "index.json").write_text(json.dumps(index))
    with pytest.raises(ValueError, match="differs between its render and its shard"):
        run_viewpoint(
            tmp_path / "o",
            [bad / "index.json"],
            scenes["shards"],
            SIZE,
            {"camera": str(scenes["model"])},
            log=lambda *_: None,
        )
