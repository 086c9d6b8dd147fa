"""Evaluation: the baseline's features and fit, occlusion replay, usable pitch range."""

import numpy as np
import pandas as pd
import pytest

from finray.evaluate.baseline import RidgeBaseline, fit_ridge, front_edge_profile
from finray.evaluate.tables import usable_range
from finray.evaluate.predictions import occlude


def test_front_edge_profile_is_subpixel_exact():
    """A row whose finger starts at x = 3.25 px (a quarter-covered pixel) -> 3.25 px
    of background; rows without finger -> the full width."""
    img = np.zeros((3, 10), np.float32)
    img[0, 4:] = 1.0
    img[0, 3] = 0.75
    img[1, 6:8] = 1.0
    img[1, 9] = 0.2  # a speck right of the finger does not move the front edge
    e = front_edge_profile(img[None])[0]
    assert e[0] == pytest.approx(3.25)
    assert e[1] == pytest.approx(6.0)
    assert e[2] == pytest.approx(10.0)


def test_ridge_recovers_a_linear_law_and_round_trips(tmp_path):
    rng = np.random.default_rng(1)
    x = rng.normal(size=(400, 5))
    w = np.array([1.0, -2.0, 0.5, 0.0, 3.0])
    y = x @ w + 0.7
    groups = np.repeat(np.arange(20), 20)
    model, info = fit_ridge(x, y, groups, alphas=(1e-6, 1e-3, 1.0))
    assert info["alpha"] == pytest.approx(1e-6)
    assert np.allclose(model.predict(x), y, atol=1e-4)
    model.save(tmp_path / "r.npz")
    again = RidgeBaseline.load(tmp_path / "r.npz")
    assert np.array_equal(again.predict(x), model.predict(x))


def test_constant_features_do_not_break_the_fit():
    x = np.c_[np.linspace(0, 1, 50), np.full(50, 32.0)]
    y = 2 * x[:, 0]
    model, _ = fit_ridge(x, y, np.arange(50) // 5, alphas=(1e-8,))
    assert np.allclose(model.predict(x), y, atol=1e-5)


def test_occlusion_is_replayable_and_within_its_level():
    imgs = np.full((6, 64, 32), 255, np.uint8)
    tab = pd.DataFrame({"scene_id": ["a"] * 3 + ["b"] * 3, "frame": [0, 1, 2] * 2})
    a = occlude(imgs, tab, "high", seed=3)
    b = occlude(imgs, tab, "high", seed=3)
    assert np.array_equal(a, b)
    assert not np.array_equal(a, occlude(imgs, tab, "high", seed=4))
    widths = (a == 0).any(axis=1).sum(axis=1) / 32  # disc diameter / image width
    assert np.all(widths >= 0.8) and np.all(widths <= 1.0)
    assert occlude(imgs, tab, "none", seed=3) is imgs


def test_usable_range_stops_at_the_first_pitch_above_the_threshold():
    m = pd.DataFrame(
        {
            "condition": ["0", "5", "10", "15"],
            "group": "all",
            "predictor": "plain",
            "nrmse_pct": [1.0, 4.0, 7.0, 3.0],
        }
    )
    assert usable_range(m, "plain", 5.0) == 5.0
    assert usable_range(m, "plain", 0.5) is None
    assert usable_range(m, "plain", 10.0) == 15.0


def test_fea_checks_gather_the_scene_checks(tmp_path):
    """summary.json of each scene -> fea_scenes.csv -> the checks the manuscript states."""
    import json

    from finray.evaluate.summary import fea_checks
    from finray.fea.figures import scene_table

    paths = []
    for i, (res, eq, ls, fb, gap) in enumerate(
        [(2e-4, 1e-8, 0, 1, 0.003), (7e-4, 3e-7, 2, 0, 0.002)]
    ):
        p = tmp_path / f"s{i}.json"
        p.write_text(
            json.dumps(
                {
                    "scene": f"s{i}",
                    "converged": True,
                    "min_gap_mm": gap,
                    "residual_tol": 1e-3,
                    "residual_final_rel": res / 2,
                    "residual_max_rel": res,
                    "equilibrium_tol": 1e-3,
                    "equilibrium_max_rel_error": eq,
                    "line_search_failures": ls,
                    "gradient_fallbacks": fb,
                }
            )
        )
        paths.append(p)
    scene_table(paths, tmp_path / "fea_scenes.csv")
    c = fea_checks(tmp_path / "fea_scenes.csv")
    assert c == {
        "n_scenes": 2,
        "residual_tol": 1e-3,
        "residual_max_rel": 7e-4,
        "residual_max_scene": "s1",
        "equilibrium_tol": 1e-3,
        "equilibrium_max_rel_error": 3e-7,
        "equilibrium_max_scene": "s1",
        "line_search_failures": 2,
        "gradient_fallbacks": 1,
        "min_gap_mm": 0.002,
    }


def test_height_rows_give_each_height_its_own_scale_and_band():
    """heights.csv: per contact height the force metrics relative to that height's largest
    force, its 10 mm band and whether a training scene used it."""
    import pandas as pd

    from finray.evaluate.experiments import _height_rows

    fr = pd.DataFrame(
        {
            "height_mm": [15.0] * 3 + [20.0] * 3,
            "fx_N": [0.0, 5.0, 10.0, 0.0, 1.0, 2.0],
            "pred_camera": [0.0, 5.0, 11.0, 0.0, 1.0, 2.2],
        }
    )
    rows = {r["height_mm"]: r for r in _height_rows(fr, "all", ["camera"], train_heights_mm=[20])}
    assert rows[15.0]["band_mm"] == 10.0 and rows[20.0]["band_mm"] == 20.0
    assert rows[15.0]["unseen"] and not rows[20.0]["unseen"]
    assert np.isclose(rows[15.0]["rmse_N"], np.sqrt(1 / 3))
    assert np.isclose(rows[15.0]["nrmse_pct"], 100 * np.sqrt(1 / 3) / 10)
    assert np.isclose(rows[20.0]["nrmse_pct"], 100 * np.sqrt(0.04 / 3) / 2)


def test_face_summary_splits_unseen_from_trained_heights(tmp_path):
    """The summary's face node: per-height rows, and the metrics over the unseen heights'
    frames apart from the trained heights'."""
    import pandas as pd

    from finray.evaluate.experiments import _height_rows
    from finray.evaluate.summary import face_summary

    fr = pd.DataFrame(
        {
            "condition": "all",
            "path": "shard",
            "height_mm": [15.0, 15.0, 20.0, 20.0],
            "fx_N": [1.0, 4.0, 0.5, 2.0],
            "pred_camera": [1.0, 3.0, 0.5, 2.0],
        }
    )
    pd.DataFrame(_height_rows(fr, "all", ["camera"], [20.0])).to_csv(
        tmp_path / "heights.csv", index=False
    )
    fr.to_csv(tmp_path / "frames.csv", index=False)
    s = face_summary(tmp_path)
    assert s["unseen_heights_mm"] == [15.0] and s["heights_mm"] == [15.0, 20.0]
    assert np.isclose(s["unseen"]["camera"]["rmse_N"], np.sqrt(0.5))
    assert np.isclose(s["unseen"]["camera"]["nrmse_pct"], 100 * np.sqrt(0.5) / 4)
    assert s["seen"]["camera"]["rmse_N"] == 0.0
    assert [r["height_mm"] for r in s["by_height"]["camera"]] == [15.0, 20.0]
    # no unseen height: no face node
    pd.DataFrame(_height_rows(fr, "all", ["camera"], [15.0, 20.0])).to_csv(
        tmp_path / "heights.csv", index=False
    )
    assert face_summary(tmp_path) is None


def test_height_rows_score_the_contact_height_on_loaded_frames_only():
    """With a contact head, each height's row has the contact height's RMSE (mm) over the
    frames pushed harder than CONTACT_MIN_FORCE_N (at rest the height means nothing)."""
    from finray.evaluate.experiments import CONTACT_MIN_FORCE_N, _height_rows

    fr = pd.DataFrame(
        {
            "height_mm": 30.0,
            "fx_N": [0.0, 0.2, 2.0, 4.0],
            "pred_camera": [0.0, 0.2, 2.0, 4.0],
            "contact_y_mm": [np.nan, 31.0, 30.0, 29.0],
            "contact_pred_camera": [50.0, 40.0, 31.0, 28.0],
        }
    )
    assert CONTACT_MIN_FORCE_N == 0.5
    (row,) = _height_rows(fr, "all", ["camera"], [30.0])
    assert row["contact_n"] == 2 and row["contact_rmse_mm"] == pytest.approx(1.0)
