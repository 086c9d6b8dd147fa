"""The training-speed study's scripts (studies/training_speed) run on the default config,
and the profile's FLOPs per convolution agree with torch's FLOP counter."""

import importlib
import sys
from pathlib import Path

import pytest

STUDY = Path(__file__).resolve().parents[2] / "studies" / "training_speed"


@pytest.fixture(scope="module")
def study():
    sys.path.insert(0, str(STUDY))
    try:
        yield importlib.import_module("step_cost"), importlib.import_module("profile_step")
    finally:
        sys.path.remove(str(STUDY))


def test_step_cost_runs_the_camera_models_step(study):
    step_cost, _ = study
    from finray.config import load_config

    cfg = load_config(step_cost.ROOT / "config" / "config.yaml")
    # the camera model's entry holds training keys (epochs) beside its augmentation
    v = step_cost._setup(cfg, 32, 16, False, True, "per-tensor")
    phases = step_cost._step(v, False)
    assert set(phases) == {"augment", "forward_backward", "adam"}
    assert all(t > 0 for t in phases.values())


def test_profile_counts_every_convolution_and_its_flops(study):
    step_cost, profile_step = study
    from finray.config import load_config

    cfg = load_config(step_cost.ROOT / "config" / "config.yaml")
    p = profile_step.profile_step(False, steps=1, warmup=1, frames=32)
    by_res = p["conv_by_output"]
    # 64x32 input: the encoder's and decoder's stages at four resolutions, 21 convolutions
    assert sorted(by_res, key=lambda r: -int(r.split("x")[0])) == ["64x32", "32x16", "16x8", "8x4"]
    assert sum(r["layers"] for r in by_res.values()) == 21
    conv = sum(r["forward_flop"] + r["backward_flop"] for r in by_res.values())
    total = step_cost.flops_per_step(cfg, 16)  # convolutions and matrix products
    assert 0.95 * total < conv <= total
    assert set(p["phases_ms"]) == set(profile_step.PHASES)
