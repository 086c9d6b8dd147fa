"""Numeric type of CPU training: bfloat16 only where the CPU runs it natively."""

import math
import re

import pytest
import yaml

from finray.config import ConfigError, validate_config
from finray.model import NetConfig
from finray.precision import CpuPrecision, cpu_name, cpu_precision, resolve_bf16
from finray.train import TrainConfig, train

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
    assert lines[0].startswith("precision: ") and hist.precision in ("bfloat16", "float32")
    assert (hist.precision == "bfloat16") is cpu_precision().native_bf16
    assert any(line.startswith("step time ") for line in lines)
    # the step times are recorded (their values belong to benchmarks, not to tests)
    assert math.isfinite(hist.step_ms) and math.isfinite(hist.step_cpu_ms)
    assert len(hist.epoch_time_s) == 2
    # a progress line inside each epoch (log_every_s=0) and an end-of-epoch line
    assert any(line.startswith("epoch 1/2: batch ") for line in lines)
    assert any(re.fullmatch(r"epoch 2/2: train loss .*, \d+ s( \(best\))?", line) for line in lines)
