"""The randomised training cameras: replayable draws within their ranges, and the camera
views' network inputs (a far, square-on camera sees the front view)."""

import numpy as np
import pytest

from finray.render.camera_views import VIEW_COLUMNS, CameraViews


def test_draws_are_replayable_and_within_their_ranges():
    v = CameraViews()
    cam, row = v.sample("circle_d10_steel_h30_p0", 7)
    cam2, row2 = v.sample("circle_d10_steel_h30_p0", 7)
    assert cam == cam2 and np.array_equal(row, row2)
    assert not np.array_equal(row, v.sample("circle_d10_steel_h30_p0", 8)[1])
    assert not np.array_equal(row, CameraViews(seed=1).sample("circle_d10_steel_h30_p0", 7)[1])
    rows = np.stack([v.sample("s", k)[1] for k in range(600)])
    d = dict(zip(VIEW_COLUMNS, rows.T))
    for key in ("pitch_deg", "yaw_deg", "roll_deg", "distance_mm", "hfov_deg"):
        lo, hi = getattr(v, key)
        assert d[key].min() >= lo and d[key].max() <= hi
        assert d[key].max() - d[key].min() > 0.9 * (hi - lo)  # the whole range is drawn
    assert {(int(w), int(h)) for w, h in zip(d["width_px"], d["height_px"])} == {
        (h, w) for w, h in v.frames_px
    }  # every stream size, portrait
    assert np.abs(d["cx_offset_px"]).max() <= v.principal_offset_px


def test_a_drawn_camera_looks_at_its_target_from_its_distance():
    v = CameraViews()
    for k in range(20):
        cam, row = v.sample("x", k)
        r = dict(zip(VIEW_COLUMNS, row))
        target = np.array([r["target_x_mm"], r["target_y_mm"], 0.0])
        assert np.linalg.norm(np.asarray(cam.position) - target) == pytest.approx(r["distance_mm"])
        u, vv = cam.project(target[None])[0]  # the target sits on the principal point
        assert (u, vv) == pytest.approx((cam.cx, cam.cy), abs=1e-6)
        # the landscape stream's horizontal field of view spans the portrait height
        assert 2 * np.degrees(np.arctan(0.5 * cam.height / cam.fy)) == pytest.approx(r["hfov_deg"])
        # pitch: the camera is above the finger's plane by distance x sin(pitch)
        assert cam.position[1] - target[1] == pytest.approx(
            r["distance_mm"] * np.sin(np.radians(r["pitch_deg"]))
        )


def test_config_section_and_bad_ranges():
    assert CameraViews.from_config(None) is None
    assert CameraViews.from_config({"enabled": False}) is None
    v = CameraViews.from_config({"pitch_deg": [0, 10], "frames_px": [[640, 480]], "seed": 3})
    assert v.pitch_deg == (0, 10) and v.frames_px == ((640, 480),) and v.seed == 3
    with pytest.raises(ValueError, match="camera_views.yaw_deg"):
        CameraViews(yaw_deg=(5.0, -5.0))
