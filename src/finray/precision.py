"""The device and numeric type of training and inference: the GPU when asked for (or,
with ``auto``, when torch sees one), else the CPU; bfloat16 autocast where the device
runs it natively, float32 elsewhere.

bfloat16 autocast can make a training step faster only on CPUs whose convolutions run it
in hardware (AVX-512 BF16 or AMX); on the others oneDNN emulates it and the step is many
times slower than in float32 (the step times per CPU are in docs/studies/run-cost.md and in each
model's ``history.json``). Hardware is not enough: with AVX-512 BF16 but no AMX a
bfloat16 step can be slower than a float32 one, so on such a CPU the training times both
(:mod:`finray.train.precision_trial`) and this module only says whether bfloat16 is worth
timing. ``train.bf16: auto`` reads what the CPU offers to the kernels torch will really
use: the ATen dispatch level (``ATEN_CPU_CAPABILITY`` lowers
it) and oneDNN's instruction set (``ONEDNN_MAX_CPU_ISA`` caps it), beside the
hardware flags. On a GPU, ``auto`` means bfloat16 where the GPU has native bfloat16
units (NVIDIA Ampere and later).
"""

from __future__ import annotations

import os
from dataclasses import dataclass

from .errors import DeviceError

# oneDNN ISA caps (ONEDNN_MAX_CPU_ISA) under which bf16 convolutions run natively
_ONEDNN_BF16_ISAS = (
    "AVX512_CORE_BF16",
    "AVX10_1_512",
    "AVX512_CORE_AMX",
    "AVX10_1_512_AMX",
    "AVX512_CORE_AMX_FP16",
    "AVX10_1_512_AMX_FP16",
    "AVX10_2_512",
    "AVX10_2_512_AMX_2",
    "ALL",
)


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
        return (
            "AVX512" in self.aten_capability.upper()
            and (self.avx512_bf16 or self.amx)
            and self.onednn_bf16
            and isa_ok
        )

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
    return CpuPrecision(
        aten_capability=torch.backends.cpu.get_cpu_capability(),
        avx512_bf16=flag("_is_avx512_bf16_supported"),
        amx=flag("_is_amx_tile_supported"),
        onednn_bf16=onednn,
        onednn_max_isa=os.environ.get("ONEDNN_MAX_CPU_ISA") or None,
    )


@dataclass(frozen=True)
class GpuPrecision:
    """What a CUDA GPU offers for bfloat16, as torch sees it."""

    name: str  # torch.cuda.get_device_name()
    native_bf16: bool  # bfloat16 in hardware (Ampere and later), not emulated

    def describe(self) -> str:
        return f"GPU {self.name}, bf16 {'native' if self.native_bf16 else 'not native'}"


def gpu_precision(device=None) -> GpuPrecision:
    """Read a CUDA GPU's bfloat16 support from torch (``device``: a torch device)."""
    import torch

    with torch.cuda.device(device):
        try:
            native = bool(torch.cuda.is_bf16_supported(including_emulation=False))
        except TypeError:  # torch before 2.3 has no including_emulation
            native = bool(torch.cuda.is_bf16_supported())
        return GpuPrecision(torch.cuda.get_device_name(), native)


def resolve_bf16(
    setting: bool | str,
    cpu: CpuPrecision | None = None,
    device=None,
    gpu: GpuPrecision | None = None,
) -> tuple[bool, str]:
    """``train.bf16`` (``"auto"``, true or false) -> (use bfloat16 autocast, a one-line
    reason for the log), for ``device`` (a torch device or its name; the CPU if None).
    ``cpu``/``gpu``: the hardware's description (read from torch if None)."""
    if isinstance(setting, str) and setting != "auto":
        raise ValueError(f"train.bf16 must be auto, true or false, not {setting!r}")
    on_gpu = device is not None and _device_type(device) == "cuda"
    hw = (gpu or gpu_precision(device)) if on_gpu else (cpu or cpu_precision())
    where = "GPU" if on_gpu else "CPU"
    native = hw.native_bf16
    if setting == "auto":
        kind = "bfloat16 autocast" if native else "float32"
        why = "native bfloat16" if native else "no native bfloat16"
        return native, f"{kind} (train.bf16: auto; {why}: {hw.describe()})"
    if setting and not native:
        return True, (
            f"bfloat16 autocast (train.bf16: true) on a {where} without native bfloat16 "
            f"({hw.describe()}): expect steps many times slower than float32"
        )
    return (
        bool(setting),
        f"{'bfloat16 autocast' if setting else 'float32'} (train.bf16: {str(bool(setting)).lower()}; {hw.describe()})",
    )


#: Values of ``train.device`` and of ``Predictor(device=...)``.
DEVICES = ("auto", "cpu", "cuda")


def _device_type(device) -> str:
    return device if isinstance(device, str) else device.type


def resolve_device(name: str = "auto", what: str = "device"):
    """``auto`` | ``cpu`` | ``cuda`` -> a ``torch.device``: ``auto`` is the GPU when torch
    sees one, else the CPU. ``cuda`` without a GPU raises :class:`DeviceError` (one line
    naming ``what``, e.g. ``train.device``), before any work."""
    import torch

    if name not in DEVICES:
        raise DeviceError(f"{what} must be one of {', '.join(DEVICES)}, not {name!r}")
    if name == "cpu" or (name == "auto" and not torch.cuda.is_available()):
        return torch.device("cpu")
    if not torch.cuda.is_available():
        build = (
            f"built with CUDA {torch.version.cuda}, but no GPU is visible (driver, "
            "CUDA_VISIBLE_DEVICES?)"
            if torch.version.cuda
            else "a CPU-only build"
        )
        raise DeviceError(
            f"{what} is cuda, but torch {torch.__version__} sees no CUDA GPU "
            f"({build}); use auto or cpu"
        )
    return torch.device("cuda", torch.cuda.current_device())


def device_name(device) -> str:
    """What a device is, for logs and benchmark files: ``cpu (<model name>)`` or
    ``cuda:0 (<GPU name>)``."""
    import torch

    device = torch.device(device)
    if device.type == "cuda":
        return f"{device} ({torch.cuda.get_device_name(device)})"
    return f"cpu ({cpu_name()})"


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
