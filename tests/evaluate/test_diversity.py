"""Training on generated objects: the comparison table, the summary's ``diversity`` key
and the manuscript's extension, on small synthetic metrics with known differences."""

import copy
import json

import pandas as pd
import pytest

from finray.config import ConfigError, diversity_models, load_config, validate_config
from finray.evaluate.diversity import GENERATED, METRICS, PAPER, comparison_table, diversity_summary
from finray.evaluate.manuscript import render_text
from finray.evaluate.summary import key_structure

from helpers import DATA, ROOT

TEMPLATE = ROOT / "paper" / "manuscript.md.j2"
FULL = json.loads((DATA / "summary_full.json").read_text())


def _row(test, group, predictor, n, mse, nrmse, r2, stress, ssim, path="shard", frames="all"):
    return {
        "condition": "all",
        "path": path,
        "frames": frames,
        "group": group,
        "predictor": predictor,
        "n": n,
        "mse_N2": mse,
        "rmse_N": mse**0.5,
        "nrmse_pct": nrmse,
        "r2": r2,
        "stress_mse_log": stress,
        "ssim": ssim,
    }


def _metrics(shape_b=0.01):
    """Two test sets as run_experiment writes them: all + groups, both models; the
    with_generated model's MSE on shape group "b" is ``shape_b`` (paper's: 0.02)."""
    shape = pd.DataFrame(
        [
            _row("shape", "all", PAPER, 20, 0.02, 2.0, 0.99, 0.08, 0.90),
            _row("shape", "all", GENERATED, 20, 0.015, 1.5, 0.995, 0.03, 0.95),
            _row("shape", "a", PAPER, 10, 0.02, 2.0, 0.99, 0.08, 0.90),
            _row("shape", "a", GENERATED, 10, 0.02 - 0.005, 1.5, 0.995, 0.03, 0.95),
            _row("shape", "b", PAPER, 10, 0.02, 2.0, 0.99, 0.08, 0.90),
            _row("shape", "b", GENERATED, 10, shape_b, 1.5, 0.995, 0.03, 0.95),
            # another path (the camera's) is not compared
            _row(
                "shape", "all", PAPER, 4, 9.0, 9.0, 0.0, 9.0, 0.0, path="camera", frames="rendered"
            ),
            _row(
                "shape",
                "all",
                GENERATED,
                4,
                1.0,
                1.0,
                0.0,
                1.0,
                0.0,
                path="camera",
                frames="rendered",
            ),
        ]
    )
    material = pd.DataFrame(
        [
            _row("material", "all", PAPER, 6, 0.01, 1.0, 0.99, 0.07, 0.93),
            _row("material", "all", GENERATED, 6, 0.012, 1.1, 0.98, 0.07, 0.92),
            _row("material", "steel", PAPER, 6, 0.01, 1.0, 0.99, 0.07, 0.93),
            _row("material", "steel", GENERATED, 6, 0.012, 1.1, 0.98, 0.07, 0.92),
        ]
    )
    return {"shape": shape, "material": material}


SETUP = {
    "model": "plain",
    "models": {PAPER: "plain_paper_objects", GENERATED: "plain"},
    "n_generated": 60,
    "train_objects": {PAPER: 15, GENERATED: 75},
}


def _training(n_train):
    return {
        "n_train": n_train,
        "n_val": n_train // 10,
        "epochs": 10,
        "best_epoch": 9,
        "train_seconds": 600.0,
    }


def _summary(metrics=None):
    return diversity_summary(
        comparison_table(metrics or _metrics()),
        {PAPER: _training(1000), GENERATED: _training(5000)},
        SETUP,
    )


def test_comparison_table_differences():
    t = comparison_table(_metrics())
    assert list(zip(t["test"], t["group"])) == [
        ("shape", "all"),
        ("shape", "a"),
        ("shape", "b"),
        ("material", "all"),
        ("material", "steel"),
    ]
    assert list(t["n"]) == [20, 10, 10, 6, 6]  # the shard path on all frames only
    shape_all = t.iloc[0]
    assert shape_all["mse_N2_paper_objects"] == 0.02 and shape_all["mse_N2_with_generated"] == 0.015
    assert shape_all["mse_N2_diff"] == pytest.approx(-0.005)
    assert shape_all["nrmse_pct_diff"] == pytest.approx(-0.5)
    assert shape_all["ssim_diff"] == pytest.approx(0.05)
    assert t.iloc[3]["mse_N2_diff"] == pytest.approx(0.002)
    assert {f"{k}_diff" for k in METRICS} <= set(t.columns)


def test_comparison_table_refuses_what_it_cannot_compare():
    m = _metrics()
    m["shape"] = m["shape"][m["shape"]["predictor"] != GENERATED]
    with pytest.raises(ValueError, match=r"^shape/all: no metrics of \['with_generated'\]$"):
        comparison_table(m)
    m = _metrics()
    m["material"].loc[1, "n"] = 5
    with pytest.raises(
        ValueError, match="^material/all: the models were scored on 6 and 5 frames$"
    ):
        comparison_table(m)


def test_summary_says_which_model_is_better():
    s = _summary()
    assert s["n_generated"] == 60 and s["training"][GENERATED]["n_train"] == 5000
    shape, mat = s["tests"]["shape"], s["tests"]["material"]
    assert list(shape["groups"]) == ["a", "b"] and list(mat["groups"]) == ["steel"]
    assert shape["all"]["better"] == {k: True for k in METRICS}  # lower errors, higher R², SSIM
    # material: every force error higher, R² and SSIM lower; the stress MSE equal: not better
    assert mat["all"]["better"] == {k: False for k in METRICS}
    assert mat["all"]["diff"]["mse_N2"] == pytest.approx(0.002)
    # the key structure merges the groups' names (two runs with other objects compare)
    other = copy.deepcopy(s)
    other["tests"]["shape"]["groups"]["c"] = other["tests"]["shape"]["groups"].pop("a")
    assert key_structure({"diversity": other}) == key_structure({"diversity": s})


def render(s):
    return render_text(TEMPLATE, s, {"speed_table": "| speed table |"})


def test_manuscript_extension_with_and_without_the_comparison():
    text = render(FULL)  # the paper's run: no generated objects, one sentence, no table
    ext = text[text.index("## Extension: training on procedurally generated objects") :]
    assert "Not run here: `config/diverse.yaml`" in ext and "|" not in ext
    s = copy.deepcopy(FULL)
    s["diversity"] = _summary()
    ext = render(s)
    ext = ext[ext.index("## Extension") :]
    assert "Not run here" not in ext
    assert "with 60 procedurally generated objects added to the paper's\n15 training objects" in ext
    assert "| paper's objects (`plain_paper_objects`) | 15 | 1000 | 100 | 10 (9) | 10.0 |" in ext
    assert (
        "| held-out shapes | **all** | 20 | 0.0200 / 0.0150 (-0.0050) | 2.00 / 1.50 (-0.50) |"
        in ext
    )
    assert "|  | steel | 6 | 0.0100 / 0.0120 (+0.0020) |" in ext
    # the words follow the numbers: 0.015 vs 0.02 is 1.3 times smaller; 0.012 vs 0.01 1.2 larger
    flat = ext.replace("\n", " ")
    assert (
        "held-out shapes, the force MSE with the generated objects is 1.3 times smaller than without them"
        in flat
    )
    assert "(lower overall, lower in 2 of the 2 shapes)" in flat
    assert (
        "ring materials, the force MSE with the generated objects is 1.2 times larger than without them"
        in flat
    )
    assert "(not lower overall, lower in 0 of the 1 materials)" in flat
    assert (
        "diversity helped in part: the force error is lower on 1 of the 2 test sets and in 2 of the 3 groups"
        in flat
    )
    assert "trained on 5.0 times more frames for the same 10 epochs" in flat


def test_manuscript_extension_verdict_turns_with_the_numbers():
    m = _metrics()
    m["material"].loc[[1, 3], "mse_N2"] = 0.005
    s = copy.deepcopy(FULL)
    s["diversity"] = _summary(m)
    flat = render(s).replace("\n", " ")
    assert (
        "diversity helped: the force error is lower on every test set and in every one of the 3 groups"
        in flat
    )
    # the stress error is not lower on the materials (equal): not claimed
    assert "the stress maps' error is lower on every test set too" not in flat
    m = _metrics(shape_b=0.03)
    for test in m.values():
        test.loc[test["predictor"] == GENERATED, "mse_N2"] = 0.05
    s["diversity"] = _summary(m)
    assert (
        "diversity did not help: the force error is lower on no test set and in none of the 3 groups"
        in render(s).replace("\n", " ")
    )


@pytest.mark.slow
def test_compare_model_config():
    """diverse.yaml compares plain; the paper config nothing; an unknown model is refused."""
    full = load_config(ROOT / "config" / "config.yaml")
    diverse = load_config(ROOT / "config" / "diverse.yaml")
    assert diversity_models(diverse) == ("plain_paper_objects", "plain")
    assert diversity_models(full) is None and full["generated"]["compare_model"] == "plain"
    raw = {"objects": {"c": {"type": "circle", "diameter_mm": 10}}}
    assert (
        diversity_models(validate_config({**raw, "generated": {"count": 2, "compare_model": None}}))
        is None
    )
    assert (
        diversity_models(validate_config({**raw, "generated": {"count": 2, "split": "shape"}}))
        is None
    )
    with pytest.raises(
        ConfigError,
        match=r"^generated.compare_model: 'nope' is not a key of train.models "
        r"\(camera, occlusion, plain\); null: no comparison$",
    ):
        validate_config({**raw, "generated": {"count": 2, "compare_model": "nope"}})
    with pytest.raises(
        ConfigError,
        match="^generated.compare_model: train.models already has 'plain_paper_objects'",
    ):
        validate_config(
            {
                **raw,
                "generated": {"count": 2},
                "train": {"models": {"plain": {}, "plain_paper_objects": {}}},
            }
        )
    # no generated object: the key is not checked (a config may have no plain model)
    validate_config(
        {**raw, "train": {"models": {"other": {}}}, "benchmarks": {"latency_model": "other"}}
    )


def test_run_diversity_scores_both_models_on_every_test_set(scene, tmp_path):
    """End to end on the camera-path fixture's shards: two untrained networks, the
    table's differences are those of the force metrics of the written frames."""
    import torch

    from finray.evaluate.diversity import run_diversity
    from finray.evaluate.metrics import force_metrics
    from finray.model import FinRayNet, NetConfig
    from finray.train import export_torchscript
    from helpers import PREPROCESS

    torch.manual_seed(1)
    net = FinRayNet(NetConfig(in_channels=1, base_channels=4, height=64, width=32, n_forces=2))
    net.set_force_normalisation([2.0, -0.5], [1.0, 0.4])
    net.eval()
    export_torchscript(net, tmp_path / "other.ts", PREPROCESS, ["fx_N", "fy_N"])
    h = {
        "epoch": [1],
        "train_loss": [1.0],
        "val_loss": [1.0],
        "val_force_rmse_N": [0.1],
        "train_seconds": 1.0,
        "n_train": 8,
        "n_val": 2,
        "validation_scenes": ["x"],
    }
    (tmp_path / "history.json").write_text(json.dumps(h))
    hist = str(tmp_path / "history.json")
    s = run_diversity(
        tmp_path / "diversity",
        {"shape": {"shards": scene["shards"], "group_col": "height_mm"}},
        (64, 32),
        {PAPER: str(scene["model"]), GENERATED: str(tmp_path / "other.ts")},
        {PAPER: hist, GENERATED: hist},
        SETUP,
        log=lambda *_: None,
    )
    assert json.loads((tmp_path / "diversity" / "summary.json").read_text()) == s
    table = pd.read_csv(tmp_path / "diversity" / "table.csv")
    assert list(table["group"].astype(str)) == ["all", "20.0", "30.0"] and list(table["n"]) == [
        10,
        5,
        5,
    ]
    f = pd.read_csv(tmp_path / "diversity" / "shape" / "frames.csv")
    a, b = (force_metrics(f["fx_N"], f[f"pred_{p}"]) for p in (PAPER, GENERATED))
    assert s["tests"]["shape"]["all"]["diff"]["mse_N2"] == pytest.approx(
        b["mse_N2"] - a["mse_N2"], rel=1e-4
    )
    assert s["tests"]["shape"]["all"]["diff"]["mse_N2"] != 0  # two different networks
    assert s["training"][PAPER]["n_train"] == 8 and s["n_generated"] == 60
