"""The FEA sweep over the whole face: its scenes (seeded, placeable down to the clamped
base) and its summary (outcomes, CPU per band)."""

import numpy as np
import pandas as pd

from finray.benchmarks.fea_sweep import KINDS, draw_scenes, lowest_height_mm, sweep_summary
from finray.config import default_config_path, load_config
from finray.geometry.finger import FingerParams
from finray.geometry.objects import object_geometry

SWEEP = load_config(default_config_path())["benchmarks"]["fea_sweep"]


def test_scenes_are_seeded_cover_the_face_and_can_be_placed():
    fp = FingerParams()
    scenes = draw_scenes(40, 3, SWEEP, fp, 1.0)
    # scene i from its own stream: the same whatever the count; another seed, others
    assert draw_scenes(10, 3, SWEEP, fp, 1.0) == scenes[:10]
    assert draw_scenes(10, 4, SWEEP, fp, 1.0) != scenes[:10]
    assert {s["kind"] for s in scenes} == set(KINDS)
    for s in scenes:
        lo = lowest_height_mm(s["spec"], 1.0)
        assert s["height_min_mm"] == round(lo, 4) and lo < s["height_mm"] <= SWEEP["height_max_mm"]
        obj = object_geometry(s["scene"], s["spec"], fp, s["height_mm"], 1.0)  # no GeometryError
        assert obj.points[:, 1].min() >= -1e-9  # never below the clamped base
    # the lowest height puts the object's lowest point on the base (y = 0)
    spec = {"type": "square", "side_mm": 10.0, "angle_deg": 45.0, "fillet_mm": 0.5}
    lo = lowest_height_mm(spec, 1.0)
    obj = object_geometry("sq", spec, fp, lo + 1e-6, 1.0)
    assert abs(obj.points[:, 1].min()) < 1e-3


def test_summary_counts_outcomes_and_bands():
    df = pd.DataFrame(
        {
            "scene": ["s0", "s1", "s2", "s3"],
            "kind": ["circle", "square", "ellipse", "polygon"],
            "spec": ["{}"] * 4,
            "height_mm": [5.0, 8.0, 35.0, 69.0],
            "outcome": ["force_cap", "failed", "complete", "complete"],
            "cause": ["", "no convergence", "", ""],
            "message": ["", "load step 9 failed", "", ""],
            "push_reached_mm": [0.4, np.nan, 10.0, 10.0],
            "max_force_N": [41.0, 90.0, 8.0, 2.0],
            "cpu_s": [3.0, 60.0, 5.0, 4.0],
        }
    )
    md = sweep_summary(df, 40.0)
    assert "**3/4 (75.0 %)" in md and "failed 1" in md
    assert "[no convergence] load step 9 failed" in md
    assert "| 0-10 " in md and "| 30-40 " in md and "| 60-70 " in md
    assert "median 4.5 s" in md
