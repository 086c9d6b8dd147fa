"""Drawn emulated rigs (finray.emulator.rigs) and the summary over rigs (finray.sim2real.rigs)."""

import colorsys

import numpy as np
import pandas as pd
import pytest

from finray.config import load_config
from finray.sim2real.rigs import rigs_summary, rigs_table
from finray.emulator.rigs import draw_rig, rig_index, rig_names, selection_rig_names


@pytest.fixture(scope="module")
def lab():
    return load_config("config/config.yaml")["lab"]


def test_rigs_are_drawn_within_their_ranges_and_replay(lab):
    spec = lab["rigs"]
    names = rig_names(spec)
    assert names == [f"rig{i}" for i in range(1, spec["count"] + 1)]
    rigs = [draw_rig(lab, rig_index(n)) for n in names]
    assert draw_rig(lab, 1) == rigs[0]  # seeded: the same rig each time
    # the selection rigs come after the reported ones, which stay as they are without them
    sel = selection_rig_names(spec)
    assert sel == [
        f"rig{i}" for i in range(spec["count"] + 1, spec["count"] + spec["selection"] + 1)
    ]
    alone = {**lab, "rigs": {**spec, "selection": 0}}
    assert [draw_rig(alone, rig_index(n)) for n in names] == rigs
    rigs = rigs + [draw_rig(lab, rig_index(n)) for n in sel]
    assert rigs[0] != rigs[1]
    for rig in rigs:
        assert "rigs" not in rig and set(rig) == set(lab) - {"rigs"}
        for path, (lo, hi) in spec["uniform"].items():
            section, key = path.split(".")
            assert np.all(
                (lo <= np.asarray(rig[section][key])) & (np.asarray(rig[section][key]) <= hi)
            ), path
        assert rig["camera"]["size_px"] in spec["choice"]["camera.size_px"]
        assert "emulated" in rig["camera"]["model"]
        # the object's hue is at least 120 deg from the finger's
        h = [colorsys.rgb_to_hsv(*rig["look"][c])[0] * 360 for c in ("finger_rgb", "object_rgb")]
        assert min(abs(h[0] - h[1]), 360 - abs(h[0] - h[1])) >= 119.9
        for name, obj in rig["objects"].items():
            base = lab["objects"][name]
            key = next((k for k in ("diameter_mm", "side_mm") if k in base), None)
            if key:
                assert 0.8 * base[key] - 0.01 <= obj[key] <= 1.2 * base[key] + 0.01
        # the heights over the face: one in each third of the span, sorted, distinct
        lo, hi = spec["height_span_mm"]
        assert len(rig["heights_mm"]) == len(lab["heights_mm"]) == len(set(rig["heights_mm"]))
        assert rig["heights_mm"] == sorted(rig["heights_mm"]) and lo <= rig["heights_mm"][0]
        assert rig["heights_mm"][-1] <= hi
        assert rig["seed"] != lab["seed"]  # its own noise


def test_rig_errors(lab):
    with pytest.raises(ValueError, match="rig1, rig2"):
        rig_index("default")
    with pytest.raises(ValueError, match="not rig 9"):
        draw_rig(lab, 9)
    bad = {**lab, "rigs": {**lab["rigs"], "uniform": {"camera.no_such_key": [0, 1]}}}
    with pytest.raises(ValueError, match="camera.no_such_key"):
        draw_rig(bad, 1)


def test_summary_over_rigs():
    def summ(errs, covs, n=100):
        return {
            "by_context": {
                str(k): {"nrmse_pct": e, "mse_N2": e / 10, "coverage_pct": c, "n_frames": n}
                for k, (e, c) in enumerate(zip(errs, covs))
            }
        }

    rig1 = summ([14, 6, 7], [70, 90, 90], n=300)
    for k, (e, n) in enumerate([(10, 250), (4, 240), (3, 240)]):  # near_base frames left out
        rig1["by_context"][str(k)]["unflagged"] = {"nrmse_pct": e, "n": n}
    # a summary from before the flag: every frame counts as unflagged
    table = rigs_table({"default": summ([12, 3, 2], [90, 80, 100]), "rig1": rig1})
    s = rigs_summary(table, 0.9)
    assert s["per_rig"]["default"] == {
        "error_falls": True,
        "nrmse_pct_most_context": 2,
        "within_target": True,
        "unflagged_error_falls": True,
        "unflagged_within_target": True,
        "unflagged_nrmse_pct": [12, 3, 2],
        "near_base_frames": [0, 0, 0],
        "nrmse_pct": [12, 3, 2],
        "coverage_pct": [90, 80, 100],
        "n_frames": [100, 100, 100],
    }
    r1 = s["per_rig"]["rig1"]
    assert not r1["error_falls"] and not r1["within_target"]
    assert r1["unflagged_error_falls"] and r1["unflagged_within_target"]
    assert r1["near_base_frames"] == [50, 60, 60]
    assert not s["all_fall"] and not s["all_within_target"]
    assert s["unflagged_all_fall"] and s["unflagged_all_within_target"]
    assert s["by_context"]["0"]["coverage_pct_pooled"] == pytest.approx((90 * 100 + 70 * 300) / 400)
    assert (s["by_context"]["1"]["nrmse_pct_min"], s["by_context"]["1"]["nrmse_pct_max"]) == (3, 6)
    assert isinstance(table, pd.DataFrame) and len(table) == 6


def test_height_span_draws_one_height_per_part_of_the_face():
    """lab.rigs.height_span_mm: a rig's heights spread over the span, one in each equal
    part, none where an object would reach below the base (plus the clearance)."""
    import numpy as np

    from finray.geometry.objects import object_shape
    from finray.emulator.rigs import BASE_CLEARANCE_MM, span_heights

    objects = {
        "cylinder": {"type": "circle", "diameter_mm": 20.0},
        "square": {"type": "square", "side_mm": 10.0, "angle_deg": 0.0},
    }
    for seed in range(20):
        hs = span_heights(np.random.default_rng(seed), objects, [4.0, 70.0], 3)
        assert hs == sorted(hs) and len(set(hs)) == 3 and all(h == int(h) for h in hs)
        lo = 10.0 + BASE_CLEARANCE_MM  # the cylinder's radius and the clearance
        edges = np.linspace(lo, 70.0, 4)
        assert all(a <= h <= b for h, a, b in zip(hs, edges[:-1], edges[1:]))
        assert min(hs) + object_shape(objects["cylinder"], 0.5).bounds[1] >= BASE_CLEARANCE_MM
    with pytest.raises(ValueError, match="height_span_mm"):
        span_heights(np.random.default_rng(0), objects, [4.0, 12.0], 3)


def _sim2real_frames(k, context, group, height_mm, sensor_N, pred_N) -> pd.DataFrame:
    """A sim-to-real frames table of one take: the prediction is the heads' mean, every
    interval wide (0-100 N)."""
    return pd.DataFrame(
        {
            "context_objects": k,
            "context": context,
            "group": group,
            "take": "t",
            "height_mm": height_mm,
            "sensor_N": sensor_N,
            "pred_N": pred_N,
            "net_mean_N": pred_N,
            "lo_N": 0.0,
            "hi_N": 100.0,
        }
    )


def test_sim2real_metrics_per_contact_height_and_over_rigs():
    """Sim-to-real's metrics: each contact height over its contexts (NRMSE in % of that
    height's largest force), carried into the summary and the summary over rigs."""
    from finray.sim2real.rigs import rigs_heights
    from finray.sim2real.experiment import metrics_table

    fr = _sim2real_frames(
        1, "a", "b", [10.0, 10.0, 60.0, 60.0], [10.0, 20.0, 1.0, 2.0], [10.0, 21.0, 1.0, 2.1]
    )
    m = metrics_table(fr, 0.9)
    h = m[m["context"] == "by_height"].set_index("test")
    assert list(h.index) == ["10", "60"]
    assert h.loc["10", "nrmse_pct"] == pytest.approx(100 * np.sqrt(0.5) / 20)
    assert h.loc["60", "nrmse_pct"] == pytest.approx(100 * np.sqrt(0.005) / 2)
    # the per-object and overall rows are as before
    assert set(m.loc[m["context"] == "all", "test"]) == {"b", "all"}
    s = {
        "rigX": {
            "by_context": {
                "1": {
                    "per_height": {
                        "60": {
                            "nrmse_pct": 3.5,
                            "coverage_pct": 90.0,
                            "rmse_N": 0.07,
                            "max_sensor_N": 2.0,
                        },
                        "10": {
                            "nrmse_pct": 2.5,
                            "coverage_pct": 80.0,
                            "rmse_N": 0.5,
                            "max_sensor_N": 20.0,
                        },
                    }
                }
            }
        }
    }
    assert rigs_heights(s) == {
        "rigX": {
            "1": {
                "10": {"nrmse_pct": 2.5, "coverage_pct": 80.0},
                "60": {"nrmse_pct": 3.5, "coverage_pct": 90.0},
            }
        }
    }


def test_sim2real_reports_the_frames_not_flagged_near_base_apart():
    """A frame the sensor flags near_base counts in every row's n_near_base and is left
    out of the ``unflagged`` row, whose metrics are those of the other frames alone."""
    from finray.evaluate.metrics import force_metrics
    from finray.sim2real.experiment import metrics_table

    fr = _sim2real_frames(
        2, "a + b", "c", [12.0, 12.0, 40.0, 40.0], [30.0, 32.0, 3.0, 4.0], [10.0, 12.0, 3.1, 3.8]
    ).assign(near_base=[True, True, False, False])
    m = metrics_table(fr, 0.9).set_index(["context", "test"])
    ok = m.loc[("unflagged", "all")]
    want = force_metrics(np.array([3.0, 4.0]), np.array([3.1, 3.8]))
    assert ok["n"] == 2 and ok["n_near_base"] == 0
    assert ok["nrmse_pct"] == pytest.approx(want["nrmse_pct"])
    assert (
        m.loc[("all", "all"), "n_near_base"] == 2 and m.loc[("by_height", "12"), "n_near_base"] == 2
    )
    assert m.loc[("all", "all"), "nrmse_pct"] > 10 * ok["nrmse_pct"]
