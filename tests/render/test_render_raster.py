"""Render stage: rasteriser correctness, pixel alignment, pyvista agreement, EXR files."""

from __future__ import annotations

import json

import numpy as np
import pytest

from finray.dataset import segment
from finray.geometry.mesh import TriMesh
from finray.render import (
    RenderParams,
    Rasterizer,
    ResultError,
    load_fea_result,
    load_render_index,
    read_exr,
    read_png,
    read_render_frame,
    render_scene,
    resample_frames,
    stress_transform,
    write_exr,
    write_png,
)

from helpers import mm_to_px, write_synthetic_fea_result


def iou(a: np.ndarray, b: np.ndarray) -> float:
    return float((a & b).sum() / max((a | b).sum(), 1))


@pytest.fixture(scope="module")
def result_path(tmp_path_factory):
    return write_synthetic_fea_result(tmp_path_factory.mktemp("fea") / "result.npz", n_frames=6)


@pytest.fixture(scope="module")
def result(result_path):
    return load_fea_result(result_path)


@pytest.fixture(scope="module")
def front_render(result_path, tmp_path_factory):
    out = tmp_path_factory.mktemp("render") / "p0"
    render_scene(
        result_path,
        out,
        0.0,
        scene={"object": "circle_d10", "material": "steel", "height_mm": 30, "split": "train"},
        params=RenderParams(files_per_scene=None),
    )  # every frame's files
    return out


def grid_mesh(n: int, h: float, x0: float, y0: float) -> TriMesh:
    """Linear triangles on an n x n grid of spacing h (both diagonals' orientations)."""
    xs = x0 + h * np.arange(n + 1)
    ys = y0 + h * np.arange(n + 1)
    X, Y = np.meshgrid(xs, ys, indexing="ij")
    pts = np.column_stack([X.ravel(), Y.ravel()])
    idx = np.arange((n + 1) ** 2).reshape(n + 1, n + 1)
    tris = []
    for i in range(n):
        for j in range(n):
            a, b, c, d = idx[i, j], idx[i + 1, j], idx[i + 1, j + 1], idx[i, j + 1]
            tris += [[a, b, c], [a, c, d]] if (i + j) % 2 else [[a, b, d], [b, c, d]]
    return TriMesh(pts, np.array(tris), np.zeros((0, 3), int), np.zeros(0, int))


def test_coverage_integrates_to_the_finger_area(result):
    params = RenderParams()
    r = Rasterizer(result.mesh, params)
    cov, stress, stress_area = r.render(result.points, np.zeros(len(result.points)))
    area = cov.sum() / params.px_per_mm**2
    from finray.geometry.mesh import signed_areas

    true_area = signed_areas(result.points, result.triangles).sum()
    assert area == pytest.approx(true_area, rel=2e-3)
    assert cov.max() <= 1.0 and cov.min() >= 0.0
    assert np.all(stress == 0.0) and np.all(stress_area == 0.0)


def test_samples_on_shared_edges_count_once():
    # vertices exactly on sample centres: every edge passes through samples
    params = RenderParams(
        window_x_mm=(0.0, 12.0), window_y_mm=(0.0, 12.0), px_per_mm=1.0, supersample=1
    )
    mesh = grid_mesh(5, 1.0, 1.5, 1.5)  # square [1.5, 6.5]^2, vertices on pixel centres
    r = Rasterizer(mesh, params)
    r.render(mesh.points)
    assert r._count.max() == 1  # no sample claimed by two triangles
    assert r._count.sum() == 25  # 6 x 6 samples on the closed square, half-open edges -> 5 x 5


def test_stress_is_the_area_average_of_the_transformed_field():
    params = RenderParams(
        window_x_mm=(0.0, 10.0),
        window_y_mm=(0.0, 10.0),
        px_per_mm=2.0,
        supersample=4,
        stress_ref_MPa=1e-3,
    )
    mesh = grid_mesh(8, 1.0, 1.1, 1.1)
    s_nodes = 0.5 + 0.2 * mesh.points[:, 0] + 0.1 * mesh.points[:, 1]  # linear in the image
    sigma = 1e-3 * (10.0**s_nodes - 1.0)  # inverse transform
    np.testing.assert_allclose(stress_transform(sigma), s_nodes, rtol=1e-12)
    cov, stress, stress_area = Rasterizer(mesh, params).render(mesh.points, sigma)
    full = cov == 1.0
    assert full.sum() > 100
    rows, cols = np.nonzero(full)
    x = params.window_x_mm[0] + (cols + 0.5) / params.px_per_mm
    y = params.window_y_mm[1] - (rows + 0.5) / params.px_per_mm
    np.testing.assert_allclose(stress[full], 0.5 + 0.2 * x + 0.1 * y, atol=1e-5)
    np.testing.assert_array_equal(stress_area[full], stress[full])
    # the map's support is the half-covered silhouette; stress_area is premultiplied
    np.testing.assert_array_equal(stress > 0, cov >= 0.5)
    half = cov >= 0.5
    np.testing.assert_allclose(stress_area[half], stress[half] * cov[half], rtol=1e-6)
    part = (cov > 0) & (cov < 0.5)
    assert part.any() and np.all(stress_area[part] > 0) and np.all(stress[part] == 0)


def test_stress_support_and_deformation_mask_are_pixel_aligned(front_render):
    index = load_render_index(front_render)
    assert index["renderer"] == "raster" and index["n_frames"] == 6
    for k in range(index["n_frames"]):
        rgb, maps = read_render_frame(front_render, k, index)
        mask = segment(rgb)  # from the image only, as for a camera
        assert iou(maps["stress"] > 0, mask) >= 0.98
        # the fixture's stress is > 0 in the whole finger
        np.testing.assert_array_equal(maps["stress"] > 0, maps["coverage"] >= 0.5)
        np.testing.assert_array_equal(maps["stress_area"] > 0, maps["coverage"] > 0)


def test_framing_is_fixed_across_frames_and_files_are_complete(front_render, result):
    index = load_render_index(front_render)
    params = RenderParams()
    shapes = set()
    for fr in index["frames"]:
        shapes.add(read_png(front_render / fr["image"]).shape)
        chans, meta = read_exr(front_render / fr["stress"])
        assert set(chans) == {"stress", "coverage", "stress_area"}
        assert meta["stress_ref_MPa"] == params.stress_ref_MPa
        assert chans["stress"].dtype == np.float32
    assert shapes == {(params.height, params.width, 3)}
    assert index["params"]["window_x_mm"] == [-5.0, 35.0]
    np.testing.assert_allclose(
        [f["displacement_mm"] for f in index["frames"]], result.displacement_mm
    )
    # the clamped base does not move in the image: row of the base's lower edge is fixed
    bottoms = []
    for k in (0, index["n_frames"] - 1):
        cov = read_render_frame(front_render, k, index)[1]["coverage"]
        bottoms.append(np.nonzero(cov.max(axis=1) > 0.5)[0].max())
    assert bottoms[0] == bottoms[1] == params.height - 1 - int(2.0 * params.px_per_mm)


def test_rasteriser_matches_pyvista_front_view(result):
    from finray.render.pvrender import PyVistaRenderer

    params = RenderParams()
    r = Rasterizer(result.mesh, params)
    from finray.render import composite

    with PyVistaRenderer(result.mesh, params, pitch_deg=0.0) as pvr:
        for k in (0, result.n_frames - 1):
            pts = result.deformed_points(k)
            cov = r.render(pts)[0]
            img_r = composite(cov, params)
            img_p = pvr.render(pts)
            m_r, m_p = segment(img_r), segment(img_p)
            assert iou(m_r, m_p) >= 0.98
            # same pixel frame: centroids agree to a tenth of a pixel
            c_r = np.argwhere(m_r).mean(axis=0)
            c_p = np.argwhere(m_p).mean(axis=0)
            assert np.abs(c_r - c_p).max() < 0.1
            # same colours: pixels differ by at most a couple of the 16 samples
            # (GPU and rasteriser disagree on samples lying on an edge), and rarely
            diff = np.abs(img_r.astype(int) - img_p.astype(int)).max(axis=2)
            one_sample = np.ceil(np.ptp(img_r.astype(int)) / params.supersample**2)
            assert diff.max() <= 2 * one_sample
            assert (diff > 1).mean() < 1e-3


def test_pitched_view_projects_with_the_documented_camera(result_path, result, tmp_path):
    pitch = 30.0
    out = tmp_path / "p30"
    params = RenderParams(frames_per_scene=2)
    index = render_scene(result_path, out, pitch, params=params)
    assert index["renderer"] == "pyvista"
    rgb, maps = read_render_frame(out, 1, index)
    mask = segment(rgb)
    # expected silhouette bounds from the documented projection of the 3D surface
    from finray.geometry.surface import extrude

    surf = extrude(result.mesh, 20.0)
    xyz = surf.deformed(result.deformed_points(result.n_frames - 1))
    px = mm_to_px(params, params.project(xyz, pitch))
    rows, cols = np.nonzero(mask)
    assert abs(rows.min() - px[:, 1].min()) < 1.5 and abs(rows.max() - px[:, 1].max()) < 1.5
    assert abs(cols.min() - px[:, 0].min()) < 1.5 and abs(cols.max() - px[:, 0].max()) < 1.5
    # the stress maps stay in the front frame at every pitch
    cov_front = Rasterizer(result.mesh, params).render(result.deformed_points(result.n_frames - 1))[
        0
    ]
    np.testing.assert_array_equal(maps["coverage"], cov_front)


def test_exr_round_trip_is_bit_exact(tmp_path):
    rng = np.random.default_rng(0)
    a = rng.standard_normal((37, 23)).astype(np.float32) * 1e3
    a.flat[:6] = [0.0, -0.0, np.float32(1e-45), np.finfo(np.float32).max, np.inf, np.nan]
    b = rng.random((37, 23)).astype(np.float32)
    write_exr(tmp_path / "x.exr", {"stress": a, "coverage": b}, {"k": 1})
    chans, meta = read_exr(tmp_path / "x.exr")
    assert meta == {"k": 1}
    np.testing.assert_array_equal(chans["stress"].view(np.uint32), a.view(np.uint32))
    np.testing.assert_array_equal(chans["coverage"].view(np.uint32), b.view(np.uint32))


def test_png_round_trip(tmp_path):
    img = np.random.default_rng(1).integers(0, 256, (20, 10, 3), dtype=np.uint8)
    write_png(tmp_path / "x.png", img)
    np.testing.assert_array_equal(read_png(tmp_path / "x.png"), img)


def test_resample_frames_interpolates_in_displacement(result):
    r4 = resample_frames(result, 11)
    assert r4.n_frames == 11
    np.testing.assert_allclose(r4.displacement_mm, np.linspace(0, 5, 11))
    np.testing.assert_array_equal(r4.u_mm[0], result.u_mm[0])
    np.testing.assert_array_equal(r4.u_mm[-1], result.u_mm[-1])
    # displacement 0.5 mm lies halfway between solver frames 0 (0 mm) and 1 (1 mm)
    np.testing.assert_allclose(r4.u_mm[1], 0.5 * (result.u_mm[0] + result.u_mm[1]), atol=1e-6)
    np.testing.assert_allclose(r4.fx_N[1], 0.5 * (result.fx_N[0] + result.fx_N[1]))
    assert r4.fea_frame[1] == pytest.approx(0.5)
    assert resample_frames(result, None) is result


def test_contact_height_is_optional_and_resampled(result, result_path, tmp_path):
    """A file without ``contact_y_mm`` reads as all NaN; one with it is interpolated
    like the forces, NaN where a bracketing frame has no contact."""
    assert result.contact_y_mm.shape == (result.n_frames,)
    assert np.isnan(result.contact_y_mm).all()
    with np.load(result_path) as f:
        d = dict(f)
    y = np.r_[np.nan, 30.0 + np.arange(result.n_frames - 1)]
    np.savez(tmp_path / "y.npz", **d, contact_y_mm=y)
    r = load_fea_result(tmp_path / "y.npz")
    np.testing.assert_array_equal(r.contact_y_mm, y)
    r2 = resample_frames(r, 2 * r.n_frames - 1)  # frame k at 2k, midpoints between
    assert np.isnan(r2.contact_y_mm[:2]).all()  # rest frame, and half way to it
    np.testing.assert_allclose(r2.contact_y_mm[2::2], y[1:])
    np.testing.assert_allclose(r2.contact_y_mm[3::2], 0.5 * (y[1:-1] + y[2:]))
    np.testing.assert_array_equal(r.frames([0, 2]).contact_y_mm, y[[0, 2]])
    # a push ended early (fea.force_cap_N): fewer frames, a shorter travel, resampled over it
    cut = resample_frames(r.frames([0, 1, 2]), 9)
    np.testing.assert_allclose(cut.displacement_mm, np.linspace(0, r.displacement_mm[2], 9))
    np.testing.assert_array_equal(cut.fx_N[-1], r.fx_N[2])


def test_malformed_result_is_rejected(result_path, tmp_path):
    with np.load(result_path) as f:
        d = dict(f)
    bad = dict(d)
    del bad["fx_N"]
    np.savez(tmp_path / "a.npz", **bad)
    with pytest.raises(ResultError, match="fx_N"):
        load_fea_result(tmp_path / "a.npz")
    bad = dict(d, von_mises_MPa=d["von_mises_MPa"][:, :-1])
    np.savez(tmp_path / "b.npz", **bad)
    with pytest.raises(ResultError, match="von_mises_MPa"):
        load_fea_result(tmp_path / "b.npz")


def test_window_must_be_whole_pixels():
    with pytest.raises(ValueError, match="window_x_mm"):
        RenderParams(window_x_mm=(0.0, 10.1), px_per_mm=4.0)


def test_draw_object_for_figures(result_path, tmp_path):
    params = RenderParams(frames_per_scene=2)
    plain = render_scene(result_path, tmp_path / "a", 0.0, params=params)
    drawn = render_scene(result_path, tmp_path / "b", 0.0, params=params, draw_object=True)
    assert json.loads((tmp_path / "b" / "index.json").read_text())["draw_object"] is True
    a = read_png(tmp_path / "a" / plain["frames"][0]["image"])
    b = read_png(tmp_path / "b" / drawn["frames"][0]["image"])
    obj_rgb = np.rint(np.array(params.object_rgb) * 255)
    ob = np.abs(b.astype(int) - obj_rgb).sum(axis=2) < 6
    area = ob.sum() / params.px_per_mm**2
    assert area == pytest.approx(np.pi * 25, rel=0.05)  # the 10 mm circle
    assert not (np.abs(a.astype(int) - obj_rgb).sum(axis=2) < 6).any()


def test_benchmark_reports_both_paths(result_path):
    from finray.benchmarks.render import benchmark

    b = benchmark(result_path, n_frames=2, pitch_deg=15.0)
    # the fields and their relation (frames per second from ms per frame), not the timings
    for key in ("raster_ms", "raster_io_ms", "pyvista_front_ms", "pyvista_pitch_ms"):
        assert np.isfinite(b[key])
        assert b[key.replace("_ms", "_fps_per_core")] == pytest.approx(1000 / b[key])
    assert b["image_px"] == [336, 160] and b["LP_NUM_THREADS"] == "1"


def test_integer_block_mean_is_exact():
    from finray.render.pvrender import block_mean, block_mean_u8

    img = np.random.default_rng(3).integers(0, 256, (12, 9, 3), dtype=np.uint8)
    for k in (1, 3):
        np.testing.assert_array_equal(block_mean_u8(img, k), block_mean(img, k))
