"""Model files prove what they are (issue 55): a checkpoint is read with
``weights_only=True`` (one whose unpickling would run code is refused unread), the
settings beside a model (``model.ts.json``) keep the SHA-256 of its files and are checked
against them and against the network before use; each refusal is one line, exit code 2,
and no --out."""

import json
import os
import re
import shutil
from pathlib import Path

import pytest
import torch

from finray.cli import main
from finray.errors import ModelError
from finray.model import FinRayNet, NetConfig
from finray.train import History, export_onnx, export_torchscript, load_checkpoint
from finray.train.export import save_checkpoint

from helpers import PREPROCESS

SRC = Path(__file__).resolve().parents[2] / "src" / "finray"


def _net(height: int, width: int, base: int = 4) -> FinRayNet:
    torch.manual_seed(0)
    return FinRayNet(
        NetConfig(in_channels=1, base_channels=base, height=height, width=width)
    ).eval()


@pytest.fixture(scope="module")
def models(tmp_path_factory):
    """Two small networks (64 x 32 and 32 x 32 inputs), each exported to model.pt,
    model.ts (+ .json) and ONNX in its own folder."""
    out = {}
    for name, (h, w, base) in {"a": (64, 32, 4), "b": (32, 32, 8)}.items():
        d = tmp_path_factory.mktemp(name)
        net = _net(h, w, base)
        save_checkpoint(net, History(), d / "model.pt")
        export_torchscript(net, d / "model.ts", PREPROCESS)
        export_onnx(net, d / "model.onnx")
        out[name] = d
    return out


def one_line(capsys, prefix: str) -> str:
    err = capsys.readouterr().err
    lines = [ln for ln in err.splitlines() if ln.strip()]
    assert len(lines) == 1 and lines[0].startswith(prefix), err
    assert "Traceback" not in err
    return lines[0]


class _RunsCode:
    """An object whose unpickling calls os.system (what weights_only=False would run)."""

    def __init__(self, marker: Path):
        self.marker = marker

    def __reduce__(self):
        return (os.system, (f"touch {self.marker}",))


def test_no_torch_load_runs_code():
    """No torch.load of the package may unpickle arbitrary objects."""
    hits = [
        f"{p.relative_to(SRC)}:{k + 1}"
        for p in SRC.rglob("*.py")
        for k, line in enumerate(p.read_text().splitlines())
        if re.search(r"weights_only\s*=\s*False", line)
    ]
    assert hits == []


def test_a_checkpoint_that_would_run_code_is_refused_unread(models, tmp_path, capsys):
    marker = tmp_path / "marker"
    ck = torch.load(models["a"] / "model.pt", weights_only=True)
    ck["extra"] = {"payload": _RunsCode(marker)}
    d = tmp_path / "m"
    d.mkdir()
    torch.save(ck, d / "model.pt")
    shutil.copy(models["a"] / "model.ts.json", d / "model.ts.json")
    with pytest.raises(ModelError, match="refused unread: loading them could run code"):
        load_checkpoint(d / "model.pt")
    out = tmp_path / "cal.json"
    argv = ["calibrate", str(tmp_path / "take"), "--model", str(d / "model.pt")]
    assert main([*argv, "--out", str(out)]) == 2
    msg = one_line(capsys, "finray calibrate: ")
    assert "is not a finray model checkpoint (model.pt): it holds objects that are not" in msg
    assert not marker.exists()  # nothing of it ran
    assert sorted(p.name for p in tmp_path.iterdir()) == ["m"]  # no --out, no temporary


def test_checkpoints_hold_plain_data_and_come_back(models):
    model, ck = load_checkpoint(models["a"] / "model.pt")
    assert model.cfg.height == 64 and isinstance(ck["net_config"]["hidden"], list)
    meta = json.loads((models["a"] / "model.ts.json").read_text())
    assert set(meta["sha256"]) == {"torchscript", "checkpoint", "onnx", "onnx_force", "settings"}


@pytest.mark.parametrize("kind", ["empty", "text", "list"])
def test_calibrate_refuses_a_model_or_no_context_file_that_is_not_one(
    models, tmp_path, capsys, kind
):
    """``calibrate --model empty.pt`` (was EOFError) and ``--no-context empty.pt`` (was
    exit 0 with outputs: the file was not read with sim_replay_frames 0)."""
    bad = tmp_path / "bad.pt"
    if kind == "empty":
        bad.write_bytes(b"")
    elif kind == "text":
        bad.write_text("not a checkpoint\n")
    else:
        torch.save([1, 2], bad)
    shutil.copy(models["a"] / "model.ts.json", tmp_path / "bad.ts.json")
    take, out = str(tmp_path / "take"), str(tmp_path / "c" / "cal.json")
    assert main(["calibrate", take, "--model", str(bad), "--out", out]) == 2
    assert (
        f"{bad} is not a finray model checkpoint (model.pt) ("
        in one_line(capsys, "finray calibrate: ")
        or kind == "list"
    )  # a list: "(it holds a list)"
    argv = ["calibrate", take, "--model", str(models["a"] / "model.pt"), "--no-context", str(bad)]
    assert main([*argv, "--out", out]) == 2
    msg = one_line(capsys, "finray calibrate: ")
    assert f"{bad} is not a no-context fit (no_context.pt)" in msg
    assert not (tmp_path / "c").exists()


def test_calibrate_refuses_settings_of_another_network(models, tmp_path, capsys):
    d = tmp_path / "m"
    shutil.copytree(models["a"], d)
    shutil.copy(models["b"] / "model.ts.json", d / "model.ts.json")
    out = tmp_path / "c" / "cal.json"
    assert main(["calibrate", "take", "--model", str(d / "model.pt"), "--out", str(out)]) == 2
    msg = one_line(capsys, "finray calibrate: ")
    assert "model.ts.json describes another network than the model's (" in msg
    assert not out.parent.exists()


def test_predict_refuses_a_file_that_is_not_a_model(tmp_path, capsys, render_png):
    """``predict --model notmodel.ts`` with settings that are not a model's (was
    KeyError: 'height')."""
    bad = tmp_path / "notmodel.ts"
    bad.write_text("hello\n")
    out = tmp_path / "out"
    for meta in ["{}", '{"height": "64", "width": 32}', "[1, 2]"]:
        (tmp_path / "notmodel.ts.json").write_text(meta)
        assert main(["predict", "--model", str(bad), str(render_png), "--out", str(out)]) == 2
        assert "notmodel.ts.json is not a model's settings (" in one_line(
            capsys, "finray predict: "
        )
    assert not out.exists() and not list(tmp_path.glob("out.part-*"))


@pytest.mark.parametrize("backend", ["torchscript", "onnx"])
@pytest.mark.parametrize("hashes", [True, False])
def test_predict_refuses_the_settings_of_another_network(
    models, tmp_path, capsys, render_png, backend, hashes
):
    """model.ts.json of another network beside a model (was four tracebacks: a shape
    mismatch, a zero-size reduction, list indices, an ONNX Runtime input error): with
    the hashes, refused by them; without (an old export), by the network's run on the
    settings' input."""
    d = tmp_path / "m"
    shutil.copytree(models["a"], d)
    meta = json.loads((models["b"] / "model.ts.json").read_text())
    if not hashes:
        del meta["sha256"]
    (d / "model.ts.json").write_text(json.dumps(meta))
    out = tmp_path / "out"
    argv = ["predict", "--model", str(d / "model.ts"), str(render_png), "--out", str(out)]
    assert main([*argv, "--backend", backend]) == 2
    msg = one_line(capsys, "finray predict: ")
    if hashes:
        assert "is not the model that model.ts.json describes (its SHA-256 differs" in msg
    else:
        assert "does not run on the input that model.ts.json describes (32x32)" in msg
    assert not out.exists() and not list(tmp_path.glob("out.part-*"))


def test_predict_refuses_force_names_that_do_not_fit_the_outputs(models, tmp_path, capsys):
    """Settings that name two forces for a network of one: its outputs' shape differs."""
    from finray.predict import Predictor

    d = tmp_path / "m"
    shutil.copytree(models["a"], d)
    meta = json.loads((d / "model.ts.json").read_text())
    meta["forces"] = ["fx_N", "fy_N"]
    del meta["sha256"]
    (d / "model.ts.json").write_text(json.dumps(meta))
    with pytest.raises(ModelError, match=r"forces has shape \(1, 1\), not the \(1, 2\)"):
        Predictor(d / "model.ts", backend="torchscript")


def test_an_old_export_without_hashes_runs_with_a_note(models, tmp_path):
    """Settings exported before the hashes were kept: taken, with a note that says how to
    have them checked (export again)."""
    from finray.predict import Predictor

    d = tmp_path / "m"
    shutil.copytree(models["a"], d)
    meta = json.loads((d / "model.ts.json").read_text())
    del meta["sha256"]
    (d / "model.ts.json").write_text(json.dumps(meta))
    p = Predictor(d / "model.ts", backend="torchscript")
    assert any("has no SHA-256 of the model's files" in n and "export" in n for n in p.notes)
    assert not any("SHA-256" in n for n in Predictor(models["a"] / "model.ts").notes)


def test_a_changed_model_file_is_refused(models, tmp_path):
    """A model file changed since its export (its ONNX here): refused by its hash."""
    from finray.predict import Predictor

    d = tmp_path / "m"
    shutil.copytree(models["a"], d)
    shutil.copy(models["b"] / "model.onnx", d / "model.onnx")
    with pytest.raises(ModelError, match="model.onnx is not the model that model.ts.json"):
        Predictor(d / "model.ts", backend="onnx")
    Predictor(d / "model.ts", backend="torchscript")  # its TorchScript is its own
