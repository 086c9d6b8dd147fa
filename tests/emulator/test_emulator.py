"""The emulated lab rig: motion, sensor, camera model, the 3D scene's projection, and a
short take end to end through ``finray ingest`` (which must not need the truth)."""

import json
import shutil

import numpy as np
import pandas as pd
import pytest

from finray.config import load_config
from finray.emulator.camera import LensDistortion, PinholeCamera
from finray.emulator.motion import GripperMotion
from finray.emulator.sensor import ForceSensor
from helpers import write_synthetic_fea_result

LAB = load_config("config/smoke.yaml")["lab"]


def test_motion_lowers_holds_and_raises():
    m = GripperMotion(
        push_mm=10.0, speed_mm_s=10.0, hold_s=1.0, starts_s=(1.0, 5.5), duration_s=10.0
    )
    d = m.push(np.array([0.0, 1.0, 1.5, 2.0, 2.5, 3.0, 4.0, 5.0, 6.5, 9.9]))
    assert d[[0, 1, 6, 7, 9]] == pytest.approx(0.0)
    assert d[[3, 4, 5, 8]] == pytest.approx(10.0)  # held 1 s at the bottom
    assert d[2] == pytest.approx(5.0)  # the minimum-jerk move is symmetric
    assert m.speed(np.array([1.5]))[0] == pytest.approx(1.875 * 10.0, rel=1e-3)  # its peak
    with pytest.raises(ValueError, match="overlap or leave"):
        GripperMotion(starts_s=(1.0, 3.0))


def test_sensor_log_offset_gain_and_noise():
    s = ForceSensor(
        rate_hz=500.0,
        noise_N=(0.0, 0.0, 0.01),
        bias_N=(0.1, 0.0, 0.2),
        gain_error=0.02,
        clock_start_s=50.0,
        latency_s=(0.03, 0.03),
        drift_ppm=0.0,
        margin_s=0.2,
    )
    offset = s.draw_offset(np.random.default_rng(0))
    assert offset == pytest.approx(-50.03)
    log = s.log(
        lambda t: (np.where(t > 1.0, 4.0, 0.0), np.zeros_like(t)),
        2.0,
        offset,
        np.random.default_rng(1),
    )
    t_cam = log["t_s"] + offset  # camera = sensor + offset
    assert t_cam[0] == pytest.approx(-0.2) and t_cam[-1] == pytest.approx(2.2)
    assert np.median(log["fz_N"][t_cam > 1.1]) == pytest.approx(-1.02 * 4.0 + 0.2, abs=0.005)
    assert np.std(log["fz_N"][t_cam < 0.9]) == pytest.approx(0.01, rel=0.15)
    assert np.all(log["fx_N"] == 0.1)


def test_distortion_samples_where_the_model_says():
    cam = PinholeCamera.looking_at(
        (0, 0, 0),
        width=160,
        height=90,
        hfov_deg=69.4,
        distance_mm=200,
        distortion=(0.04, -0.01, 0.0005, -0.0003, 0.0),
    )
    rows, cols = cam.undistorted_coords()
    # bilinear sampling is exact on a linear image: the columns' index comes back
    img = np.broadcast_to(np.arange(160, dtype=np.float32)[None, :, None], (90, 160, 3))
    out = LensDistortion(cam).image(np.ascontiguousarray(img))
    inside = (cols >= 0) & (cols <= 159) & (rows >= 0) & (rows <= 89)
    assert np.abs(out[..., 0] - cols)[inside].max() < 1e-3
    # barrel (inverse model, k1 > 0): the corners sample from further out, the centre stays
    assert cols[0, 0] < 0 and abs(cols[45, 80] - 80) < 0.1
    box = (10, 30, 40, 90)
    assert np.array_equal(
        LensDistortion(cam).image(np.ascontiguousarray(img), box), out[10:30, 40:90]
    )


@pytest.fixture(scope="module")
def result(tmp_path_factory):
    return write_synthetic_fea_result(
        tmp_path_factory.mktemp("fea") / "result.npz",
        n_frames=11,
        max_displacement_mm=10.0,
        size_mm=1.0,
    )


def test_scene_projects_like_the_camera_and_windows_are_exact(result):
    from finray.emulator.studio import Studio
    from finray.render.result import load_fea_result

    res = load_fea_result(result)
    look = dict(LAB["look"])
    cam = PinholeCamera.looking_at(
        (5.0, 38.0, 0.0),
        width=320,
        height=180,
        hfov_deg=69.4,
        distance_mm=200,
        yaw_deg=6,
        pitch_deg=4,
        roll_deg=1,
        principal_offset_px=(3.5, -2.0),
    )
    outline = res.object_points_mm[0].astype(float)
    with Studio(res.mesh, outline, cam, look, 20.0) as scene:
        scene.pose(res.deformed_points(5), -5.0)
        full = scene.render_mask().copy()
        colour = scene.render_colour().copy()
        uv = cam.project(scene.finger.points)  # the finger's corners, as the camera sees them
        r, c = np.nonzero(full)
        # the mask's extent is the projection's (the clamp hides a little of the base)
        assert abs(c.min() - uv[:, 0].min()) < 1.5 and abs(c.max() - uv[:, 0].max()) < 1.5
        assert abs(r.min() - uv[:, 1].min()) < 1.5
        scene.set_window(100, 20, 120, 150)
        part = scene.render_mask()
        assert np.array_equal(part, full[20:170, 100:220])  # the same rays, pixel for pixel
        assert np.abs(scene.render_colour().astype(int) - colour[20:170, 100:220]).max() <= 1
    # the finger is orange where it shows
    assert (colour[full][:, 0] > colour[full][:, 2] + 60).mean() > 0.95


@pytest.mark.slow
def test_a_short_take_ingests_without_its_truth(result, tmp_path):
    from finray.emulator.emulate import emulate_take
    from finray.recording import IngestParams, ingest

    lab = json.loads(json.dumps(LAB))
    lab["motion"].update(starts_s=[0.2, 1.4], duration_s=2.6, speed_mm_s=25.0, hold_s=0.3)
    lab["camera"].update(size_px=[640, 360], distance_mm=120.0)
    truth = emulate_take(
        result,
        tmp_path / "take",
        lab,
        object_name="cylinder",
        height_mm=30.0,
        extrusion_mm=20.0,
        seed=3,
        log=lambda m: None,
    )
    files = sorted(p.name for p in (tmp_path / "take").iterdir())
    assert files == ["forces.csv", "take.json", "take.mp4", "truth"]
    forces = pd.read_csv(tmp_path / "take" / "forces.csv")
    assert list(forces.columns) == ["t_s", "fx_N", "fy_N", "fz_N"]
    # ingest sees what a real rig writes: the take without truth/
    shutil.copytree(tmp_path / "take", tmp_path / "rig", ignore=shutil.ignore_patterns("truth"))
    s = ingest(
        tmp_path / "rig", tmp_path / "out", IngestParams(write_masks=True), log=lambda m: None
    )
    assert s["frames"]["ok"] == truth["n_frames"] == 78
    assert abs(s["sync"]["offset_s"] - truth["offset_s"]) < truth["frame_interval_s"]

    from finray.evaluate.lab_takes import mask_iou

    iou = mask_iou(tmp_path / "out", tmp_path / "take")
    assert len(iou) == 78 and iou["iou"].min() > 0.9
    label = pd.read_csv(tmp_path / "out" / "frames.csv")["force_N"]
    true = pd.read_csv(tmp_path / "take" / "truth" / "frames.csv")["force_N"]
    # the label is the sensor's: its gain error and offset, not the truth
    g, b = np.polyfit(true, label, 1)
    assert g == pytest.approx(1 + LAB["sensor"]["gain_error"], abs=0.01)
    assert b == pytest.approx(-LAB["sensor"]["bias_N"][2], abs=0.02)


def test_a_scene_stopped_at_its_force_limit_makes_a_shorter_push(tmp_path):
    """An FEA scene that stopped at the physical limit (fea.force_cap_N) before the
    motion's push: the take pushes as far as the FEA reached, and its truth says so."""
    from finray.emulator.emulate import emulate_take

    res = write_synthetic_fea_result(
        tmp_path / "result.npz", n_frames=5, max_displacement_mm=6.0, size_mm=1.0
    )
    lab = json.loads(json.dumps(LAB))
    lab["motion"].update(starts_s=[0.2], duration_s=1.6, speed_mm_s=25.0, hold_s=0.3)
    lab["camera"].update(size_px=[320, 180], distance_mm=120.0)
    said = []
    truth = emulate_take(
        res,
        tmp_path / "take",
        lab,
        object_name="cylinder",
        height_mm=30.0,
        extrusion_mm=20.0,
        seed=3,
        log=said.append,
    )
    assert truth["force_limited"] and truth["push_mm"] == pytest.approx(6.0)
    frames = pd.read_csv(tmp_path / "take" / "truth" / "frames.csv")
    assert frames["push_mm"].max() == pytest.approx(6.0, abs=1e-3)
    assert any("the take pushes 6.000 mm" in m for m in said)
