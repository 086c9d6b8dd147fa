"""The manuscript's words come from its numbers; it renders from the full config's
summary (and, in tests/workflow/test_workflow.py, from the smoke config's).

tests/data/summary_full.json is the summary of a full run (config/config.yaml, 2-core CPU
run of 2026-11-22 in the main checkout), rebuilt with this checkout's summary code by
``PYTHONPATH=src python tests/data/make_summary_full.py <results>``. The smoke run test
checks that its key structure still matches what build_summary writes, so that it cannot
go stale silently: refresh it when the summary gains or loses a key.
"""

import copy
import json

import pandas as pd
import pytest

from finray.evaluate.manuscript import render_text
from finray.evaluate.summary import fea_forces, key_structure, training_data, training_summary
from finray.evaluate.wording import compare, count, range_relation, reach
from finray.paper_reference import paper_reference, paper_value

from helpers import DATA, ROOT

TEMPLATE = ROOT / "paper" / "manuscript.md.j2"
FULL = json.loads((DATA / "summary_full.json").read_text())


def render(s):
    return render_text(TEMPLATE, s, {"speed_table": "| speed table |"})


def test_compare_both_directions_and_the_tolerance():
    assert compare(1.0, 3.4) == "3.4 times smaller than"
    assert compare(2.1, 1.0) == "2.1 times larger than"
    assert compare(1.05, 1.0) == "about the same as"  # within SAME_FACTOR (1.1)
    assert compare(1.0, 1.05) == "about the same as"
    assert compare(1.0, 1.2, "less", "more", than=False) == "1.2 times less"
    assert compare(None, 1.0) == "not comparable with"
    assert compare(1.0, 0.0) == "not comparable with"


def test_range_relation_and_counts():
    paper = [0.02, 0.09]
    assert range_relation([0.007, 0.01], paper) == "below"
    assert range_relation([0.1, 0.2], paper) == "above"
    assert range_relation([0.03, 0.05], paper) == "within"
    assert range_relation([0.01, 0.05], paper) == "overlapping"
    assert count(3, "held-out shape") == "three held-out shapes"
    assert count(1, "held-out shape") == "one held-out shape"
    assert count(12, "scene") == "12 scenes"


def test_reach_says_only_when_short_of_the_paper():
    pitches = [0, 5, 10, 15]
    assert (
        reach(0.0, pitches, 10.0)
        == "up to 0° only, short of the paper's network (usable below 10°)"
    )
    assert reach(5.0, pitches, 10.0) == "up to 5°, as the paper's network (usable below 10°)"
    assert reach(15.0, pitches, 10.0) == "up to 15°, beyond the paper's network (usable below 10°)"
    assert reach(None, pitches, 10.0).startswith("at no pitch")


def test_paper_reference_is_the_one_home():
    ref = paper_reference()["values"]
    for name, v in ref.items():
        assert {"value", "unit", "where", "quote"} <= set(v), name
    assert paper_value("shape_mse_N2") == [0.02, 0.09]
    assert paper_value("sim_to_real_mse_N2") == {
        "sim_only": 0.092,
        "one_real_sample": 0.07,
        "two_real_samples": 0.037,
    }
    with pytest.raises(KeyError, match="no paper reference value 'nope'"):
        paper_value("nope")
    # the template types none of the paper's numbers: it reads them from s.paper
    text = TEMPLATE.read_text()
    for typed in ("0.02", "0.09", "0.092", "0.037", "8 ms", "10°", "20,000"):
        assert typed not in text, typed


def test_manuscript_renders_from_the_full_summary():
    assert FULL["paper"] == paper_reference()["values"]
    text = render(FULL)
    assert "{{" not in text and "{%" not in text
    shp = FULL["experiments"]["shape"]["all"]
    assert f"{shp['plain']['all']['nrmse_pct']:.1f} %" in text
    net, base = shp["plain"]["all"]["nrmse_pct"], shp["baseline"]["all"]["nrmse_pct"]
    assert net < base  # the fixture's network beats the baseline: the words must say so
    assert f"The network's error is {base / net:.1f} times smaller than\nthe baseline's" in text
    # the words derive from the numbers (the whole-face test set's MSEs fall inside the range)
    from finray.evaluate.wording import range_relation

    mses = [g["mse_N2"] for g in shp["plain"]["groups"].values()]
    assert (
        f"{range_relation(mses, FULL['paper']['shape_mse_N2']['value'])} the paper's range" in text
    )
    assert "up to 0° only" in text
    t = FULL["training"]["plain"]
    assert f"epoch {t['best_epoch']} of {t['epochs']}" in text
    d = FULL["training_data"]
    assert f"{d['solver_frames']} distinct FEA states" in text
    # the emulated lab takes: called so, and compared with the paper's sim-only 0.092 N²
    q = FULL["lab"]["qa"]
    assert "is **emulated**" in text and "the takes below are not recordings" in text
    ratio = q["force_vs_sensor"]["mse_N2"] / 0.092
    assert f"{ratio:.1f} times larger than the paper's\n0.092 N² on its real takes" in text
    # the viewpoint experiment on perspective renders: each model's reach, from the summary
    v = FULL["viewpoint"]
    for key, name in (("plain", "CNN, front views"), ("camera", "CNN, camera views")):
        u = v["usable_deg"][key]
        assert f"- {name}: " + ("at no pitch" if u is None else f"up to {u:g}°") in text
    c = FULL["camera_model"]["shape"]
    assert (
        f"{'loses' if c['loss_pp'] > 0 else 'gains'} {abs(c['loss_pp']):.2f} percentage points "
        "on the shape test"
    ) in text


def test_the_words_turn_with_the_numbers():
    s = copy.deepcopy(FULL)
    shp = s["experiments"]["shape"]["all"]
    shp["plain"]["all"]["nrmse_pct"] = 3 * shp["baseline"]["all"]["nrmse_pct"]
    for g in shp["plain"]["groups"].values():
        g["mse_N2"] = 0.5
    s["pitch_usable_deg"]["plain"] = 20.0
    s["pitch_augmentation_iou"]["5"]["iou_front_view_mean"] = 0.95
    occ = s["experiments"]["occlusion"]
    occ["low"]["baseline"]["all"]["nrmse_pct"] = occ["none"]["baseline"]["all"]["nrmse_pct"]
    s["camera_model"]["shape"]["loss_pp"] = -0.3
    s["viewpoint"]["nrmse_pct"]["plain"]["0"] = 4.0  # within the threshold: no "Even at 0°"
    text = render(s)
    assert "gains 0.30 percentage points on the shape test" in text
    assert "Even at 0°" not in text and "Even at 0°" in render(FULL)
    assert "3.0 times larger than\nthe baseline's" in text
    assert "above the paper's range" in text
    assert "up to 20°, beyond the paper's network" in text
    assert "by\n95 %" in text and "only 95" not in text
    assert "about the same as\nits" in text and "already worse" not in text


def test_the_occlusion_section_says_how_the_occlusion_model_trained():
    """Trained from new weights the paper's words stand; fine-tuned from another model
    (train.models.occlusion.start_from), the section says from which and for how long."""
    assert "Retrained with random occlusion, it is at" in render(FULL)
    s = copy.deepcopy(FULL)
    s["setup"]["model_start"]["occlusion"] = {"from": "plain", "epochs": 5}
    text = " ".join(render(s).split())
    assert (
        "Retrained with random occlusion (the paper retrains; here the plain network's "
        "weights are trained on for 5 more epochs, against 10 for a network from new "
        "weights), it is at"
    ) in text


def test_the_camera_model_says_when_it_keeps_averaged_weights():
    """A camera model trained with train.models.camera.ema_decay says so, with its epochs
    and the average's span; one trained without (a summary from before it) does not."""
    assert "moving average" not in render(FULL)
    s = copy.deepcopy(FULL)
    s["training"]["camera"].update(ema_decay=0.999, epochs=14, best_epoch=9)
    text = " ".join(render(s).split())
    assert (
        "It trains 14 epochs (the others 10), and the weights it keeps are the moving "
        "average of the trained ones (decay 0.999 per step, about 1000 steps; epoch 9 kept;"
    ) in text


def test_summary_training_data_and_forces(tmp_path):
    """The frames behind training against the solver frames; the force spread per height."""
    rows = []
    for sc in ("a", "b"):
        for k, f in enumerate([0.0, 0.5, 1.0, 1.5, 2.0]):  # 5 frames over 3 solver frames
            rows.append(
                {
                    "scene_id": sc,
                    "split": "train",
                    "pitch_deg": 0.0,
                    "frame": k,
                    "fea_frame": f,
                    "fx_N": 1.0 + k,
                }
            )
    rows.append(
        {
            "scene_id": "c",
            "split": "shape",
            "pitch_deg": 0.0,
            "frame": 0,
            "fea_frame": 0.0,
            "fx_N": 0.0,
        }
    )
    pd.DataFrame(rows).to_csv(tmp_path / "manifest.csv", index=False)
    assert training_data(tmp_path / "manifest.csv") == {
        "split": "train",
        "pitch_deg": 0.0,
        "scenes": 2,
        "frames": 10,
        "solver_frames": 6,
        "solver_frames_per_scene": [3, 3],
        "frames_on_solver_frames": 6,
    }
    pd.DataFrame(
        {
            "scene": list("abc"),
            "split": ["train", "train", "shape"],
            "height_mm": [20.0, 20.0, 20.0],
            "fx_final_N": [4.0, 6.0, 9.0],
            "self_contact_max_pairs": [3, 0, 5],
            "self_contact_first_mm": [4.5, None, 6.0],
        }
    ).to_csv(tmp_path / "s.csv", index=False)
    f = fea_forces(tmp_path / "s.csv")
    assert f["force_cv_max_pct"] == pytest.approx(20.0)  # std 1 / mean 5
    assert f["force_spread_max_pct"] == pytest.approx(40.0)
    assert (f["self_contact_scenes"], f["n_scenes_all"], f["self_contact_first_mm"]) == (
        2,
        3,
        [4.5, 6.0],
    )
    h = {
        "epoch": [1, 2, 3],
        "train_loss": [3.0, 2.0, 1.0],
        "val_loss": [2.0, 0.5, 0.7],
        "val_force_rmse_N": [0.3, 0.2, 0.1],
        "train_seconds": 1.0,
        "n_train": 5,
        "n_val": 5,
        "validation_scenes": ["b"],
    }
    t = training_summary(h, tmp_path / "manifest.csv")
    # kept: the lowest validation loss (epoch 2), not the lowest force RMSE (epoch 3)
    assert (t["best_epoch"], t["best_val_force_rmse_N"]) == (2, 0.2)
    assert t["force_mean_N"] == [3.0] and t["force_std_N"] == [pytest.approx(1.5811, abs=1e-4)]
    assert t["ema_decay"] == 0.0  # a history from before the average: none
    assert training_summary({**h, "train_config": {"ema_decay": 0.999}})["ema_decay"] == 0.999
    assert (
        training_summary({**h, "best_epoch": 3, "force_mean_N": [1.0], "force_std_N": [2.0]})[
            "best_epoch"
        ]
        == 3
    )


def test_key_structure_ignores_names_only():
    s = copy.deepcopy(FULL)
    a = key_structure(s)
    mat = s["experiments"]["material"]["all"]["plain"]["groups"]
    mat["rubber"] = mat.pop("steel")
    s["speed"]["stages"].pop("geometry")
    assert key_structure(s) == a
    for m in s["training"].values():  # the models' keys merge: a key that none has
        m.pop("best_epoch")
    assert key_structure(s) != a


def test_sim2real_section_follows_its_numbers():
    """The sim-to-real words: emulated takes, the error's trend and the comparison with
    the paper's MSE, taken from the summary."""
    text = render(FULL)
    r = FULL["sim2real"]
    assert "**emulated** ones above, not recordings" in text
    assert ("The error falls with each context object" in text) == r["error_falls"]
    s = copy.deepcopy(FULL)
    s["sim2real"]["error_falls"] = False
    s["sim2real"]["by_context"]["2"]["mse_N2"] = 0.37  # ten times the paper's 0.037
    text = render(s)
    assert "The error does not fall with each context object" in text
    assert "10.0 times larger than the paper's 0.037" in text.replace("\n", " ")
    assert f"{r['lab_coverage_pct_with_context']:.1f} % of the held-out frames" in render(
        FULL
    ).replace("\n", " ")


def test_the_spread_section_quotes_the_study_or_says_the_figures_are_one_draw():
    text = render(FULL)
    assert "one training's draw" in text and "evaluate.spread.manuscript: true" in text
    s = copy.deepcopy(FULL)
    s["spread"] = {
        "variants": ["s0_auto", "s1_fp32"],
        "default": "s0_auto",
        "runs": {},
        "machines": ["cpu (AMD EPYC), bfloat16", "cpu (AMD EPYC), float32"],
        "rows": [
            {
                "label": "camera: held-out shapes, force NRMSE %",
                "default": 1.25,
                "mean": 1.5,
                "min": 1.25,
                "max": 1.75,
                "range": 0.5,
                "n": 2,
            }
        ],
    }
    text = render(s)
    assert "| camera: held-out shapes, force NRMSE % | 1.25 | 1.50 | 1.25–1.75 |" in text
    assert "2 variants (s0_auto, s1_fp32" in text and "one training's draw" not in text
