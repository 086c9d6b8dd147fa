"""Devices: train.device / Predictor(device=...) resolution, the one-line refusal of
cuda without a GPU, GPU bfloat16 choice, exports free of device constants, and the
device benchmark (on the CPU: tests never need a GPU)."""

import json
import re

import pytest
import torch
import yaml

from finray.config import ConfigError, validate_config
from finray.model import FinRayNet, NetConfig
from finray.precision import DeviceError, GpuPrecision, resolve_bf16, resolve_device
from finray.predict import DeviceInputError, InputError, Predictor
from finray.train import (
    TrainConfig,
    _autocast,
    export_onnx,
    export_torchscript,
    train,
    train_from_shards,
)

from helpers import CFG, ROOT, toy

HAS_GPU = torch.cuda.is_available()
no_gpu = pytest.mark.skipif(HAS_GPU, reason="checks the refusal of cuda on a machine without a GPU")
NO_CUDA = (
    re.escape(f"is cuda, but torch {torch.__version__} sees no CUDA GPU (")
    + r"[^\n]+\); use auto or cpu"
)
NET = NetConfig(height=32, width=16, base_channels=4)


def test_names_resolve_to_torch_devices():
    assert resolve_device("cpu") == torch.device("cpu")
    assert resolve_device("auto").type == ("cuda" if HAS_GPU else "cpu")
    with pytest.raises(
        DeviceError, match=r"^train.device must be one of auto, cpu, cuda, not 'gpu'$"
    ):
        resolve_device("gpu", "train.device")


@no_gpu
def test_cuda_without_a_gpu_is_one_clear_line():
    with pytest.raises(DeviceError, match="^train.device " + NO_CUDA + "$") as exc:
        resolve_device("cuda", "train.device")
    assert "\n" not in str(exc.value)
    assert isinstance(exc.value, ValueError)


@no_gpu
def test_training_refuses_cuda_before_any_work(tmp_path):
    x, s, f = toy(32)
    lines = []
    with pytest.raises(DeviceError, match="^train.device " + NO_CUDA + "$"):
        train(x, s, f, None, NET, TrainConfig(**CFG, device="cuda"), log=lines.append)
    assert lines == []  # nothing logged: it stopped before seeding, precision, data
    # from shards: refused before the shards are read (these do not exist)
    with pytest.raises(DeviceError, match="^train.device " + NO_CUDA + "$"):
        train_from_shards(
            [tmp_path / "missing.npz"],
            tmp_path / "out",
            NET,
            TrainConfig(**CFG, device="cuda"),
            None,
        )
    assert not (tmp_path / "out").exists()


def test_training_refuses_a_frame_stride_below_one_before_any_work(tmp_path):
    with pytest.raises(ValueError, match="^train.frame_every must be >= 1, got 0$"):
        train_from_shards(
            [tmp_path / "missing.npz"],
            tmp_path / "out",
            NET,
            TrainConfig(**CFG, device="cpu"),
            None,
            frame_every=0,
        )
    assert not (tmp_path / "out").exists()


@pytest.mark.skipif(HAS_GPU, reason="auto is the GPU there")
def test_cpu_and_auto_train_alike_on_a_cpu_machine():
    x, s, f = toy(64)
    runs = [
        # one type for both: `auto` may time the toy network's two types as a tie either way
        train(x, s, f, None, NET, TrainConfig(**CFG, device=d, bf16=False), log=lambda m: None)
        for d in ("cpu", "auto")
    ]
    assert runs[0][1].train_loss == runs[1][1].train_loss
    assert runs[0][1].device.startswith("cpu (")
    assert next(runs[0][0].parameters()).device.type == "cpu"


def test_autocast_follows_the_device():
    with _autocast(True, torch.device("cpu")):
        assert torch.is_autocast_enabled("cpu") and not torch.is_autocast_enabled("cuda")
        assert torch.get_autocast_dtype("cpu") == torch.bfloat16
    assert not torch.is_autocast_enabled("cpu")


def test_gpu_bf16_follows_the_gpu():
    ampere = GpuPrecision("NVIDIA A100", native_bf16=True)
    turing = GpuPrecision("NVIDIA T4", native_bf16=False)
    use, why = resolve_bf16("auto", device="cuda", gpu=ampere)
    assert use is True and why.startswith("bfloat16 autocast") and "NVIDIA A100" in why
    use, why = resolve_bf16("auto", device=torch.device("cuda", 0), gpu=turing)
    assert use is False and why.startswith("float32") and "NVIDIA T4" in why
    use, why = resolve_bf16(True, device="cuda", gpu=turing)
    assert use is True and "on a GPU without native bfloat16" in why
    assert resolve_bf16(False, device="cuda", gpu=ampere)[0] is False


def test_config_key_defaults_to_auto_and_refuses_others():
    smoke = yaml.safe_load((ROOT / "config" / "smoke.yaml").read_text())
    assert validate_config(smoke, base_dir=ROOT)["train"]["device"] == "auto"
    for value in ("cpu", "cuda"):
        cfg = {**smoke, "train": {**smoke.get("train", {}), "device": value}}
        assert validate_config(cfg, base_dir=ROOT)["train"]["device"] == value
    cfg = {**smoke, "train": {**smoke.get("train", {}), "device": "gpu"}}
    with pytest.raises(ConfigError, match="train.device"):
        validate_config(cfg, base_dir=ROOT)
    # the config's settings on every device (the paper's batch and epochs; the cosine's
    # peak at 4x the paper's constant rate, docs/studies/seeds.md "Seeds, numeric types and what to expect")
    full = yaml.safe_load((ROOT / "config" / "config.yaml").read_text())["train"]
    assert (full["device"], full["batch_size"], full["lr"], full["epochs"]) == (
        "auto",
        16,
        4e-4,
        10,
    )


@pytest.fixture(scope="module")
def exported(tmp_path_factory):
    torch.manual_seed(0)
    net = FinRayNet(NetConfig(in_channels=1, base_channels=4, height=64, width=32)).eval()
    d = tmp_path_factory.mktemp("model")
    export_torchscript(net, d / "model.ts")
    export_onnx(net, d / "model.onnx")
    return d / "model.ts"


def test_torchscript_export_has_no_device_constants(exported):
    """A TorchScript traced on the CPU loads on a GPU (map_location) only if no node
    names a device."""
    ts = torch.jit.load(str(exported))
    for graph in (ts.graph, ts.force.graph):
        assert not re.search(r"\bcpu\b|Device", str(graph))


def test_predictor_on_the_cpu_is_unchanged(exported):
    x = torch.rand(2, 1, 64, 32).numpy()
    default = Predictor(exported)
    cpu = Predictor(exported, device="cpu")
    assert cpu.device == torch.device("cpu") and cpu.backend == "onnx"
    if not HAS_GPU:
        assert default.device == torch.device("cpu") and default.backend == "onnx"
    ts = Predictor(exported, backend="torchscript", device="cpu")
    assert (abs(ts.run_force(x) - cpu.run_force(x)) < 1e-4).all()


@no_gpu
@pytest.mark.parametrize("backend", ["auto", "onnx", "torchscript"])
def test_predictor_refuses_cuda_without_a_gpu(exported, backend):
    with pytest.raises(DeviceInputError, match="^device " + NO_CUDA + "$") as exc:
        Predictor(exported, backend=backend, device="cuda")
    assert isinstance(exc.value, InputError) and isinstance(exc.value, DeviceError)


@no_gpu
def test_finray_predict_device_cuda_is_one_line(exported, tmp_path, capsys):
    from finray.cli import main

    img = tmp_path / "frame.png"
    img.write_bytes(b"")  # never read: the device is refused first
    assert (
        main(
            [
                "predict",
                "--model",
                str(exported),
                str(img),
                "--out",
                str(tmp_path / "o"),
                "--device",
                "cuda",
            ]
        )
        == 2
    )
    err = capsys.readouterr().err
    assert re.fullmatch("finray predict: device " + NO_CUDA + "\n", err)
    assert not (tmp_path / "o").exists()


def test_device_benchmark_runs_on_the_cpu(tmp_path):
    from finray.benchmarks.device import main

    out = tmp_path / "device.json"
    assert (
        main(
            [
                "--out",
                str(out),
                "--device",
                "cpu",
                "--frames",
                "32",
                "--calls",
                "3",
                "--repeats",
                "1",
            ]
        )
        == 0
    )
    r = json.loads(out.read_text())
    assert r["device"] == "cpu" and r["device_name"].startswith("cpu (")
    assert r["model"] is None and r["net"]["height"] == 64 and r["net"]["width"] == 32
    t = r["train"]
    assert (t["frames"], t["batch_size"], t["lr"]) == (32, 16, 1e-4)
    assert t["epoch_s"] > 0 and t["step_ms"] > 0
    assert t["full_epoch_estimate_s"] == pytest.approx(t["step_ms"] * (18204 // 16) / 1e3)
    i = r["inference"]
    assert i["device"] == "cpu" and i["backend"] == "onnx" and i["n_calls"] == 3
    assert 0 < i["force_ms"] and 0 < i["full_ms"]


def test_device_benchmark_takes_a_checkpoint_and_refuses_bad_input(tmp_path, capsys):
    from finray.benchmarks.device import main
    from finray.train import save_checkpoint

    x, s, f = toy(32)
    x = x[:, :1]
    model, hist = train(
        x,
        s,
        f,
        None,
        NetConfig(in_channels=1, height=32, width=16, base_channels=4),
        TrainConfig(**CFG),
        log=lambda m: None,
    )
    save_checkpoint(model, hist, tmp_path / "model.pt")
    out = tmp_path / "device.json"
    assert (
        main(
            [
                "--out",
                str(out),
                "--model",
                str(tmp_path / "model.pt"),
                "--device",
                "cpu",
                "--frames",
                "32",
                "--calls",
                "2",
                "--repeats",
                "1",
            ]
        )
        == 0
    )
    r = json.loads(out.read_text())
    assert (r["net"]["base_channels"], r["net"]["height"], r["net"]["n_forces"]) == (4, 32, 1)
    assert main(["--out", str(out), "--model", str(tmp_path / "none.pt")]) == 2
    assert capsys.readouterr().err.endswith(f"no model checkpoint at {tmp_path / 'none.pt'}\n")
    if not HAS_GPU:
        assert main(["--out", str(tmp_path / "x.json"), "--device", "cuda"]) == 2
        assert re.fullmatch(
            "finray.benchmarks.device: --device " + NO_CUDA + "\n", capsys.readouterr().err
        )
        assert not (tmp_path / "x.json").exists()
