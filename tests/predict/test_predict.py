"""Exports (TorchScript, ONNX) and the predictor: parity, force-only path, `finray
predict` on a render and on a never-seen image (other size, plain background)."""

import csv
import json

import numpy as np
import pytest
import torch
from PIL import Image

from finray.cli import main
from finray.model import FinRayNet, NetConfig
from finray.benchmarks.realtime import latency
from finray.predict import Predictor, read_frames
from finray.train import export_onnx, export_torchscript, force_onnx_path

from helpers import PREPROCESS


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


def never_seen(png, path):
    """The render's finger, 1.6x larger, as a flat pale-yellow shape on a plain grey
    background of another size, off-centre: what a different camera might give (the
    finger brighter than the background, as configured)."""
    from PIL import Image

    from finray.dataset import segment

    rgb = np.asarray(Image.open(png).convert("RGB"))
    mask = segment(rgb)
    h, w = mask.shape
    big = (
        np.asarray(
            Image.fromarray(mask.astype(np.uint8) * 255).resize(
                (int(w * 1.6), int(h * 1.6)), Image.BILINEAR
            )
        )
        > 127
    )
    canvas = np.zeros((620, 480), bool)
    canvas[40 : 40 + big.shape[0], 90 : 90 + big.shape[1]] = big
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
    force = ort.InferenceSession(
        str(force_onnx_path(d / "model.onnx")), providers=["CPUExecutionProvider"]
    )
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
    for key in (
        "segment_ms",
        "resample_ms",
        "network_full_ms",
        "network_force_ms",
        "force_ms",
        "full_ms",
        "force_cpu_ms",
        "full_cpu_ms",
    ):
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
    assert (
        main(
            [
                "predict",
                "--model",
                str(d / "model.ts"),
                str(src),
                "--out",
                str(out),
                "--backend",
                backend,
            ]
        )
        == 0
    )
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
    assert (
        main(
            [
                "predict",
                "--model",
                str(d / "model.ts"),
                str(src),
                "--out",
                str(out2),
                "--backend",
                backend,
                "--force-only",
            ]
        )
        == 0
    )
    rows2 = list(csv.DictReader(open(out2 / "forces.csv")))
    np.testing.assert_allclose([float(r["fx_N"]) for r in rows2], forces, atol=1e-4)
    assert not list(out2.glob("*_stress.png"))


def err_lines(text: str) -> list[str]:
    """stderr's lines, less the notes (how the finger is found, what an old export lacks)."""
    return [
        line for line in text.strip().splitlines() if not line.startswith("finray predict: note: ")
    ]


def one_line_error(capsys, prefix):
    """One line on stderr, starting with ``prefix`` (main returned, no traceback)."""
    lines = err_lines(capsys.readouterr().err)
    assert len(lines) == 1 and lines[0].startswith(prefix), lines
    return lines[0]


def blank(path):
    """A frame without a finger: plain grey."""
    from PIL import Image

    Image.fromarray(np.full((120, 80, 3), 90, np.uint8)).save(path)
    return path


def test_a_two_force_model_writes_fx_and_fy(render_png, tmp_path, capsys):
    """A model of the force vector (fx, fy): ``forces()`` names both, forces.csv has a
    column each, the CLI prints both."""
    torch.manual_seed(1)
    net = FinRayNet(NetConfig(in_channels=1, base_channels=4, height=64, width=32, n_forces=2))
    net.set_force_normalisation([3.0, -0.6], [2.0, 0.5])
    net.eval()
    export_torchscript(net, tmp_path / "model.ts", PREPROCESS, ["fx_N", "fy_N"])
    p = Predictor(tmp_path / "model.ts", backend="torchscript")
    assert p.force_names == ["fx_N", "fy_N"]
    frame = np.asarray(Image.open(render_png).convert("RGB"))
    f = p.forces(frame)
    assert list(f) == ["fx_N", "fy_N"] and f["fx_N"] == pytest.approx(p.force(frame), abs=1e-5)
    assert (
        main(
            [
                "predict",
                str(render_png),
                "--model",
                str(tmp_path / "model.ts"),
                "--out",
                str(tmp_path / "out"),
                "--backend",
                "torchscript",
            ]
        )
        == 0
    )
    rows = list(csv.DictReader(open(tmp_path / "out" / "forces.csv")))
    assert list(rows[0]) == ["frame", "fx_N", "fy_N", "valid"]
    assert float(rows[0]["fy_N"]) == pytest.approx(f["fy_N"], abs=1e-4)
    assert f"fy {f['fy_N']:.4f} N" in capsys.readouterr().out
    with pytest.raises(ValueError, match="2 force names for a model with 1"):
        export_torchscript(
            FinRayNet(NetConfig(in_channels=1, base_channels=4)),
            tmp_path / "x.ts",
            PREPROCESS,
            ["fx_N", "fy_N"],
        )


def test_cli_predict_bad_input_is_one_line(exported, render_png, tmp_path, capsys):
    _, d = exported
    model = str(d / "model.ts")
    out = str(tmp_path / "out")
    assert (
        main(["predict", "--model", str(tmp_path / "none.ts"), str(render_png), "--out", out]) == 2
    )
    assert f"no model at {tmp_path / 'none.ts'}" in one_line_error(capsys, "finray predict: ")
    assert main(["predict", "--model", model, str(tmp_path / "nothing.png"), "--out", out]) == 2
    msg = one_line_error(capsys, "finray predict: ")
    assert f"{tmp_path / 'nothing.png'} does not exist" in msg
    notes = tmp_path / "notes.png"
    notes.write_text("not an image\n")
    assert main(["predict", "--model", model, str(notes), "--out", out]) == 2
    assert "notes.png: not a readable image (" in one_line_error(capsys, "finray predict: ")
    no_finger = blank(tmp_path / "blank.png")
    assert main(["predict", "--model", model, str(no_finger), "--out", out]) == 2
    assert "blank.png: no finger found in the image" in one_line_error(capsys, "finray predict: ")
    empty = tmp_path / "empty"
    empty.mkdir()
    assert main(["predict", "--model", model, str(empty), "--out", out]) == 2
    assert "no images (.png" in one_line_error(capsys, "finray predict: ")
    bad_ts = tmp_path / "bad.ts"
    bad_ts.write_bytes(b"not a model")
    (tmp_path / "bad.ts.json").write_text((d / "model.ts.json").read_text())
    bad = ["predict", "--model", str(bad_ts), str(render_png), "--out", out]
    assert main([*bad, "--backend", "torchscript"]) == 2
    assert "bad.ts is not the model that bad.ts.json describes (its SHA-256 differs" in (
        one_line_error(capsys, "finray predict: ")
    )
    # settings without the hashes (an old export): the file itself is refused
    meta = json.loads((d / "model.ts.json").read_text())
    del meta["sha256"]
    (tmp_path / "bad.ts.json").write_text(json.dumps(meta))
    assert main([*bad, "--backend", "torchscript"]) == 2
    assert "bad.ts is not a TorchScript model" in one_line_error(capsys, "finray predict: ")
    assert not (tmp_path / "out").exists()  # every refusal above left nothing behind


def test_cli_predict_refuses_an_out_with_another_runs_results(
    exported, render_png, tmp_path, capsys
):
    """A second run into a used --out would mix its table with the first run's stress
    maps: refused without --overwrite, which removes them first."""
    _, d = exported
    model, out = str(d / "model.ts"), tmp_path / "out"
    assert (
        main(
            [
                "predict",
                "--model",
                model,
                str(render_png),
                "--out",
                str(out),
                "--backend",
                "torchscript",
            ]
        )
        == 0
    )
    first = sorted(f.name for f in out.iterdir())
    assert "forces.csv" in first and any(n.endswith("_stress.exr") for n in first)
    capsys.readouterr()
    assert (
        main(["predict", "--model", model, str(render_png), "--out", str(out), "--force-only"]) == 2
    )
    msg = one_line_error(capsys, "finray predict: ")
    assert f"{out} holds another run's results (" in msg and "give --overwrite" in msg
    assert sorted(f.name for f in out.iterdir()) == first  # untouched
    assert (
        main(
            [
                "predict",
                "--model",
                model,
                str(render_png),
                "--out",
                str(out),
                "--force-only",
                "--overwrite",
                "--backend",
                "torchscript",
            ]
        )
        == 0
    )
    # the old maps went with it
    assert sorted(f.name for f in out.iterdir()) == ["forces.csv", "segmentation.json"]


def three_frames(folder, render_png):
    """A folder of three copies of the rendered frame, f0.png .. f2.png."""
    folder.mkdir()
    for k in range(3):
        (folder / f"f{k}.png").write_bytes(render_png.read_bytes())
    return folder


def test_an_interrupted_run_keeps_the_frames_done(exported, render_png, tmp_path):
    """Ctrl-C after two of three frames: forces.csv in place with those two, no .part."""
    from finray.predict import predict_files

    _, d = exported
    src = three_frames(tmp_path / "frames", render_png)
    done = []

    def on_frame(row):
        done.append(row)
        if len(done) == 2:
            raise KeyboardInterrupt

    with pytest.raises(KeyboardInterrupt):
        predict_files(
            d / "model.ts",
            src,
            tmp_path / "out",
            backend="torchscript",
            force_only=True,
            on_frame=on_frame,
        )
    rows = list(csv.DictReader(open(tmp_path / "out" / "forces.csv")))
    assert [r["frame"] for r in rows] == ["f0.png", "f1.png"]
    assert not (tmp_path / "out" / "forces.csv.part").exists()


def test_cli_predict_skips_bad_frames_and_writes_the_others(exported, render_png, tmp_path, capsys):
    _, d = exported
    src = tmp_path / "frames"
    src.mkdir()
    (src / "a_render.png").write_bytes(render_png.read_bytes())
    (src / "b_corrupt.png").write_bytes(render_png.read_bytes()[:200])  # truncated file
    blank(src / "c_blank.png")
    never_seen(render_png, src / "d_other_camera.png")
    out = tmp_path / "out"
    assert (
        main(
            [
                "predict",
                "--model",
                str(d / "model.ts"),
                str(src),
                "--out",
                str(out),
                "--backend",
                "torchscript",
            ]
        )
        == 1
    )  # done, but not every frame
    io = capsys.readouterr()
    assert "Traceback" not in io.err
    err = err_lines(io.err)
    assert err[0].startswith("finray predict: skipped b_corrupt.png: not a readable image (")
    assert err[1] == (
        "finray predict: skipped c_blank.png: no finger found in the image (empty segmentation)"
    )
    assert err[2].startswith("finray predict: 2 of 4 frames skipped")
    assert len(err) == 3
    rows = list(csv.DictReader(open(out / "forces.csv")))
    assert [r["frame"] for r in rows] == ["a_render.png", "d_other_camera.png"]
    p = Predictor(d / "model.ts", backend="torchscript")
    from PIL import Image

    for r in rows:
        want = p(np.asarray(Image.open(src / r["frame"]).convert("RGB")))[0]
        assert abs(float(r["fx_N"]) - want) < 1e-4
        assert (out / f"{r['frame'][:-4]}_stress.exr").is_file()
    assert not (out / "b_corrupt_stress.exr").exists() and not (out / "c_blank_stress.exr").exists()


def test_the_table_is_written_as_frames_complete_and_moved_into_place(
    exported, render_png, tmp_path
):
    from finray.predict import predict_files

    _, d = exported
    src = three_frames(tmp_path / "frames", render_png)
    on_disk = []

    def on_frame(row):  # what a reader of the running table sees when frame k completes
        on_disk.append((tmp_path / "out" / "forces.csv.part").read_text().splitlines())
        assert not (tmp_path / "out" / "forces.csv").exists()  # in place only when done

    out = predict_files(
        d / "model.ts",
        src,
        tmp_path / "out",
        backend="torchscript",
        force_only=True,
        on_frame=on_frame,
    )
    assert [len(lines) for lines in on_disk] == [2, 3, 4]  # header + one row per frame
    assert on_disk[0][1].startswith("f0.png,") and out["skipped"] == []
    assert (tmp_path / "out" / "forces.csv").read_text().splitlines() == on_disk[-1]
    assert not (tmp_path / "out" / "forces.csv.part").exists()


def write_video(path, frames, fps=10):
    """An H.264 MP4 of RGB frames (even sizes), through PyAV."""
    import av

    h, w = frames[0].shape[:2]
    with av.open(str(path), "w") as c:
        s = c.add_stream("libx264", rate=fps)
        s.width, s.height, s.pix_fmt = w, h, "yuv420p"
        s.options = {"crf": "10"}  # near lossless: the finger's edges stay put
        for f in frames:
            c.mux(s.encode(av.VideoFrame.from_ndarray(np.ascontiguousarray(f), format="rgb24")))
        c.mux(s.encode())
    return path


def test_cli_predict_on_a_video(exported, render_png, tmp_path, capsys):
    """The fixture's rendered frames as a video, with a frame without a finger between
    them: one force per frame with a finger, the same as from the PNGs."""
    from PIL import Image

    _, d = exported
    pngs = sorted(render_png.parent.glob("image_*.png"))
    frames = [np.asarray(Image.open(f).convert("RGB")) for f in pngs]
    assert len(frames) == 3 and frames[0].shape[0] % 2 == 0 and frames[0].shape[1] % 2 == 0
    video = write_video(tmp_path / "clip.mp4", [frames[0], np.zeros_like(frames[0]), *frames[1:]])
    out = tmp_path / "out"
    assert (
        main(
            [
                "predict",
                "--model",
                str(d / "model.ts"),
                str(video),
                "--out",
                str(out),
                "--backend",
                "torchscript",
            ]
        )
        == 1
    )
    err = err_lines(capsys.readouterr().err)
    assert (
        err[0]
        == "finray predict: skipped clip_00001: no finger found in the image (empty segmentation)"
        and len(err) == 2
    )
    rows = list(csv.DictReader(open(out / "forces.csv")))
    assert [r["frame"] for r in rows] == ["clip_00000", "clip_00002", "clip_00003"]
    assert all(np.isfinite(float(r["fx_N"])) for r in rows)
    assert [float(r["t_s"]) for r in rows] == pytest.approx([0.0, 0.2, 0.3], abs=1e-6)  # 10 FPS
    # the decoded frames are the rendered ones, in order (H.264 moves a few edge pixels)
    p = Predictor(d / "model.ts", backend="torchscript")
    decoded = {name: f for name, f, _ in read_frames(video)}
    assert list(decoded) == [f"clip_{k:05d}" for k in range(4)]
    for name, f in zip(["clip_00000", "clip_00002", "clip_00003"], frames):
        assert decoded[name].shape == f.shape and decoded[name].dtype == np.uint8
        assert np.abs(decoded[name].astype(int) - f).mean() < 6
        mask, want = p.segment(decoded[name]), p.segment(f)
        assert (mask != want).sum() < 0.01 * want.sum()
    assert all((out / f"{r['frame']}_stress.exr").is_file() for r in rows)


def test_cli_predict_on_a_file_that_is_not_a_video(exported, tmp_path, capsys):
    _, d = exported
    fake = tmp_path / "clip.mp4"
    fake.write_bytes(b"\x00" * 64)
    assert (
        main(["predict", "--model", str(d / "model.ts"), str(fake), "--out", str(tmp_path / "out")])
        == 2
    )
    assert "clip.mp4 is not a readable video (" in one_line_error(capsys, "finray predict: ")


def test_cli_predict_on_a_video_with_a_corrupt_frame(exported, render_png, tmp_path, capsys):
    """One frame's packet zeroed in the file: that frame is reported, the others written."""
    import av
    from PIL import Image

    _, d = exported
    frames = [
        np.asarray(Image.open(f).convert("RGB"))
        for f in sorted(render_png.parent.glob("image_*.png"))
    ]
    video = write_video(tmp_path / "clip.mp4", frames + frames)
    with av.open(str(video)) as c:
        s = c.streams.video[0]
        packets = [
            (round(p.pts * p.time_base * s.average_rate), p.pos, p.size)
            for p in c.demux(s)
            if p.size and not p.is_keyframe
        ]
    rank, pos, size = max(packets, key=lambda p: p[2])  # the largest frame after the key frame
    data = bytearray(video.read_bytes())
    data[pos : pos + size] = bytes(size)
    video.write_bytes(bytes(data))
    out = tmp_path / "out"
    assert (
        main(
            [
                "predict",
                "--model",
                str(d / "model.ts"),
                str(video),
                "--out",
                str(out),
                "--backend",
                "torchscript",
                "--force-only",
            ]
        )
        == 1
    )
    err = err_lines(capsys.readouterr().err)
    assert err[0].startswith(f"finray predict: skipped clip_{rank:05d}: the frame does not decode")
    assert err[1].startswith("finray predict: 1 of 6 frames skipped") and len(err) == 2
    rows = list(csv.DictReader(open(out / "forces.csv")))
    assert sorted(r["frame"] for r in rows) == [f"clip_{k:05d}" for k in range(6) if k != rank]


def test_cli_predict_annotates_a_video(exported, render_png, tmp_path):
    """--annotate on a video: annotated.mp4 with a frame per predicted frame, the frame
    and a colour-bar panel beside it; forces.png; --force-only with it is refused."""
    import av

    _, d = exported
    frames = [
        np.asarray(Image.open(f).convert("RGB"))
        for f in sorted(render_png.parent.glob("image_*.png"))
    ]
    video = write_video(tmp_path / "clip.mp4", frames)
    out = tmp_path / "out"
    assert (
        main(
            ["predict", "--model", str(d / "model.ts"), str(video), "--out", str(out), "--annotate"]
        )
        == 0
    )
    with av.open(str(out / "annotated.mp4")) as c:
        decoded = [f.to_ndarray(format="rgb24") for f in c.decode(video=0)]
    from finray.annotate import BAR_PX

    h, w = frames[0].shape[:2]
    assert len(decoded) == len(frames) and decoded[0].shape == (h, (w + BAR_PX) // 2 * 2, 3)
    assert (out / "forces.png").stat().st_size > 1000
    assert not list(out.glob("*_annotated.png"))  # a video's frames go into the video
    assert (
        main(
            [
                "predict",
                "--model",
                str(d / "model.ts"),
                str(video),
                "--out",
                str(tmp_path / "o2"),
                "--annotate",
                "--force-only",
            ]
        )
        == 2
    )
    assert not (tmp_path / "o2").exists()


def test_show_without_a_display_says_so_and_writes_the_files(
    exported, render_png, tmp_path, capsys, monkeypatch
):
    """--show on a machine without a display: one line says so, the run writes what
    --annotate writes; --no-maps leaves out the per-frame stress maps; each annotated
    frame also goes to ``on_annotated`` (the window's hook)."""
    from finray.annotate import Window
    from finray.predict import predict_files

    _, d = exported
    frames = [
        np.asarray(Image.open(f).convert("RGB"))
        for f in sorted(render_png.parent.glob("image_*.png"))
    ]
    video = write_video(tmp_path / "clip.mp4", frames)
    monkeypatch.delenv("DISPLAY", raising=False)
    monkeypatch.delenv("WAYLAND_DISPLAY", raising=False)
    out = tmp_path / "out"
    assert (
        main(
            [
                "predict",
                "--model",
                str(d / "model.ts"),
                str(video),
                "--out",
                str(out),
                "--show",
                "--no-maps",
            ]
        )
        == 0
    )
    err = err_lines(capsys.readouterr().err)
    assert err == [
        "finray predict: --show: no display (DISPLAY and WAYLAND_DISPLAY unset); "
        "writing the annotated files only"
    ]
    assert (out / "annotated.mp4").is_file() and (out / "forces.png").is_file()
    assert not list(out.glob("*_stress.*"))
    shown = []
    predict_files(d / "model.ts", video, tmp_path / "o2", annotate=True, on_annotated=shown.append)
    assert len(shown) == len(frames) and shown[0].ndim == 3
    assert len(list((tmp_path / "o2").glob("*_stress.exr"))) == len(frames)
    with pytest.raises(RuntimeError, match="no display"):
        Window()
    monkeypatch.setenv("DISPLAY", ":97")  # no X server there
    with pytest.raises(RuntimeError, match="cannot open a window"):
        Window()


def test_overlay_colours_the_mask_inside_the_window_only():
    """Each masked pixel in the window takes its map cell's colour (blended); pixels
    outside the mask or the window keep the frame's value."""
    from finray.annotate import STRESS_LOG_MAX, _lut, annotate_frame, overlay_stress

    frame = np.full((40, 30), 100, np.uint8)
    mask = np.zeros((40, 30), bool)
    mask[5:35, 5:25] = True
    box = (0.0, 0.0, 20.0, 40.0)  # columns 0-19: the window; 20-29 outside it
    stress = np.array([[0.0, STRESS_LOG_MAX], [STRESS_LOG_MAX / 2, 0.0]])  # 2 x 2 cells
    out = overlay_stress(frame, mask, box, stress, alpha=1.0)
    lut = _lut()
    assert (out[10, 8] == lut[0]).all() and (out[10, 12] == lut[255]).all()  # top cells
    assert (out[30, 8] == lut[128]).all() and (out[30, 12] == lut[0]).all()  # bottom cells
    assert (out[2, 2] == 100).all() and (out[10, 22] == 100).all()  # off the mask; off the window
    # a partial alpha blends each pixel with its cell: (1 - alpha) frame + alpha colour,
    # to within the 8-bit fixed point's rounding
    rgb = np.random.default_rng(0).integers(0, 256, (40, 30, 3), dtype=np.uint8)
    out = overlay_stress(rgb, mask, box, stress, alpha=0.65)
    cell = lut[np.clip(np.rint(stress / STRESS_LOG_MAX * 255), 0, 255).astype(int)]
    rows, cols = np.nonzero(mask[:, :20])
    want = 0.35 * rgb[rows, cols] + 0.65 * cell[rows * 2 // 40, cols * 2 // 20]
    assert np.abs(out[rows, cols] - want).max() <= 1.0
    assert (out[~mask] == rgb[~mask]).all() and (out[:, 20:] == rgb[:, 20:]).all()
    img = annotate_frame(
        frame,
        mask,
        box,
        stress,
        {"fx_N": 2.0, "fy_N": 0.5},
        {"force_N": 2.1, "lo_N": 1.9, "hi_N": 2.3, "level": 0.9},
        "f0",
    )
    assert img.shape[:2] == (40, 30 + 96) and img.dtype == np.uint8


def test_text_from_cached_glyphs_matches_pillows():
    """The annotation's text, composed from cached glyphs, covers the pixels Pillow's
    own outlined text covers (white fill, black outline), kerning aside."""
    from PIL import Image, ImageDraw

    from finray.annotate import TEXT_STROKE_PX, _font, draw_text

    text, size = "frame 12, t = 0.400 s\n|F| 3.21 N  (fx 3.20 N, fy -0.25 N)", 24
    ours = np.full((90, 520, 3), 128, np.uint8)
    draw_text(ours, (8, 6), text, size)
    img = Image.new("RGB", (520, 90), (128, 128, 128))
    ImageDraw.Draw(img).multiline_text(
        (8, 6),
        text,
        fill=(255, 255, 255),
        font=_font(size),
        stroke_width=TEXT_STROKE_PX,
        stroke_fill=(0, 0, 0),
    )
    theirs = np.asarray(img)
    for level in (lambda a: a[..., 0] > 200, lambda a: a[..., 0] < 50):  # fill, outline
        a, b = level(ours), level(theirs)
        assert (a & b).sum() / (a | b).sum() > 0.95
        assert abs(int(a.sum()) - int(b.sum())) < 0.02 * b.sum()
    assert (ours[80:] == 128).all()  # nothing below the text


SERVE = """
import sys, numpy as np, av
from PIL import Image
port, pngs = int(sys.argv[1]), sys.argv[2:]
frames = [np.asarray(Image.open(p).convert("RGB")) for p in pngs] * 3
h, w = frames[0].shape[:2]
with av.open(f"tcp://127.0.0.1:{port}?listen=1", "w", format="mpegts") as c:
    s = c.add_stream("mpeg2video", rate=10)
    s.width, s.height, s.pix_fmt = w, h, "yuv420p"
    for f in frames:
        c.mux(s.encode(av.VideoFrame.from_ndarray(np.ascontiguousarray(f), format="rgb24")))
    c.mux(s.encode())
"""


@pytest.mark.parametrize("buffer", [1, 2, 3])
def test_live_frames_keep_the_latest_frames_in_order(tmp_path, buffer):
    """A live source's reader keeps the latest ``buffer`` frames for a consumer that
    is behind: the rest are dropped and counted, and what is kept comes in order."""
    import time

    import av

    from finray.media import LiveFrames

    path = tmp_path / "v.mp4"
    with av.open(str(path), "w") as c:
        s = c.add_stream("mpeg4", rate=10)
        s.width, s.height, s.pix_fmt = 32, 32, "yuv420p"
        for k in range(12):
            img = np.full((32, 32, 3), 20 * k, np.uint8)
            c.mux(s.encode(av.VideoFrame.from_ndarray(img, format="rgb24")))
        c.mux(s.encode())
    live = LiveFrames(path, buffer=buffer)
    t0 = time.monotonic()
    while not live._done and time.monotonic() - t0 < 10:  # the consumer is far behind
        time.sleep(0.01)
    got = [f.index for f in live]
    live.close()
    assert live.received == 12 and live.dropped == 12 - buffer
    assert got == list(range(12 - buffer, 12))
    with pytest.raises(ValueError, match="at least one frame"):
        LiveFrames(path, buffer=0)


def test_cli_predict_on_a_live_network_stream(exported, render_png, tmp_path, capsys):
    """A TCP stream (MPEG-TS, served by PyAV in another process) read as a live source
    until it ends: a row per frame kept, each with its time; the summary line counts the
    frames received and dropped; a stream nobody serves is one line, exit code 2."""
    import socket
    import subprocess
    import sys
    import time

    _, d = exported
    pngs = sorted(str(f) for f in render_png.parent.glob("image_*.png"))
    with socket.socket() as sock:
        sock.bind(("127.0.0.1", 0))
        port = sock.getsockname()[1]
    (tmp_path / "serve.py").write_text(SERVE)
    server = subprocess.Popen([sys.executable, str(tmp_path / "serve.py"), str(port), *pngs])
    out, rc = tmp_path / "out", 2
    try:
        for _ in range(100):  # until the server listens
            rc = main(
                [
                    "predict",
                    "--model",
                    str(d / "model.ts"),
                    f"tcp://127.0.0.1:{port}",
                    "--out",
                    str(out),
                    "--backend",
                    "torchscript",
                ]
            )
            if rc != 2:
                break
            time.sleep(0.1)
    finally:
        server.wait(timeout=60)
    assert rc == 0
    rows = list(csv.DictReader(open(out / "forces.csv")))
    err = err_lines(capsys.readouterr().err)[-1]
    n = int(err.split("frames predicted of ")[1].split()[0])
    dropped = int(err.split("received (")[1].split()[0])
    assert 1 <= len(rows) and len(rows) + dropped == n <= 3 * len(pngs), err
    assert "the stream ended" in err
    assert all(r["frame"].startswith("live_") and r["t_s"] != "" for r in rows)
    assert (
        main(
            [
                "predict",
                "--model",
                str(d / "model.ts"),
                f"tcp://127.0.0.1:{port}",
                "--out",
                str(tmp_path / "none"),
            ]
        )
        == 2
    )
    assert not (tmp_path / "none").exists()


def test_fit_frame_crops_to_the_aspect_and_resizes():
    from finray.benchmarks.realtime import fit_frame

    tall = np.zeros((1280, 720, 3), np.uint8)
    tall[160:1120] = 200  # the rows the 4:3 crop keeps
    out = fit_frame(tall, (640, 480))
    assert out.shape == (640, 480, 3) and (out == 200).all()
    assert fit_frame(tall, (100, 400)).shape == (100, 400, 3)


@pytest.mark.slow
def test_stream_benchmark_on_a_live_stream(exported, render_png, tmp_path):
    """The real-time benchmark's measurement (the figures themselves are timings, not
    asserted): a served stream read alone and by finray predict; every frame the server
    sent is received, each predicted or dropped; latencies from the server's clock."""
    from PIL import Image

    from finray.benchmarks.realtime import stream_benchmark, write_stream_video

    _, d = exported
    pngs = sorted(render_png.parent.glob("image_*.png"))
    frames = [np.asarray(Image.open(p).convert("RGB")) for p in pngs]
    video = write_stream_video(frames, tmp_path / "s.ts", (160, 96), 60, 30.0)  # 2 s
    for mode in ("read", "force"):
        r = stream_benchmark(d / "model.ts", video, tmp_path / mode, mode, cores=None)
        assert r["frames_sent"] == r["received"] == 60, r
        assert r["predicted"] + r["dropped"] == r["received"] and r["predicted"] > 3
        assert 0 <= r["dropped_steady"] <= r["dropped"]
        assert 0 < r["latency_p50_ms"] <= r["latency_p99_ms"] <= r["latency_max_ms"]
        # the steady window of a 2 s stream of small frames may fall within one 10 ms tick
        assert r["cpu_ms_per_frame_run"] > 0 and r["cpu_ms_per_frame"] >= 0
        assert r["mode"] == mode
    rows = list(csv.DictReader(open(tmp_path / "force" / "forces.csv")))
    assert len(rows) == r["predicted"]
    with pytest.raises(ValueError, match="mode"):
        stream_benchmark(d / "model.ts", video, tmp_path / "x", "fast")


def test_stream_force_error_matches_rows_to_the_frames_they_read(tmp_path):
    """Rows of a stream's run matched by time stamp to the frames of the forth-and-back
    cycle: rows that carry each frame's true force plus 0.1 N give an RMSE of 0.1 N."""
    from finray.benchmarks.realtime import stream_force_error, write_stream_video
    from finray.media import video_frames

    frames = [np.full((40, 24, 3), 40 * k, np.uint8) for k in range(5)]
    video = write_stream_video(frames, tmp_path / "s.ts", (40, 24), 20, 30.0)
    truth = np.array([0.0, 1.0, 2.0, 3.0, 4.0])
    order = [0, 1, 2, 3, 4, 3, 2, 1]
    stamps = [f.t_s for f in video_frames(video)]
    ks = [0, 3, 4, 5, 9, 17, 19]  # some dropped, as a live run drops them
    with open(tmp_path / "forces.csv", "w") as f:
        f.write("frame,t_s,fx_N\n")
        f.writelines(f"live_{k},{stamps[k]:.6f},{truth[order[k % 8]] + 0.1}\n" for k in ks)
    err = stream_force_error(tmp_path / "forces.csv", video, truth)
    assert err["force_rmse_N"] == pytest.approx(0.1)
    assert err["force_nrmse_pct"] == pytest.approx(100 * 0.1 / 4.0)


def _serve(video, port):
    """The real-time benchmark's server (finray.benchmarks.realtime.SERVE): the video's
    own packets over TCP at their pace, in another process."""
    import subprocess
    import sys

    from finray.benchmarks.realtime import SERVE

    return subprocess.Popen(
        [sys.executable, "-c", SERVE, str(video), str(port)], stdout=subprocess.PIPE, text=True
    )


def test_a_stream_gives_the_files_forces_frame_for_frame(exported, render_png, tmp_path):
    """A video served over 127.0.0.1 (its packets as they are, no re-encoding) and the
    same file: every frame predicted from the stream has the file's forces for the frame
    of the same time stamp."""
    import time

    from finray.benchmarks.realtime import _free_port, write_stream_video
    from finray.predict import predict_files

    _, d = exported
    frames = [
        np.asarray(Image.open(f).convert("RGB"))
        for f in sorted(render_png.parent.glob("image_*.png"))
    ]
    video = write_stream_video(frames, tmp_path / "clip.ts", (160, 96), 30, 10.0)  # 3 s
    from_file = predict_files(d / "model.ts", video, tmp_path / "file", force_only=True)["rows"]
    from finray.predict import InputError

    port = _free_port()
    server = _serve(video, port)
    try:
        for _ in range(100):  # until the server listens
            try:
                live = predict_files(
                    d / "model.ts", f"tcp://127.0.0.1:{port}", tmp_path / "live", force_only=True
                )
                break
            except InputError as exc:
                assert "cannot be opened" in str(exc)
                time.sleep(0.1)
    finally:
        server.wait(timeout=60)
    by_time = {round(r["t_s"], 4): r for r in from_file}
    assert len(from_file) == 30 and live["received"] == 30 and len(live["rows"]) >= 10
    for r in live["rows"]:
        f = by_time[round(r["t_s"], 4)]
        assert [r[k] for k in r if k.endswith("_N")] == [f[k] for k in f if k.endswith("_N")], (
            r,
            f,
        )


@pytest.mark.slow
def test_sigint_ends_a_live_run_with_a_complete_table(exported, render_png, tmp_path):
    """SIGINT (Ctrl-C) to `finray predict` on a live stream, the way a live run ends:
    exit code 0, forces.csv in place with a full row per frame predicted, no .part left,
    the summary line."""
    import signal
    import subprocess
    import sys

    from finray.benchmarks.realtime import _free_port, write_stream_video

    _, d = exported
    frames = [
        np.asarray(Image.open(f).convert("RGB"))
        for f in sorted(render_png.parent.glob("image_*.png"))
    ]
    video = write_stream_video(frames, tmp_path / "long.ts", (160, 96), 600, 30.0)  # 20 s
    port = _free_port()
    server = _serve(video, port)
    out = tmp_path / "out"
    # SIGINT's default disposition in the child (a test runner's workers may ignore it,
    # and a Python started with SIGINT ignored installs no KeyboardInterrupt)
    proc = subprocess.Popen(
        [
            sys.executable,
            "-m",
            "finray.cli",
            "predict",
            "--model",
            str(d / "model.ts"),
            f"tcp://127.0.0.1:{port}",
            "--out",
            str(out),
            "--force-only",
        ],
        stdout=subprocess.PIPE,
        stderr=subprocess.PIPE,
        text=True,
        preexec_fn=lambda: signal.signal(signal.SIGINT, signal.SIG_DFL),
    )
    try:
        lines = [proc.stdout.readline() for _ in range(5)]  # five rows predicted
        proc.send_signal(signal.SIGINT)
        rest, err = proc.communicate(timeout=60)
    finally:
        server.kill()
    assert all(line.startswith("live_") for line in lines)
    assert proc.returncode == 0, err
    rows = list(csv.DictReader(open(out / "forces.csv")))
    assert len(rows) >= 5 and all(r["fx_N"] and r["t_s"] for r in rows)
    assert not (out / "forces.csv.part").exists()
    assert "stopped by Ctrl-C" in err


@pytest.fixture(scope="module")
def exported_contact(tmp_path_factory):
    """An untrained network with the contact head (its own normalisation) exported to
    TorchScript and ONNX."""
    torch.manual_seed(2)
    net = FinRayNet(NetConfig(in_channels=1, base_channels=4, height=64, width=32, contact=True))
    net.set_force_normalisation([3.0], [2.0])
    net.set_contact_normalisation(40.0, 15.0)
    net.eval()
    d = tmp_path_factory.mktemp("contact_model")
    export_torchscript(net, d / "model.ts", PREPROCESS, contact_min_force_N=0.2)
    export_onnx(net, d / "model.onnx")
    return net, d


@pytest.mark.parametrize("backend", ["onnx", "torchscript"])
def test_a_contact_model_gives_the_height_beside_the_force(exported_contact, render_png, backend):
    """``forces()`` adds ``contact_mm`` (the network's height, mm) for a model with the
    head; the full and force-only paths agree on it."""
    net, d = exported_contact
    p = Predictor(d / "model.ts", backend=backend)
    assert p.backend == backend and p.has_contact and p.contact_min_force_N == 0.2
    frame = np.asarray(Image.open(render_png).convert("RGB"))
    out = p.forces(frame)
    assert list(out) == ["fx_N", "contact_mm"]
    x = p.network_input(p.segment(frame))
    with torch.no_grad():
        want = float(net.contact(torch.from_numpy(x))[0])
    assert out["contact_mm"] == pytest.approx(want, abs=1e-3) == p.contact(frame)
    stress, force, contact = p.run_contact(x)
    assert contact.shape == (1,) and contact[0] == pytest.approx(want, abs=1e-3)
    np.testing.assert_allclose(stress, p.run(x)[0], atol=1e-4)
    np.testing.assert_allclose(force, p.run_force_contact(x)[0], atol=1e-4)


def test_cli_predict_writes_the_contact_height(
    exported_contact, exported, render_png, tmp_path, capsys
):
    """forces.csv gets a contact_mm column (also --force-only), the CLI prints it,
    --annotate draws; a model without the head keeps its columns and gives NaN."""
    _, d = exported_contact
    p = Predictor(d / "model.ts")
    want = p.contact(np.asarray(Image.open(render_png).convert("RGB")))
    for extra in ([], ["--force-only"], ["--annotate"]):
        out = tmp_path / ("out" + "".join(extra))
        assert (
            main(
                [
                    "predict",
                    str(render_png),
                    "--model",
                    str(d / "model.ts"),
                    "--out",
                    str(out),
                    *extra,
                ]
            )
            == 0
        )
        rows = list(csv.DictReader(open(out / "forces.csv")))
        assert list(rows[0]) == ["frame", "fx_N", "contact_mm", "valid"]
        assert float(rows[0]["contact_mm"]) == pytest.approx(want, abs=1e-3)
        assert f"contact {want:.2f} mm" in capsys.readouterr().out
    assert (tmp_path / "out--annotate" / f"{render_png.stem}_annotated.png").is_file()
    _, old = exported
    p_old = Predictor(old / "model.ts")
    assert not p_old.has_contact and np.isnan(p_old.contact(np.asarray(Image.open(render_png))))
    assert (
        main(
            [
                "predict",
                str(render_png),
                "--model",
                str(old / "model.ts"),
                "--out",
                str(tmp_path / "old"),
            ]
        )
        == 0
    )
    assert list(csv.DictReader(open(tmp_path / "old" / "forces.csv")))[0].keys() == {
        "frame",
        "fx_N",
        "valid",
    }


def test_annotate_marks_the_contact_height_on_the_front_edge():
    """A finger 30 px wide (1 px/mm) standing on row 180 of a synthetic frame: a contact
    at 40 mm is marked on its front (left) edge at row 140, and only when |fx| is above
    the threshold; without crop_y_mm a height cannot be placed."""
    from finray.annotate import CONTACT_RGB, annotate_frame, contact_point
    from finray.dataset.imageops import base_anchored_box

    frame = np.full((200, 100, 3), 60, np.uint8)
    mask = np.zeros((200, 100), bool)
    mask[20:180, 30:60] = True
    frame[mask] = 200
    box = base_anchored_box(mask, 30.0, (-5.0, 35.0), (0.0, 80.0))
    assert box == pytest.approx((25.0, 100.0, 65.0, 180.0))
    assert contact_point(mask, box, (0.0, 80.0), 40.0) == (140, 30)
    assert contact_point(mask, box, (0.0, 80.0), 79.0) == (101, 30)
    assert contact_point(mask, box, (0.0, 80.0), 200.0) is None  # above the frame
    stress = np.zeros((64, 32), np.float32)
    kw = dict(crop_y_mm=(0.0, 80.0), contact_min_force_N=0.2)
    marked = annotate_frame(frame, mask, box, stress, {"fx_N": 1.0, "contact_mm": 40.0}, **kw)
    plain = annotate_frame(frame, mask, box, stress, {"fx_N": 1.0}, **kw)
    weak = annotate_frame(frame, mask, box, stress, {"fx_N": 0.1, "contact_mm": 40.0}, **kw)
    weak_plain = annotate_frame(frame, mask, box, stress, {"fx_N": 0.1}, **kw)
    np.testing.assert_array_equal(weak, weak_plain)
    rows, cols = np.nonzero((marked != plain).any(axis=2))
    mark = rows > 100  # the text is at the top
    assert abs(rows[mark].mean() - 140) < 2 and abs(cols[mark].mean() - 30) < 10
    assert (marked[140, 18:26] == CONTACT_RGB).all(axis=1).any()  # the tick left of the edge
    with pytest.raises(ValueError, match="crop_y_mm"):
        annotate_frame(frame, mask, box, stress, {"fx_N": 1.0, "contact_mm": 40.0})


def test_predict_images_gives_the_contact_heights_on_request(exported_contact, exported):
    """The evaluation's batched predictions: a third array of heights (mm) with
    ``contact=True``, the same forces and maps as without; NaN for a model without the head."""
    from finray.evaluate.predictions import predict_images

    rng = np.random.default_rng(0)
    images = rng.integers(0, 256, (5, 64, 32), dtype=np.uint8)
    net, d = exported_contact
    p = Predictor(d / "model.ts", backend="torchscript")
    f, m, c = predict_images(p, images, batch=2, contact=True)
    f0, m0 = predict_images(p, images, batch=2)
    np.testing.assert_allclose(f, f0, atol=1e-5)
    np.testing.assert_allclose(m, m0, atol=1e-5)
    with torch.no_grad():
        want = net.contact(torch.from_numpy(images[:, None].astype(np.float32) / 255)).numpy()
    assert c.shape == (5,) and np.abs(c - want).max() < 1e-3
    assert np.isnan(
        predict_images(Predictor(exported[1] / "model.ts"), images, contact=True)[2]
    ).all()


def test_force_time_figure_adds_the_contact_height(tmp_path):
    from finray.annotate import force_time_figure

    rows = [
        {"frame": f"f{k}", "t_s": 0.1 * k, "fx_N": 0.5 * k, "contact_mm": 30.0 + k}
        for k in range(5)
    ]
    force_time_figure(rows, tmp_path / "c.png")
    force_time_figure(
        [{k: v for k, v in r.items() if k != "contact_mm"} for r in rows], tmp_path / "f.png"
    )
    h = [Image.open(tmp_path / n).size[1] for n in ("c.png", "f.png")]
    assert h[0] > 1.5 * h[1]  # a second panel


def test_a_truncated_mkv_reports_its_lost_frames(exported, render_png, tmp_path, capsys):
    """A Matroska file cut short: the container counts no frames, so its duration at the
    frame rate says how many to expect; the frames it lost are reported and skipped
    (exit code 1), as a corrupt frame of an MP4 is (it was 12 of 30 frames, exit 0)."""
    _, d = exported
    frames = [
        np.asarray(Image.open(f).convert("RGB"))
        for f in sorted(render_png.parent.glob("image_*.png"))
    ]
    video = write_video(tmp_path / "clip.mkv", (frames * 10)[:30])
    whole = [isinstance(f, np.ndarray) for _, f, _ in read_frames(video)]
    assert whole == [True] * 30  # the whole file: none lost
    data = video.read_bytes()
    video.write_bytes(data[: int(0.5 * len(data))])
    out = tmp_path / "out"
    argv = ["predict", "--model", str(d / "model.ts"), str(video), "--out", str(out)]
    assert main([*argv, "--backend", "torchscript", "--force-only"]) == 1
    err = err_lines(capsys.readouterr().err)
    rows = list(csv.DictReader(open(out / "forces.csv")))
    n_lost = 30 - len(rows)
    assert 0 < len(rows) < 30 and len(err) == n_lost + 1, err
    assert err[-1].startswith(f"finray predict: {n_lost} of 30 frames skipped")
    assert err[-2] == (
        "finray predict: skipped clip_00029: the frame is missing: the video "
        "ends before it (cut short?)"
    )
