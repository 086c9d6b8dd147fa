"""Fast segmentation and resampling: the same results as the reference (skimage)
pipeline and the plain weight-matrix products."""

import numpy as np
import pytest
from skimage import filters, measure, morphology

from finray.dataset.imageops import (
    _axis_weights,
    area_resample,
    segment,
    threshold_isodata,
    to_gray,
)


def reference_segment(image, min_object_frac=1e-3, max_hole_frac=2e-4, keep_largest=True):
    """The segmentation as first written: skimage on the whole float64 image."""
    g = to_gray(image)
    mask = g > (g.min() if g.min() == g.max() else filters.threshold_isodata(g))
    n = mask.size
    mask = morphology.remove_small_objects(mask, max_size=int(round(min_object_frac * n)))
    mask = morphology.remove_small_holes(mask, max_size=int(round(max_hole_frac * n)))
    if keep_largest and mask.any():
        lab = measure.label(mask, connectivity=2)
        counts = np.bincount(lab.ravel())
        counts[0] = 0
        mask = lab == int(np.argmax(counts))
    return mask


def blobby_image(rng, h=120, w=60, noise=30.0):
    """A finger-like bright shape with cavities, specks, small holes and fragments,
    8-bit RGB on a dark background."""
    yy, xx = np.mgrid[:h, :w]
    shape = np.zeros((h, w), bool)
    x0 = int(rng.integers(3, w // 3))
    shape[int(rng.integers(2, 10)) : h - 3, x0 : x0 + 4] = True
    shape[5 : h - 3, w - 12 : w - 8] = True
    for y in rng.integers(10, h - 10, size=5):
        shape[y : y + 2, x0 : w - 8] = True  # ribs (cavities between them)
    for _ in range(int(rng.integers(0, 6))):  # fragments, some touching diagonally
        cy, cx = rng.integers(0, h), rng.integers(0, w)
        shape |= (yy - cy) ** 2 + (xx - cx) ** 2 <= rng.uniform(0.5, 4) ** 2
    img = np.where(shape[..., None], [220, 140, 40], [15, 15, 15]).astype(float)
    img += rng.normal(0, noise, img.shape)
    specks = rng.random((h, w)) < 0.003
    img[specks] = 255 - img[specks]  # bright specks on the background, dark holes in the finger
    return np.clip(img, 0, 255).astype(np.uint8)


@pytest.mark.parametrize("seed", range(40))
def test_segment_equals_the_skimage_pipeline(seed):
    rng = np.random.default_rng(seed)
    img = blobby_image(rng, noise=[5.0, 30.0, 60.0][seed % 3])
    np.testing.assert_array_equal(segment(img), reference_segment(img))
    # larger holes/specks allowed, no largest-component step
    kw = dict(min_object_frac=5e-3, max_hole_frac=3e-3, keep_largest=bool(seed % 2))
    np.testing.assert_array_equal(segment(img, **kw), reference_segment(img, **kw))


def test_segment_on_fixture_renders(tmp_path):
    """The fabricated scene's camera frames (test_render_fixture.py), front view."""
    from finray.render import RenderParams, load_render_index, read_render_frame, render_scene
    from helpers import write_synthetic_fea_result

    res = write_synthetic_fea_result(tmp_path / "result.npz", n_frames=5)
    render_scene(
        res,
        tmp_path / "p0",
        0.0,
        params=RenderParams(frames_per_scene=5),
        scene={"object": "ellipse_16x9", "material": "steel", "height_mm": 30.0, "split": "shape"},
    )
    n_frames = len(load_render_index(tmp_path / "p0")["frames"])
    for k in range(n_frames):
        rgb = read_render_frame(tmp_path / "p0", k)[0]
        np.testing.assert_array_equal(segment(rgb), reference_segment(rgb))
    assert n_frames == 5


def test_segment_edge_cases():
    assert not segment(np.zeros((20, 10, 3), np.uint8)).any()
    flat = np.full((20, 10), 0.7)
    assert not segment(flat).any()
    one = np.zeros((30, 30))
    one[10:20, 12:18] = 1.0
    np.testing.assert_array_equal(segment(one), one > 0.5)
    full = np.ones((16, 16))
    full[0, 0] = 0.0
    np.testing.assert_array_equal(segment(full), reference_segment(full))


def framed(img, shape=(720, 1280), at=(300, 500), bg=15):
    """``img`` placed in a larger camera frame of background ``bg``."""
    out = np.full(shape + img.shape[2:], bg, img.dtype)
    out[at[0] : at[0] + img.shape[0], at[1] : at[1] + img.shape[1]] = img
    return out


@pytest.mark.parametrize("seed", range(12))
def test_segment_roi_stride_matches_the_whole_frame(seed):
    """The coarse-to-fine segmentation: with the same grey level, the mask of the whole
    frame pixel for pixel; with the threshold from the coarse grid, the same mask up
    to a few edge pixels."""
    rng = np.random.default_rng(seed)
    img = framed(blobby_image(rng, noise=[5.0, 30.0][seed % 2]), at=(300 + seed, 500 + 3 * seed))
    stride = [2, 3, 4][seed % 3]  # the shape's bars are 4 px wide: each meets the grid
    for kw in ({"threshold": 0.3}, {"threshold": 0.3, "keep_largest": False}):
        np.testing.assert_array_equal(segment(img, roi_stride=stride, **kw), segment(img, **kw))
    fast, whole = segment(img, roi_stride=stride), segment(img)
    assert (fast != whole).sum() <= 0.02 * whole.sum()
    dark = 255 - img  # a dark finger on a bright background
    np.testing.assert_array_equal(
        segment(dark, foreground="dark", threshold=0.7, roi_stride=stride),
        segment(dark, foreground="dark", threshold=0.7),
    )


def test_segment_roi_stride_edge_cases():
    assert not segment(np.zeros((720, 1280, 3), np.uint8), roi_stride=4).any()
    one = np.zeros((300, 200))
    one[3:150, 1:7] = 1.0  # at the frame's edge, between grid rows and columns
    np.testing.assert_array_equal(segment(one, roi_stride=4), one > 0.5)
    with pytest.raises(ValueError, match="foreground"):
        segment(one, foreground="grey", roi_stride=4)


def test_threshold_isodata_matches_skimage():
    rng = np.random.default_rng(0)
    for _ in range(50):
        g = np.concatenate(
            [
                rng.normal(rng.uniform(0, 0.4), 0.05, 500),
                rng.normal(rng.uniform(0.5, 1), 0.1, int(rng.integers(50, 900))),
            ]
        )
        assert threshold_isodata(g) == pytest.approx(filters.threshold_isodata(g), abs=1e-12)


def test_isodata_small_finger_on_a_video_background():
    """A video frame: a finger on 1 % of the frame over a flat dark background with a
    few darker compression specks. skimage's lowest isodata level falls between the
    specks and the background (the background would be segmented as the finger); the
    level kept separates the finger, and the mask is the finger."""
    rng = np.random.default_rng(0)
    g = np.full((320, 180), 12.0)
    g.flat[rng.choice(g.size, 150, replace=False)] = rng.integers(4, 12, 150)
    g[150:190, 80:95] = 150.0
    levels = filters.threshold_isodata(g / 255, return_all=True) * 255
    assert len(levels) == 2 and levels[0] < 12 < 150 > levels[1] > 12
    assert threshold_isodata(g / 255) * 255 == pytest.approx(levels[1])
    img = np.repeat(g.astype(np.uint8)[..., None], 3, axis=2)
    for stride in (1, 4):
        np.testing.assert_array_equal(segment(img, roi_stride=stride), g == 150.0)


def test_axis_weights_sparse_build():
    """Each row is the covered fraction of the cell by each source pixel: rows sum to
    the covered share of the cell, entries in [0, 1]."""
    w = _axis_weights(10, -2.5, 12.5, 6)
    assert w.shape == (6, 10)
    np.testing.assert_allclose(w.sum(1), [0.0, 1.0, 1.0, 1.0, 1.0, 0.0])
    assert w.min() >= 0 and w.max() <= 1
    np.testing.assert_allclose(_axis_weights(4, 0, 4, 2), [[0.5, 0.5, 0, 0], [0, 0, 0.5, 0.5]])


@pytest.mark.parametrize(
    "box",
    [
        (-20.3, 7.7, 140.2, 330.1),
        (0, 0, 160, 336),
        (3.5, -10, 30.25, 50.5),
        (-50, -50, 400, 500),
        (170, 10, 200, 40),
    ],
)
def test_fast_resample_equals_the_products(box):
    rng = np.random.default_rng(3)
    mask = rng.random((336, 160)) > 0.5
    for out in [(64, 32), (128, 64), (7, 3)]:
        a = area_resample(mask, box, out)
        b = area_resample(mask, box, out, fast=True)
        assert b.shape == a.shape == out
        np.testing.assert_allclose(b, a, atol=1e-12)
