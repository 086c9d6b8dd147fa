"""Dataset stage: crop + area resampling, segmentation, shards, manifest, splits, figure."""

from __future__ import annotations

import numpy as np
import pandas as pd
import pytest

from finray.dataset import (
    MANIFEST_COLUMNS,
    DatasetParams,
    FramePreparer,
    area_resample,
    build_shard,
    example_figure,
    load_shard,
    pitch_object,
    render_shard,
    scene_splits,
    segment,
    write_manifest,
)
from finray.dataset.params import SHARD_KEYS
from finray.render import RenderParams, load_render_index, read_render_frame, render_scene

from helpers import write_synthetic_fea_result


@pytest.fixture(scope="module")
def renders(tmp_path_factory):
    """The fixture scene rendered at pitch 0 and 20 (3 frames each)."""
    tmp = tmp_path_factory.mktemp("ds")
    res = write_synthetic_fea_result(tmp / "result.npz", n_frames=5)
    params = RenderParams(frames_per_scene=3)
    scene = {"object": "ellipse_16x9", "material": "steel", "height_mm": 30.0, "split": "shape"}
    out = {}
    for pitch in (0.0, 20.0):
        out[pitch] = tmp / f"p{pitch:g}"
        render_scene(res, out[pitch], pitch, params=params, scene=scene)
    return out


def test_area_resample_is_an_exact_area_average():
    rng = np.random.default_rng(0)
    img = rng.random((40, 20))
    # integer factor: block means
    out = area_resample(img, (0, 0, 20, 40), (10, 5))
    np.testing.assert_allclose(out, img.reshape(10, 4, 5, 4).mean(axis=(1, 3)))
    # non-integer factor: the mean is preserved
    out = area_resample(img, (0, 0, 20, 40), (16, 8))
    assert out.mean() == pytest.approx(img.mean())
    # fractional crop of a constant image: constant inside, outside counts as 0
    one = np.ones((40, 20))
    np.testing.assert_allclose(area_resample(one, (2.5, 3.25, 12.5, 23.25), (8, 4)), 1.0)
    edge = area_resample(one, (-2.0, 0.0, 18.0, 40.0), (4, 2))
    np.testing.assert_allclose(edge[:, 0], 0.8)
    # colour images resample channel by channel
    rgb = rng.random((40, 20, 3))
    np.testing.assert_allclose(
        area_resample(rgb, (0, 0, 20, 40), (8, 4))[..., 1],
        area_resample(rgb[..., 1], (0, 0, 20, 40), (8, 4)),
    )


def test_segmentation_works_on_a_noisy_camera_like_image():
    rng = np.random.default_rng(1)
    h, w = 200, 100
    truth = np.zeros((h, w), bool)
    truth[20:180, 30:40] = True  # a wall
    truth[20:30, 30:80] = True  # a rib
    truth[100:104, 30:80] = True  # a thin rib
    truth[20:180, 70:80] = True
    img = np.where(truth[..., None], [200, 120, 40], [20, 25, 30]).astype(float)
    img += rng.normal(0, 12, img.shape)  # sensor noise
    img[5, 5] = img[150, 55] = 255  # specks on the background
    img[60, 35] = 0  # a dark speck on the finger
    seg = segment(np.clip(img, 0, 255).astype(np.uint8))
    assert (seg == truth).mean() > 0.999
    assert not seg[5, 5] and not seg[150, 55] and seg[60, 35]
    # the cavities (large holes) stay open
    assert not seg[60:90, 45:65].any()
    # dark finger on a bright background
    seg_dark = segment(255 - np.clip(img, 0, 255).astype(np.uint8), foreground="dark")
    assert (seg_dark == truth).mean() > 0.999


def test_build_shard_and_manifest(renders, tmp_path):
    params = DatasetParams()
    splits0 = scene_splits("shape", 0.0, is_pitch_object=True)
    splits20 = scene_splits("shape", 20.0, is_pitch_object=True)
    assert splits0 == ["shape", "pitch"] and splits20 == ["pitch"]
    m0 = build_shard(renders[0.0], tmp_path / "s0.npz", {"splits": splits0}, params)
    m20 = build_shard(renders[20.0], tmp_path / "s20.npz", {"splits": splits20}, params)
    assert m0["scene"]["scene_id"] == "ellipse_16x9_steel_h30_p0"
    assert m20["scene"]["pitch_deg"] == 20.0
    d = load_shard(tmp_path / "s0.npz")
    for h, w in params.sizes:
        k = f"{h}x{w}"
        assert d[f"input_{k}"].shape == (3, h, w) and d[f"input_{k}"].dtype == np.uint8
        assert d[f"mask_{k}"].shape == (3, h, w) and set(np.unique(d[f"mask_{k}"])) == {0, 1}
        assert d[f"stress_{k}"].dtype == np.float32 and (d[f"stress_{k}"] >= 0).all()
        # at pitch 0 the stress support and the segmented mask agree (up to the
        # rounding of sub-pixel ribs: the mask is the area average of a binary
        # segmentation, the stress support that of the exact coverage)
        for f in range(3):
            sup, mask = d[f"stress_{k}"][f] > 0, d[f"mask_{k}"][f] == 1
            assert (sup & mask).sum() / (sup | mask).sum() >= 0.93
    # the soft input keeps sub-pixel ribs: more finger area than the binary mask shows
    assert d["input_64x32"][0].sum() / 255 == pytest.approx(d["mask_64x32"][0].sum(), rel=0.25)
    np.testing.assert_allclose(d["displacement_mm"], [0.0, 2.5, 5.0])
    assert d["fx_N"][0] == 0.0 and d["fx_N"][-1] == pytest.approx(3.0)
    # the finger area in the input equals the rendered area (area averaging is exact)
    index = load_render_index(renders[0.0])
    _, maps = read_render_frame(renders[0.0], 0, index)
    rp = RenderParams.from_config(index["params"])
    cov_mm2 = maps["coverage"].sum() / rp.px_per_mm**2
    px_mm = (params.crop_x_mm[1] - params.crop_x_mm[0]) / 64
    inp_mm2 = d["input_128x64"][0].sum() / 255 * px_mm**2
    assert inp_mm2 == pytest.approx(cov_mm2, rel=0.02)

    df = write_manifest(
        [tmp_path / "s0.npz", tmp_path / "s20.npz"], tmp_path / "manifest.csv", relative_to=tmp_path
    )
    back = pd.read_csv(tmp_path / "manifest.csv")
    assert list(back.columns) == MANIFEST_COLUMNS
    assert len(back) == len(df) == 3 * 2 + 3
    pitch = back[back.split == "pitch"]
    assert sorted(pitch.pitch_deg.unique()) == [0.0, 20.0]
    assert (back[back.split == "shape"].pitch_deg == 0).all()
    assert set(back.shard) == {"s0.npz", "s20.npz"}
    assert (back.object == "ellipse_16x9").all() and (back.height_mm == 30.0).all()


def test_pitched_shard_keeps_the_front_stress_map(renders, tmp_path):
    build_shard(renders[0.0], tmp_path / "a.npz")
    build_shard(renders[20.0], tmp_path / "b.npz", {"splits": ["pitch"]})
    a, b = load_shard(tmp_path / "a.npz"), load_shard(tmp_path / "b.npz")
    np.testing.assert_array_equal(a["stress_128x64"], b["stress_128x64"])
    assert not np.array_equal(a["input_128x64"], b["input_128x64"])


def test_splits_and_pitch_object():
    cfg = {
        "objects": {
            "circle_d5": {"split": "train"},
            "ring_d15": {"split": "material"},
            "ellipse_16x9": {"split": "shape"},
            "tri": {"split": "shape"},
        }
    }
    assert pitch_object(cfg) == "ellipse_16x9"
    assert pitch_object(dict(cfg, dataset={"pitch_object": "tri"})) == "tri"
    with pytest.raises(ValueError, match="pitch_object"):
        pitch_object(dict(cfg, dataset={"pitch_object": "nope"}))
    assert scene_splits("train", 0.0, False) == ["train"]
    assert scene_splits("material", 0.0, False) == ["material"]
    with pytest.raises(ValueError):
        scene_splits("train", 10.0, False)


def test_params_from_config():
    p = DatasetParams.from_config(
        {
            "sizes": [[64, 32]],
            "noise_levels": {"none": 0, "low": 0.2},
            "occlusion_levels": {"none": [0, 0], "high": [0.8, 1.0]},
            "crop_x_mm": [0, 40],
            "crop_y_mm": [0, 80],
            "unrelated": 1,
        }
    )
    assert p.sizes == ((64, 32),) and p.noise == {"none": 0.0, "low": 0.2}
    assert p.occlusion["high"] == (0.8, 1.0)
    with pytest.raises(ValueError, match="height = 2 x width"):
        DatasetParams(sizes=((64, 64),))
    r = RenderParams.from_config({"px_per_mm": 8, "window_x_mm": [-5, 35], "pitches_deg": [0, 5]})
    assert r.shape == (84 * 8, 40 * 8)


def test_example_figure(renders, tmp_path):
    out = example_figure(renders[0.0], tmp_path / "fig.png", pitch_dirs=renders)
    assert out.stat().st_size > 10_000


def test_frame_preparer_is_the_exact_area_average(renders):
    """The banded weights give area_resample's values; masks and stress support use
    ">= half" robustly (exact half-covered pixels count as covered)."""
    params = DatasetParams(sizes=((128, 64), (64, 32), (50, 25)))
    index = load_render_index(renders[0.0])
    rgb, maps = read_render_frame(renders[0.0], 2, index)
    rp = RenderParams.from_config(index["params"])
    for box in (rp.box_px(params.crop_x_mm, params.crop_y_mm), (-3.3, 2.7, 150.1, 302.3)):
        out = FramePreparer(rp.shape, box, params).prepare(rgb, maps)
        sil = params.segment(rgb).astype(float)
        for size in params.sizes:
            k = f"{size[0]}x{size[1]}"
            soft = area_resample(sil, box, size)
            np.testing.assert_array_equal(out[f"input_{k}"], np.rint(soft * 255).astype(np.uint8))
            np.testing.assert_array_equal(out[f"mask_{k}"], soft >= 0.5 - 1e-9)
            cov = area_resample(maps["coverage"], box, size)
            area = area_resample(maps["stress_area"], box, size)
            ref = np.where(cov >= 0.5 - 1e-9, area / np.maximum(cov, 1e-300), 0.0)
            np.testing.assert_allclose(out[f"stress_{k}"], ref, rtol=1e-6, atol=1e-7)
    # a half-covered pixel is a mask pixel whatever the rounding of the sums
    half = np.zeros((8, 4, 3), np.uint8)
    half[:, :2] = 255
    one = FramePreparer(
        (8, 4),
        (0, 0, 4, 8),
        DatasetParams(sizes=((2, 1),), threshold=0.5, min_object_frac=0, max_hole_frac=0),
    )
    assert one.prepare(half)["mask_2x1"].tolist() == [[1], [1]]


def test_render_shard_equals_build_shard_of_all_files(renders, tmp_path):
    """One pass (frames in memory, a few files) gives the shard that rendering every
    frame to files and reading them back gives."""
    scene = {"object": "ellipse_16x9", "material": "steel", "height_mm": 30.0, "split": "shape"}
    for pitch in (0.0, 20.0):
        rp = RenderParams(frames_per_scene=3, files_per_scene=2)
        meta = render_shard(
            renders[0.0].parent / "result.npz",
            tmp_path / f"r{pitch:g}",
            tmp_path / f"s{pitch:g}.npz",
            pitch,
            render_params=rp,
            scene=dict(scene, splits=["pitch"]),
        )
        assert meta["scene"]["scene_id"] == f"ellipse_16x9_steel_h30_p{pitch:g}"
        assert meta["scene"]["splits"] == ["pitch"]
        # the settings its arrays depend on, the ones the workflow re-renders for
        assert sorted(meta["dataset"]) == sorted(SHARD_KEYS)
        if pitch == 0.0:  # every frame's image and stress support are pixel-aligned
            assert meta["support_iou_min"] >= 0.98
        build_shard(renders[pitch], tmp_path / f"b{pitch:g}.npz", {"splits": ["pitch"]})
        a, b = load_shard(tmp_path / f"s{pitch:g}.npz"), load_shard(tmp_path / f"b{pitch:g}.npz")
        assert sorted(a) == sorted(b)
        for key in a:
            if key != "meta":
                np.testing.assert_array_equal(a[key], b[key], err_msg=key)
        assert a["meta"]["support_iou_min"] == b["meta"]["support_iou_min"]
        # files only for the first and the last frame; the index lists every frame
        index = load_render_index(tmp_path / f"r{pitch:g}")
        assert index["n_frames"] == 3 and index["n_files"] == 2
        assert [f["image"] is not None for f in index["frames"]] == [True, False, True]
        assert sorted(p.name for p in (tmp_path / f"r{pitch:g}").iterdir()) == [
            "image_0000.png",
            "image_0002.png",
            "index.json",
            "stress_0000.exr",
            "stress_0002.exr",
        ]
        rgb, _ = read_render_frame(tmp_path / f"r{pitch:g}", 2, index)
        np.testing.assert_array_equal(rgb, read_render_frame(renders[pitch], 2)[0])
        with pytest.raises(FileNotFoundError, match="files_per_scene"):
            read_render_frame(tmp_path / f"r{pitch:g}", 1, index)
    # the example figure needs only the last frame's files
    dirs = {0.0: tmp_path / "r0", 20.0: tmp_path / "r20"}
    assert example_figure(dirs[0.0], tmp_path / "fig.png", pitch_dirs=dirs).stat().st_size > 10_000


def test_written_frames():
    assert RenderParams().written_frames(4).tolist() == [0, 1, 2, 3]
    assert RenderParams(files_per_scene=5).written_frames(444).tolist() == [0, 111, 222, 332, 443]
    assert RenderParams(files_per_scene=1).written_frames(444).tolist() == [443]
    assert RenderParams(files_per_scene=0).written_frames(444).tolist() == []
    assert RenderParams(files_per_scene=9).written_frames(3).tolist() == [0, 1, 2]


def test_a_shard_carries_the_contact_height_of_its_result(tmp_path):
    """The FEA result's contact_y_mm (mm, NaN without contact) reaches the render index
    and the shard per rendered frame, resampled with the frames; a result without it
    gives NaN."""
    src = write_synthetic_fea_result(tmp_path / "plain.npz", n_frames=5)
    d = dict(np.load(src))
    d["contact_y_mm"] = np.array([np.nan, 30.0, 31.0, 32.0, 33.0])
    np.savez(tmp_path / "result.npz", **d)
    rp = RenderParams(frames_per_scene=3, files_per_scene=0)
    scene = {"object": "ellipse_16x9", "material": "steel", "height_mm": 30.0, "split": "shape"}
    render_shard(
        tmp_path / "result.npz",
        tmp_path / "r",
        tmp_path / "s.npz",
        0.0,
        render_params=rp,
        scene=scene,
    )
    want = [np.nan, 31.0, 33.0]  # displacements 0, 2.5, 5 mm: solver frames 0, 2, 4
    np.testing.assert_array_equal(load_shard(tmp_path / "s.npz")["contact_y_mm"], want)
    np.testing.assert_array_equal(
        [f["contact_y_mm"] for f in load_render_index(tmp_path / "r")["frames"]], want
    )
    render_shard(src, tmp_path / "r0", tmp_path / "s0.npz", 0.0, render_params=rp, scene=scene)
    assert np.isnan(load_shard(tmp_path / "s0.npz")["contact_y_mm"]).all()
