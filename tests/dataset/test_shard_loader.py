"""One shard reader: training (load_split) and evaluation (load_test_set) read the same
frames through finray.dataset.load_frames."""

import json

import numpy as np
import pytest

from finray.dataset import FRAME_COLUMNS, load_frames, load_shard
from finray.dataset.shards import save_npz
from finray.evaluate.predictions import load_test_set
from finray.train import load_split


def _shard(path, scene_id, n, seed):
    rng = np.random.default_rng(seed)
    arrays = {}
    for h, w in ((8, 4), (16, 8)):
        arrays[f"input_{h}x{w}"] = rng.integers(0, 256, (n, h, w), dtype=np.uint8)
        arrays[f"stress_{h}x{w}"] = rng.normal(size=(n, h, w)).astype(np.float32)
        arrays[f"mask_{h}x{w}"] = rng.random((n, h, w)) > 0.5
    scene = {
        "scene_id": scene_id,
        "object": scene_id.split("_")[0],
        "material": "steel",
        "height_mm": 30.0,
        "pitch_deg": 0.0,
        "split": "train",
        "splits": ["train"],
    }
    arrays.update(
        frame=np.arange(n, dtype=np.int32),
        fea_frame=np.linspace(0, 20, n),
        displacement_mm=np.linspace(0, 10, n),
        fx_N=-np.linspace(0, 5, n) * (seed + 1),
        fy_N=np.zeros(n),
        meta=np.array(json.dumps({"scene": scene})),
    )
    save_npz(path, arrays)
    return path


@pytest.fixture()
def shards(tmp_path):
    return [
        _shard(tmp_path / "b.npz", "square_s10", 5, 1),
        _shard(tmp_path / "a.npz", "circle_d5", 4, 0),
    ]


def test_load_frames_reads_one_size_as_stored(shards):
    a, t = load_frames(shards, (16, 8), every=2)
    d0, d1 = load_shard(shards[0]), load_shard(shards[1])
    for key, stored in (("images", "input_16x8"), ("stress", "stress_16x8"), ("mask", "mask_16x8")):
        np.testing.assert_array_equal(a[key], np.concatenate([d0[stored][::2], d1[stored][::2]]))
    assert (
        a["images"].dtype == np.uint8
        and a["stress"].dtype == np.float32
        and a["mask"].dtype == bool
    )
    assert list(t.columns) == FRAME_COLUMNS
    assert t["scene_id"].tolist() == ["square_s10"] * 3 + ["circle_d5"] * 2  # the order given
    assert t["frame"].tolist() == [0, 2, 4, 0, 2]
    np.testing.assert_array_equal(t["fx_N"], a["fx_N"])
    with pytest.raises(ValueError, match="no shards given"):
        load_frames([], (16, 8))


def test_training_and_evaluation_read_the_same_frames(shards):
    tr = load_split(shards, (8, 4))
    arrays, table = load_test_set(shards, (8, 4))
    # evaluation sorts the paths (a.npz first); training keeps the given order
    order = np.r_[5:9, 0:5]
    np.testing.assert_array_equal(tr["images"][order, 0], arrays["images"] / np.float32(255))
    assert tr["images"].dtype == np.float32 and tr["images"].shape == (9, 1, 8, 4)
    np.testing.assert_array_equal(tr["stress"][order, 0], arrays["stress"])
    np.testing.assert_array_equal(tr["mask"][order], arrays["mask"])
    np.testing.assert_array_equal(tr["fx_N"][order, 0], arrays["fx_N"].astype(np.float32))
    np.testing.assert_array_equal(tr["scene_id"][order], table["scene_id"])
    np.testing.assert_array_equal(tr["displacement_mm"][order], table["displacement_mm"])
    assert tr["scene_id"].dtype.kind == "U"
    assert table["object"].tolist() == ["circle"] * 4 + ["square"] * 5


def test_no_context_frames_in_each_view(shards, tmp_path):
    """The no-context fit's simulated frames: front, camera or both views, forces and
    table row for row with the images; camera views a shard lacks are one clear error."""
    from finray.sim2real.experiment import _frames

    cam = [tmp_path / f"cam{i}.npz" for i in range(len(shards))]
    for src, dst in zip(shards, cam):
        with np.load(src) as f:
            d = {k: f[k] for k in f.files}
        d["camera_input_16x8"] = 255 - d["input_16x8"]
        save_npz(dst, d)
    x_f, y_f, t_f = _frames(cam, (16, 8))
    x_c, y_c, _ = _frames(cam, (16, 8), views="camera")
    x_b, y_b, t_b = _frames(cam, (16, 8), views="both")
    assert x_f.shape == x_c.shape == (9, 1, 16, 8) and x_b.shape == (18, 1, 16, 8)
    np.testing.assert_allclose(x_c, 1 - x_f, atol=1e-6)
    np.testing.assert_array_equal(x_b, np.concatenate([x_f, x_c]))
    np.testing.assert_array_equal(y_c, y_f)
    np.testing.assert_array_equal(y_b, np.r_[y_f, y_f])
    assert t_b["scene_id"].tolist() == t_f["scene_id"].tolist() * 2 and len(t_b) == len(y_b)
    with pytest.raises(
        ValueError, match="sim_views: both reads the camera views.*set sim_views: front"
    ):
        _frames(shards, (16, 8), views="both")
    with pytest.raises(ValueError, match="sim_views: 'side' is not one of"):
        _frames(cam, (16, 8), views="side")


def test_contact_heights_are_read_and_nan_where_a_shard_has_none(shards, tmp_path):
    """A shard's contact_y_mm (mm) reaches load_frames, load_split (contact_mm), the
    manifest and load_shard; a shard without it (built before it, a recording) gives NaN."""
    from finray.dataset import write_manifest

    d = dict(np.load(shards[1]))
    d["contact_y_mm"] = np.array([np.nan, 20.0, 30.0, 40.0])
    save_npz(shards[1], d)
    a, t = load_frames(shards, (8, 4))
    assert np.isnan(a["contact_y_mm"][:5]).all()
    np.testing.assert_array_equal(a["contact_y_mm"][5:], d["contact_y_mm"])
    np.testing.assert_array_equal(t["contact_y_mm"], a["contact_y_mm"])
    tr = load_split(shards, (8, 4))
    assert tr["contact_mm"].dtype == np.float32
    np.testing.assert_array_equal(tr["contact_mm"], a["contact_y_mm"].astype(np.float32))
    assert np.isnan(load_shard(shards[0])["contact_y_mm"]).all()
    m = write_manifest(shards, tmp_path / "manifest.csv")
    assert m.loc[m["scene_id"] == "circle_d5", "contact_y_mm"].tolist()[1:] == [20.0, 30.0, 40.0]
