"""Lab recordings: `finray ingest` on synthetic takes with a known clock offset, force
and finger mask (tests/recording_synth.py); the recording format's checks."""

import json
import shutil

import av
import numpy as np
import pandas as pd
import pytest

from finray.cli import main
from finray.dataset import load_shard
from finray.dataset.imageops import base_anchored_box, silhouette_input
from finray.recording import ColourRange, TakeError, align_clocks, learn_colour, segment_finger
from recording_synth import profile, write_take

SMALL = dict(size=(320, 240), duration_s=2.5, starts=(0.3, 1.35), ramp=0.35, hold=0.2)


def ingest_cli(take, out, capsys):
    rc = main(["ingest", str(take), "--out", str(out)])
    return rc, capsys.readouterr()


def error_line(take, out, capsys) -> str:
    """Exit code 2 and one line on stderr that names the subcommand, no traceback."""
    rc, cap = ingest_cli(take, out, capsys)
    lines = cap.err.strip().splitlines()
    assert rc == 2 and len(lines) == 1 and lines[0].startswith("finray ingest: "), cap.err
    assert "Traceback" not in cap.err
    return lines[0]


def iou(a, b):
    return (a & b).sum() / (a | b).sum()


@pytest.fixture(scope="module")
def mp4(tmp_path_factory):
    """30 FPS H.264 (4:4:4) take with two pushes, ingested."""
    d = tmp_path_factory.mktemp("mp4")
    truth = write_take(
        d / "take", pix_fmt="yuv444p", duration_s=2.5, starts=(0.3, 1.4), ramp=0.4, hold=0.25
    )
    assert main(["ingest", str(d / "take"), "--out", str(d / "out")]) == 0
    return d, truth


@pytest.fixture(scope="module")
def png(tmp_path_factory):
    """A frames/ folder of PNGs with frames.csv, the sensor at 1 kHz."""
    d = tmp_path_factory.mktemp("png")
    truth = write_take(d / "take", kind="frames", sensor_hz=1000.0, offset_s=12.3456, **SMALL)
    return d, truth


def test_mp4_take_offset_masks_and_shard(mp4):
    d, truth = mp4
    sync = json.loads((d / "out" / "sync.json").read_text())
    assert abs(sync["offset_s"] - truth["offset_s"]) < 1 / 30  # within one frame
    assert 0 < sync["uncertainty_s"] < 1 / 30 and sync["method"]
    # the colour masks: object (blue, touching) and clamp (grey) stay out
    frames = [
        f.to_ndarray(format="rgb24") for f in av.open(str(d / "take" / "take.mp4")).decode(video=0)
    ]
    colour = learn_colour(frames[:5])
    ious = [iou(segment_finger(f, colour), m) for f, m in zip(frames, truth["masks"])]
    assert len(ious) == 75 and min(ious) >= 0.95
    # the shard: training format, sensor labels, no stress map
    s = load_shard(d / "out" / "shard.npz")
    assert s["has_stress"] is False and s["meta"]["has_stress"] is False
    for k in ("128x64", "64x32"):
        assert s[f"input_{k}"].shape[0] == 75 and s[f"input_{k}"].dtype == np.uint8
        assert np.isnan(s[f"stress_{k}"]).all() and s[f"stress_{k}"].shape == s[f"input_{k}"].shape
        assert set(np.unique(s[f"mask_{k}"])) <= {0, 1}
    # the sensor's push (-fz, bias 0.1 N) at the frame times
    np.testing.assert_allclose(s["fx_N"], truth["force_N"] - 0.1, atol=0.08)
    table = pd.read_csv(d / "out" / "frames.csv")
    assert (table["status"] == "ok").all() and len(table) == 75
    np.testing.assert_allclose(table["force_N"], s["fx_N"], atol=1e-5)
    assert (d / "out" / "qa.png").stat().st_size > 10_000


def test_frame_folder_ingests_and_crops_like_the_predictor(png, tmp_path, capsys):
    d, truth = png
    rc, cap = ingest_cli(d / "take", tmp_path / "out", capsys)
    assert rc == 0, cap.err
    assert "clock offset" in cap.out
    sync = json.loads((tmp_path / "out" / "sync.json").read_text())
    assert abs(sync["offset_s"] - truth["offset_s"]) < 1 / 30
    s = load_shard(tmp_path / "out" / "shard.npz")
    # lossless frames: the colour mask is the drawn one, so the shard's input is the
    # base-anchored crop of the true mask
    for k, m in enumerate(truth["masks"][::10]):
        box = base_anchored_box(m, 30.0, (-5.0, 35.0), (0.0, 80.0), 4)
        np.testing.assert_array_equal(s["input_64x32"][10 * k], silhouette_input(m, box, (64, 32)))


def test_one_frame_gives_one_network_input_through_dataset_ingest_and_predictor(
    png, tmp_path, capsys
):
    """The input window has one home (finray.dataset.window): the camera views' path (the
    dataset's window of the config), ingest's shard and a model's Predictor (the window
    train_model writes into model.ts.json) cut and resample one mask alike."""
    import torch

    from finray.dataset import DatasetParams
    from finray.model import FinRayNet, NetConfig
    from finray.predictor import Predictor
    from finray.train.export import export_torchscript

    d, truth = png
    rc, cap = ingest_cli(d / "take", tmp_path / "out", capsys)
    assert rc == 0, cap.err
    s = load_shard(tmp_path / "out" / "shard.npz")
    window = DatasetParams().window(30.0)
    torch.manual_seed(0)
    net = FinRayNet(NetConfig(in_channels=1, base_channels=4, height=64, width=32)).eval()
    (tmp_path / "m").mkdir()
    export_torchscript(net, tmp_path / "m" / "model.ts", window.to_json())
    predictor = Predictor(tmp_path / "m" / "model.ts")
    assert predictor.window == window
    assert not any("preprocess" in n for n in predictor.notes), predictor.notes
    for k in range(0, len(truth["masks"]), 10):
        m = truth["masks"][k]
        dataset = window.inputs(m, [(64, 32)])[(64, 32)]
        np.testing.assert_array_equal(s["input_64x32"][k], dataset)
        x = np.rint(predictor.network_input(m)[0, 0] * 255.0).astype(np.uint8)
        np.testing.assert_array_equal(x, dataset)


def test_the_base_is_the_widest_of_four_rows_on_every_path():
    """A ragged bottom row (a video's colour blocks at the clamp, 12 px of the base's 60)
    does not set the scale: the window's base is the widest of the lowest 4 rows, on a
    mask too short for base_band to reach them."""
    from finray.dataset.window import BASE_ROWS, InputWindow

    mask = np.zeros((40, 100), bool)
    mask[5:39, 20:80] = True
    mask[39, 44:56] = True  # the ragged row
    box = InputWindow(base_band=0.0).box(mask)
    assert BASE_ROWS == 4
    assert box[2] - box[0] == pytest.approx(60 / 30.0 * 40.0)  # 2 px/mm x the 40 mm window


def test_a_sideways_camera_is_turned_by_take_json(png, tmp_path, capsys):
    """Frames filmed with the finger lying on its side (turned 90 deg clockwise) and
    ``rotate_deg: 90`` in take.json give the upright take's shard."""
    from PIL import Image

    d, _ = png
    side = tmp_path / "side"
    shutil.copytree(d / "take", side)
    for f in sorted((side / "frames").iterdir()):
        Image.fromarray(np.rot90(np.asarray(Image.open(f)), -1)).save(f)
    meta = json.loads((side / "take.json").read_text())
    (side / "take.json").write_text(json.dumps({**meta, "rotate_deg": 90}))
    rc, cap = ingest_cli(side, tmp_path / "out_side", capsys)
    assert rc == 0, cap.err
    rc, cap = ingest_cli(d / "take", tmp_path / "out_up", capsys)
    assert rc == 0, cap.err
    a, b = (
        load_shard(tmp_path / "out_side" / "shard.npz"),
        load_shard(tmp_path / "out_up" / "shard.npz"),
    )
    np.testing.assert_array_equal(a["input_64x32"], b["input_64x32"])


def test_60_fps_take_and_4_2_0_chroma(tmp_path, capsys):
    truth = write_take(tmp_path / "take", fps=60.0, offset_s=-3.21, **SMALL)
    rc, cap = ingest_cli(tmp_path / "take", tmp_path / "out", capsys)
    assert rc == 0, cap.err
    sync = json.loads((tmp_path / "out" / "sync.json").read_text())
    assert abs(sync["offset_s"] - truth["offset_s"]) < 1 / 60
    assert load_shard(tmp_path / "out" / "shard.npz")["fx_N"].shape == (150,)
    # 4:2:0 chroma (half resolution) blurs the colour edges: with walls ~6 px the masks
    # lose IoU (docs/guide/recordings.md, "Lab recordings"); the finger must still be whole
    frames = [
        f.to_ndarray(format="rgb24")
        for f in av.open(str(tmp_path / "take" / "take.mp4")).decode(video=0)
    ]
    colour = learn_colour(frames[:5])
    assert (
        min(iou(segment_finger(f, colour), m) for f, m in zip(frames[::10], truth["masks"][::10]))
        > 0.8
    )


def test_a_frame_that_does_not_decode_is_kept_as_unreadable(tmp_path, capsys):
    """One packet of the video zeroed: its frame is a row with status unreadable at its
    time, and ingest.json says why (finray.media's policy), not dropped."""
    write_take(tmp_path / "take", **SMALL)
    video = tmp_path / "take" / "take.mp4"
    with av.open(str(video)) as c:
        s = c.streams.video[0]
        packets = [
            (round(p.pts * p.time_base * s.average_rate), p.pos, p.size)
            for p in c.demux(s)
            if p.size and not p.is_keyframe
        ]
    rank, pos, size = max(packets)  # the last frame: no other frame depends on it
    data = bytearray(video.read_bytes())
    data[pos : pos + size] = bytes(size)
    video.write_bytes(bytes(data))
    rc, cap = ingest_cli(tmp_path / "take", tmp_path / "out", capsys)
    assert rc == 0, cap.err
    table = pd.read_csv(tmp_path / "out" / "frames.csv")
    assert len(table) == 75 and sorted(table["frame"]) == list(range(75))
    bad = table[table["status"] == "unreadable"]
    assert len(bad) == 1 and bad["t_s"].iloc[0] == pytest.approx(rank / 30, abs=1e-3)
    summary = json.loads((tmp_path / "out" / "ingest.json").read_text())
    assert summary["frames"]["unreadable"] == 1
    assert [x.split(":")[0] for x in summary["lost"]] == [f"frame {bad['frame'].iloc[0]}"]
    assert "the frame does not decode" in summary["lost"][0]


def test_mjpeg_avi_take(tmp_path, capsys):
    truth = write_take(tmp_path / "take", kind="avi", offset_s=0.5, **SMALL)
    rc, cap = ingest_cli(tmp_path / "take", tmp_path / "out", capsys)
    assert rc == 0, cap.err
    assert abs(json.loads((tmp_path / "out" / "sync.json").read_text())["offset_s"] - 0.5) < 1 / 30
    assert len(truth["t_s"]) == 75


def test_align_clocks_sub_frame_and_sign():
    rng = np.random.default_rng(1)
    t = np.arange(0, 6, 1 / 30)
    s = 2.0 * profile(t, (1.0, 3.5), 0.6, 0.5) + rng.normal(0, 0.01, len(t))
    ts = np.arange(100.0, 107.0, 1 / 500)
    offset = -100.0 + 0.4 + 0.0123  # camera = sensor + offset
    f = 5.0 * profile(ts + offset, (1.0, 3.5), 0.6, 0.5) + rng.normal(0, 0.02, len(ts))
    r = align_clocks(t, s, ts, f, 1 / 30)
    assert abs(r["offset_s"] - offset) < 0.1 / 30  # a tenth of a frame
    assert r["pearson_r"] > 0.99 and r["p_value"] <= 0.05
    with pytest.raises(TakeError, match="clocks cannot be aligned.*push_axis's sign"):
        align_clocks(t, s, ts, -f, 1 / 30)


def _copy(png, tmp_path):
    take = tmp_path / "take"
    shutil.copytree(png[0] / "take", take)
    return take


def test_error_missing_column(png, tmp_path, capsys):
    take = _copy(png, tmp_path)
    df = pd.read_csv(take / "forces.csv").drop(columns="fz_N")
    df.to_csv(take / "forces.csv", index=False)
    line = error_line(take, tmp_path / "out", capsys)
    assert "forces.csv: no column 'fz_N' (columns: t_s, fx_N, fy_N)" in line


def test_error_non_monotonic_time(png, tmp_path, capsys):
    take = _copy(png, tmp_path)
    df = pd.read_csv(take / "forces.csv")
    df.loc[20, "t_s"] = df.loc[18, "t_s"]
    df.to_csv(take / "forces.csv", index=False)
    assert "forces.csv: time is not increasing at line 22" in error_line(
        take, tmp_path / "out", capsys
    )
    take2 = _copy(png, tmp_path / "b")
    lines = (take2 / "frames.csv").read_text().splitlines()
    lines[3], lines[4] = lines[4], lines[3]
    (take2 / "frames.csv").write_text("\n".join(lines) + "\n")
    assert "frames.csv: time is not increasing at line 5" in error_line(
        take2, tmp_path / "out", capsys
    )


def test_error_too_few_samples(png, tmp_path, capsys):
    take = _copy(png, tmp_path)
    pd.read_csv(take / "forces.csv").head(5).to_csv(take / "forces.csv", index=False)
    assert "forces.csv: too few samples (5 rows; at least 10)" in error_line(
        take, tmp_path / "out", capsys
    )


def test_error_unreadable_video(png, tmp_path, capsys):
    take = _copy(png, tmp_path)
    shutil.rmtree(take / "frames")
    (take / "frames.csv").unlink()
    (take / "take.mp4").write_bytes(b"\x00\x01 not a video" * 100)
    assert "take.mp4 is not a readable video" in error_line(take, tmp_path / "out", capsys)


def test_error_no_finger(png, tmp_path, capsys):
    take = _copy(png, tmp_path)
    meta = json.loads((take / "take.json").read_text())
    meta["finger_colour"] = "green"  # the finger is orange: nothing green in view
    (take / "take.json").write_text(json.dumps(meta))
    line = error_line(take, tmp_path / "out", capsys)
    assert "no finger found in any of the 75 frames" in line and "hue 75-165 deg" in line
    # learned colour on grey frames: nothing coloured
    from PIL import Image

    for f in (take / "frames").iterdir():
        Image.fromarray(np.full((240, 320, 3), 128, np.uint8)).save(f)
    del meta["finger_colour"]
    (take / "take.json").write_text(json.dumps(meta))
    assert "no finger found: nothing coloured" in error_line(take, tmp_path / "out", capsys)


def test_error_clocks_cannot_be_aligned(png, tmp_path, capsys):
    take = _copy(png, tmp_path)
    df = pd.read_csv(take / "forces.csv")
    df["fz_N"] = np.random.default_rng(0).normal(0, 0.05, len(df))  # the sensor saw nothing
    df.to_csv(take / "forces.csv", index=False)
    line = error_line(take, tmp_path / "out", capsys)
    assert line.startswith("finray ingest: clocks cannot be aligned: ")


def test_error_bad_take_json(png, tmp_path, capsys):
    take = _copy(png, tmp_path)
    meta = json.loads((take / "take.json").read_text())
    meta["push_axis"] = "fw"
    (take / "take.json").write_text(json.dumps(meta))
    assert "take.json: push_axis: 'fw' does not match" in error_line(take, tmp_path / "out", capsys)


def test_colour_ranges_wrap_and_lab():
    rgb = np.array([[[230, 20, 40], [40, 200, 60], [128, 128, 128]]], np.uint8)  # red, green, grey
    assert ColourRange.from_take("red").contains(rgb).tolist() == [[True, False, False]]
    lab = ColourRange.from_take({"space": "lab", "lo": [30, -100, 0], "hi": [90, -30, 100]})
    assert lab.contains(rgb).tolist() == [[False, True, False]]


def test_training_refuses_a_shard_without_stress(mp4):
    from finray.train import load_split

    with pytest.raises(ValueError, match="has no stress map"):
        load_split([mp4[0] / "out" / "shard.npz"], (64, 32))
    # evaluation reads it through the same loader: sensor forces, NaN stress
    from finray.dataset import load_frames

    a, table = load_frames([mp4[0] / "out" / "shard.npz"], (64, 32))
    assert np.isnan(a["stress"]).all() and np.isfinite(a["fx_N"]).all()
    assert len(table) == len(a["images"]) > 0
