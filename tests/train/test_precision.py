"""Numeric type of CPU training: bfloat16 only where the CPU runs it natively, and with
``auto`` only where it is measured faster."""

import math
import re

import pytest
import torch
import yaml

from finray.config import ConfigError, validate_config
from finray.model import FinRayNet, NetConfig
from finray.precision import CpuPrecision, cpu_name, cpu_precision, resolve_bf16
from finray.train import TrainConfig, train
from finray.train import loop
from finray.train.precision_trial import MARGIN, PrecisionTrial, time_precisions

from helpers import ROOT, toy


ZEN4 = CpuPrecision("AVX512", avx512_bf16=True, amx=False, onednn_bf16=True, onednn_max_isa=None)
SAPPHIRE = CpuPrecision("AVX512", avx512_bf16=True, amx=True, onednn_bf16=True, onednn_max_isa=None)
SKYLAKE_X = CpuPrecision(
    "AVX512", avx512_bf16=False, amx=False, onednn_bf16=True, onednn_max_isa=None
)
EPYC_AVX2 = CpuPrecision(
    "AVX2", avx512_bf16=False, amx=False, onednn_bf16=False, onednn_max_isa=None
)
# a bf16 CPU whose kernels are capped to AVX2 (ATEN_CPU_CAPABILITY / ONEDNN_MAX_CPU_ISA)
CAPPED = CpuPrecision("AVX2", avx512_bf16=True, amx=False, onednn_bf16=False, onednn_max_isa="AVX2")
CAPPED_ONEDNN = CpuPrecision(
    "AVX512", avx512_bf16=True, amx=False, onednn_bf16=True, onednn_max_isa="AVX512_CORE"
)


@pytest.mark.parametrize(
    "cpu, native",
    [
        (ZEN4, True),
        (SAPPHIRE, True),
        (SKYLAKE_X, False),
        (EPYC_AVX2, False),
        (CAPPED, False),
        (CAPPED_ONEDNN, False),
    ],
)
def test_auto_uses_bf16_only_where_native(cpu, native):
    use, why = resolve_bf16("auto", cpu)
    assert use is native
    assert why.startswith("bfloat16 autocast" if native else "float32")
    assert "train.bf16: auto" in why and cpu.aten_capability in why


def test_explicit_setting_wins_and_warns_when_emulated():
    assert resolve_bf16(False, ZEN4)[0] is False
    use, why = resolve_bf16(True, EPYC_AVX2)
    assert use is True and "without native bfloat16" in why and "slower" in why
    assert "slower" not in resolve_bf16(True, ZEN4)[1]


def test_bad_setting_is_refused():
    with pytest.raises(ValueError, match="train.bf16 must be auto, true or false, not 'fast'"):
        resolve_bf16("fast", ZEN4)


def test_this_machine_is_read():
    cpu = cpu_precision()
    assert cpu.aten_capability
    assert resolve_bf16("auto", cpu)[0] is cpu.native_bf16
    assert cpu_name()


def test_config_accepts_auto_true_false_and_refuses_others():
    smoke = yaml.safe_load((ROOT / "config" / "smoke.yaml").read_text())
    for value, ok in (("auto", True), (True, True), (False, True), ("fast", False)):
        cfg = {**smoke, "train": {**smoke.get("train", {}), "bf16": value}}
        if ok:
            assert validate_config(cfg, base_dir=ROOT)["train"]["bf16"] == value
        else:
            with pytest.raises(ConfigError, match="train.bf16"):
                validate_config(cfg, base_dir=ROOT)


def test_training_logs_its_precision_step_time_and_epochs():
    x, s, f = toy(64)
    lines = []
    _, hist = train(
        x,
        s,
        f,
        (x[:16], s[:16], f[:16]),
        NetConfig(height=32, width=16, base_channels=4),
        TrainConfig(epochs=2, batch_size=16, progress=False, log_every_s=0.0, contact_weight=0.0),
        log=lines.append,
    )
    precision = next(line for line in lines if line.startswith("precision: "))
    assert hist.precision in ("bfloat16", "float32")
    if cpu_precision().native_bf16:  # the faster type, measured (test below)
        trial = PrecisionTrial(**hist.precision_trial_ms)
        assert (hist.precision == "bfloat16") is trial.bf16
        assert precision == f"precision: {trial.describe()}"
    else:  # no bfloat16 hardware: float32, nothing timed
        assert hist.precision == "float32" and hist.precision_trial_ms is None
    assert any(line.startswith("step time ") for line in lines)
    # the step times are recorded (their values belong to benchmarks, not to tests)
    assert math.isfinite(hist.step_ms) and math.isfinite(hist.step_cpu_ms)
    assert len(hist.epoch_time_s) == 2
    # a progress line inside each epoch (log_every_s=0) and an end-of-epoch line
    assert any(line.startswith("epoch 1/2: batch ") for line in lines)
    assert any(re.fullmatch(r"epoch 2/2: train loss .*, \d+ s( \(best\))?", line) for line in lines)


def test_auto_takes_the_type_measured_faster_by_a_margin():
    assert PrecisionTrial(float32_ms=100.0, bfloat16_ms=60.0, steps=8).bf16
    assert PrecisionTrial(float32_ms=100.0, bfloat16_ms=100.0 * (1 - MARGIN), steps=8).bf16
    # a near tie or a slower bfloat16 (AVX-512 BF16 without AMX) keeps float32
    assert not PrecisionTrial(float32_ms=100.0, bfloat16_ms=97.0, steps=8).bf16
    assert not PrecisionTrial(float32_ms=104.8, bfloat16_ms=116.5, steps=8).bf16
    why = PrecisionTrial(float32_ms=104.8, bfloat16_ms=116.5, steps=8).describe()
    assert why.startswith("float32 (train.bf16: auto; measured")
    assert "float32 104.8 ms, bfloat16 116.5 ms of CPU per step" in why


def test_the_trial_times_copies_and_leaves_the_network_as_it_was():
    net = FinRayNet(NetConfig(height=32, width=16, base_channels=4))
    before = {k: v.clone() for k, v in net.state_dict().items()}
    x = torch.rand(8, 3, 32, 16)
    calls = []

    def step(m, bf16):
        calls.append(bf16)
        with loop._autocast(bf16, torch.device("cpu")):
            s, f = m.forward_normalised(x)
        return s.float().mean() + f.float().mean()

    trial = time_precisions(net, step, lr=1e-3, warmup=1, steps=2)
    assert calls == [False, True] * 3  # alternating, warm-up included
    assert trial.steps == 2 and trial.float32_ms > 0 and trial.bfloat16_ms > 0
    after = net.state_dict()
    assert all(torch.equal(before[k], after[k]) for k in before)


def test_a_measured_choice_trains_as_the_pinned_type(monkeypatch):
    """The trial (forced here, as on a CPU with bfloat16 hardware) changes nothing but
    the choice: the training equals one pinned to the type it chose."""
    monkeypatch.setattr(
        loop,
        "resolve_bf16",
        lambda setting, device: (True, "hardware") if setting == "auto" else (setting, "pinned"),
    )
    x, s, f = toy(64)
    cfg = dict(epochs=1, batch_size=16, progress=False, contact_weight=0.0)
    net = NetConfig(height=32, width=16, base_channels=4)
    model, hist = train(x, s, f, None, net, TrainConfig(**cfg), log=lambda m: None)
    assert set(hist.precision_trial_ms) == {"float32_ms", "bfloat16_ms", "steps"}
    pinned = hist.precision == "bfloat16"
    model2, hist2 = train(x, s, f, None, net, TrainConfig(**cfg, bf16=pinned), log=lambda m: None)
    assert hist2.precision_trial_ms is None and hist2.precision == hist.precision
    assert hist.train_loss == hist2.train_loss
    assert all(
        torch.equal(a, b) for a, b in zip(model.state_dict().values(), model2.state_dict().values())
    )
