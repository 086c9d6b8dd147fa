"""The numeric type of CPU training: bfloat16 autocast where the CPU runs it natively,
float32 elsewhere.

bfloat16 autocast makes a training step faster only on CPUs whose convolutions run it in
hardware (AVX-512 BF16 or AMX); on the others oneDNN emulates it and the step is many
times slower than in float32 (the step times per CPU are in the README and in each
model's ``history.json``). ``train.bf16: auto`` picks from what the CPU offers to the
kernels torch will really use: the ATen dispatch level (``ATEN_CPU_CAPABILITY`` lowers
it) and oneDNN's instruction set (``ONEDNN_MAX_CPU_ISA`` caps it), beside the
hardware flags.
"""
from __future__ import annotations

import os
from dataclasses import dataclass

# oneDNN ISA caps (ONEDNN_MAX_CPU_ISA) under which bf16 convolutions run natively
_ONEDNN_BF16_ISAS = ("AVX512_CORE_BF16", "AVX10_1_512", "AVX512_CORE_AMX", "AVX10_1_512_AMX",
                     "AVX512_CORE_AMX_FP16", "AVX10_1_512_AMX_FP16", "AVX10_2_512",
                     "AVX10_2_512_AMX_2", "ALL")


@dataclass(frozen=True)
class CpuPrecision:
    """What the CPU offers for bfloat16, as torch sees it."""

    aten_capability: str  # torch.backends.cpu.get_cpu_capability(): DEFAULT, AVX2, AVX512, ...
    avx512_bf16: bool  # hardware flag
    amx: bool  # hardware flag (AMX tiles)
    onednn_bf16: bool  # oneDNN will run bf16 kernels (natively or emulated)
    onednn_max_isa: str | None  # ONEDNN_MAX_CPU_ISA, if set

    @property
    def native_bf16(self) -> bool:
        """bfloat16 convolutions run in hardware on the kernels torch will use."""
        isa_ok = self.onednn_max_isa is None or self.onednn_max_isa.upper() in _ONEDNN_BF16_ISAS
        return ("AVX512" in self.aten_capability.upper() and (self.avx512_bf16 or self.amx)
                and self.onednn_bf16 and isa_ok)

    def describe(self) -> str:
        flags = [f for f, on in (("avx512_bf16", self.avx512_bf16), ("amx", self.amx)) if on]
        s = f"ATen {self.aten_capability}, bf16 flags: {', '.join(flags) or 'none'}"
        if self.onednn_max_isa:
            s += f", ONEDNN_MAX_CPU_ISA={self.onednn_max_isa}"
        return s


def cpu_precision() -> CpuPrecision:
    """Read the CPU's bfloat16 support from torch (no timing, no side effects)."""
    import torch

    def flag(name: str) -> bool:
        f = getattr(torch.cpu, name, None)
        return bool(f()) if f is not None else False

    try:
        onednn = bool(torch.ops.mkldnn._is_mkldnn_bf16_supported())
    except (AttributeError, RuntimeError):  # a torch built without oneDNN
        onednn = False
    return CpuPrecision(aten_capability=torch.backends.cpu.get_cpu_capability(),
                        avx512_bf16=flag("_is_avx512_bf16_supported"),
                        amx=flag("_is_amx_tile_supported"), onednn_bf16=onednn,
                        onednn_max_isa=os.environ.get("ONEDNN_MAX_CPU_ISA") or None)


def resolve_bf16(setting: bool | str, cpu: CpuPrecision | None = None) -> tuple[bool, str]:
    """``train.bf16`` (``"auto"``, true or false) -> (use bfloat16 autocast, a one-line
    reason for the log)."""
    if isinstance(setting, str) and setting != "auto":
        raise ValueError(f"train.bf16 must be auto, true or false, not {setting!r}")
    cpu = cpu or cpu_precision()
    native = cpu.native_bf16
    if setting == "auto":
        kind = "bfloat16 autocast" if native else "float32"
        why = "native bfloat16" if native else "no native bfloat16"
        return native, f"{kind} (train.bf16: auto; {why}: {cpu.describe()})"
    if setting and not native:
        return True, ("bfloat16 autocast (train.bf16: true) on a CPU without native bfloat16 "
                      f"({cpu.describe()}): expect steps many times slower than float32")
    return bool(setting), f"{'bfloat16 autocast' if setting else 'float32'} (train.bf16: {str(bool(setting)).lower()}; {cpu.describe()})"


def cpu_name() -> str:
    """The CPU's model name (``/proc/cpuinfo``; ``platform.processor()`` elsewhere)."""
    import platform

    try:
        for line in open("/proc/cpuinfo", encoding="utf-8"):
            if line.startswith("model name"):
                return line.split(":", 1)[1].strip()
    except OSError:
        pass
    return platform.processor() or platform.machine()
