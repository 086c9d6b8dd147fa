"""Exports (TorchScript, ONNX) and the predictor: parity, force-only path, `finray
predict` on a render and on a never-seen image (other size, plain background)."""
import csv

import numpy as np
import pytest
import torch

from finray.cli import main
from finray.model import FinRayNet, NetConfig
from finray.predict import Predictor, latency
from finray.train import export_onnx, export_torchscript, force_onnx_path

PREPROCESS = {"base_width_mm": 30.0, "crop_x_mm": [-5.0, 35.0], "crop_y_mm": [0.0, 80.0],
              "segment": {"threshold": "isodata", "foreground": "bright", "min_object_frac": 1e-3,
                          "max_hole_frac": 2e-4, "keep_largest": True}}


@pytest.fixture(scope="module")
def exported(tmp_path_factory):
    """An untrained network (random weights, non-trivial force normalisation, batch-norm
    statistics moved off their defaults) exported to TorchScript and ONNX."""
    torch.manual_seed(0)
    net = FinRayNet(NetConfig(in_channels=1, base_channels=4, height=64, width=32))
    net.set_force_normalisation([3.0], [2.0])
    net.train()
    with torch.no_grad():
        net(torch.rand(8, 1, 64, 32))  # batch-norm running statistics
    net.eval()
    d = tmp_path_factory.mktemp("model")
    export_torchscript(net, d / "model.ts", PREPROCESS)
    export_onnx(net, d / "model.onnx")
    return net, d


@pytest.fixture(scope="module")
def render_png(tmp_path_factory):
    """A camera frame of the fabricated scene (test_render_fixture.py), front view."""
    from finray.render import RenderParams, load_render_index, render_scene
    from test_render_fixture import write_synthetic_fea_result

    tmp = tmp_path_factory.mktemp("render")
    res = write_synthetic_fea_result(tmp / "result.npz", n_frames=4)
    render_scene(res, tmp / "p0", 0.0, params=RenderParams(frames_per_scene=3),
                 scene={"object": "ellipse_16x9", "material": "steel", "height_mm": 30.0,
                        "split": "shape"})
    frames = load_render_index(tmp / "p0")["frames"]
    return tmp / "p0" / frames[-1]["image"]


def never_seen(png, path):
    """The render's finger, 1.6x larger, as a flat pale-yellow shape on a plain grey
    background of another size, off-centre: what a different camera might give (the
    finger brighter than the background, as configured)."""
    from PIL import Image

    from finray.dataset import segment

    rgb = np.asarray(Image.open(png).convert("RGB"))
    mask = segment(rgb)
    h, w = mask.shape
    big = np.asarray(Image.fromarray(mask.astype(np.uint8) * 255).resize(
        (int(w * 1.6), int(h * 1.6)), Image.BILINEAR)) > 127
    canvas = np.zeros((620, 480), bool)
    canvas[40:40 + big.shape[0], 90:90 + big.shape[1]] = big
    img = np.where(canvas[..., None], [240, 230, 150], [90, 95, 100]).astype(np.uint8)
    Image.fromarray(img).save(path)
    return path


def test_torchscript_force_path_and_onnx_parity(exported):
    net, d = exported
    ts = torch.jit.load(str(d / "model.ts"))
    x = torch.rand(5, 1, 64, 32)
    with torch.no_grad():
        s0, f0 = net(x)
        s1, f1 = ts(x)
        f2 = ts.force(x)
    assert (f0 - f1).abs().max() < 1e-4 and (s0 - s1).abs().max() < 1e-4
    assert (f1 - f2).abs().max() < 1e-5  # the force path skips only the decoder
    import onnxruntime as ort

    full = ort.InferenceSession(str(d / "model.onnx"), providers=["CPUExecutionProvider"])
    force = ort.InferenceSession(str(force_onnx_path(d / "model.onnx")),
                                 providers=["CPUExecutionProvider"])
    s3, f3 = full.run(None, {"image": x.numpy()})
    (f4,) = force.run(None, {"image": x.numpy()})
    assert np.abs(f3 - f1.numpy()).max() < 1e-4
    assert np.abs(f4 - f1.numpy()).max() < 1e-4
    assert np.abs(s3 - s1.numpy()).max() < 1e-4


def test_predictor_backends_agree(exported, render_png):
    from PIL import Image

    _, d = exported
    frame = np.asarray(Image.open(render_png).convert("RGB"))
    p_onnx = Predictor(d / "model.ts", backend="onnx")
    p_ts = Predictor(d / "model.ts", backend="torchscript")
    assert Predictor(d / "model.ts").backend == "onnx"
    f_o, s_o = p_onnx(frame)
    f_t, s_t = p_ts(frame)
    assert s_o.shape == s_t.shape == (64, 32)
    assert abs(f_o - f_t) < 1e-4 and np.abs(s_o - s_t).max() < 1e-4
    assert abs(p_onnx.force(frame) - f_o) < 1e-5 and abs(p_ts.force(frame) - f_t) < 1e-5
    # the predictor's input is the dataset's: 8-bit levels in [0, 1]
    x, mask = p_ts.preprocess(frame)
    assert x.shape == (1, 1, 64, 32) and mask.shape == frame.shape[:2]
    np.testing.assert_allclose(x.numpy() * 255, np.rint(x.numpy() * 255), atol=1e-4)
    with pytest.raises(ValueError, match="no finger"):
        p_ts(np.zeros((100, 50, 3), np.uint8))


def test_latency_report_fields(exported, render_png):
    from PIL import Image

    _, d = exported
    frame = np.asarray(Image.open(render_png).convert("RGB"))
    out = latency(Predictor(d / "model.ts"), [frame], n_frames=3, repeats=1)
    # the report's fields (the timings themselves are the benchmark's, not asserted here)
    for key in ("segment_ms", "resample_ms", "network_full_ms", "network_force_ms", "force_ms",
                "full_ms", "force_cpu_ms", "full_cpu_ms"):
        assert isinstance(out[key], float) and np.isfinite(out[key])
    assert out["n_calls"] == 3 and out["n_distinct_frames"] == 1
    assert out["input_size"] == [64, 32]


@pytest.mark.parametrize("backend", ["onnx", "torchscript"])
def test_cli_predict_on_a_render_and_a_never_seen_image(exported, render_png, tmp_path, backend):
    _, d = exported
    src = tmp_path / "frames"
    src.mkdir()
    (src / "render.png").write_bytes(render_png.read_bytes())
    never_seen(render_png, src / "other_camera.png")
    out = tmp_path / "out"
    assert main(["predict", "--model", str(d / "model.ts"), str(src), "--out", str(out),
                 "--backend", backend]) == 0
    rows = list(csv.DictReader(open(out / "forces.csv")))
    assert [r["frame"] for r in rows] == ["other_camera.png", "render.png"]
    forces = [float(r["fx_N"]) for r in rows]
    assert all(np.isfinite(forces))
    for stem in ("render", "other_camera"):
        assert (out / f"{stem}_stress.exr").is_file() and (out / f"{stem}_stress.png").is_file()
    # anchored on the finger's base: the other camera's frame gives the same input
    p = Predictor(d / "model.ts", backend=backend)
    from PIL import Image

    xa = p.preprocess(np.asarray(Image.open(src / "render.png").convert("RGB")))[0]
    xb = p.preprocess(np.asarray(Image.open(src / "other_camera.png").convert("RGB")))[0]
    assert float((xa - xb).abs().mean()) < 0.03
    # force-only run: the same forces, no maps
    out2 = tmp_path / "out_force"
    assert main(["predict", "--model", str(d / "model.ts"), str(src), "--out", str(out2),
                 "--backend", backend, "--force-only"]) == 0
    rows2 = list(csv.DictReader(open(out2 / "forces.csv")))
    np.testing.assert_allclose([float(r["fx_N"]) for r in rows2], forces, atol=1e-4)
    assert not list(out2.glob("*_stress.png"))
