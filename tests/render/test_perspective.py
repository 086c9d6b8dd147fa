"""The perspective render path: the pinhole raster's coverage (exact on a box, and
sample for sample pyvista's perspective render of a deformed finger), the silhouette a
segmentation finds in pyvista's image, and the VTK camera set from the pinhole."""

import numpy as np
import pytest
from scipy.spatial import ConvexHull

from finray.render.camera import PinholeCamera
from finray.render.params import RenderParams
from finray.render.perspective import PerspectiveRaster
from finray.render.raster import to_uint8
from helpers import rectangle_mesh, write_synthetic_fea_result

BOX_MM = (30.0, 80.0, 20.0)  # x, y extent of the 2D mesh; extrusion (z)


def _box():
    return rectangle_mesh(np.linspace(0.0, BOX_MM[0], 4), np.linspace(0.0, BOX_MM[1], 6), order=1)


@pytest.mark.parametrize(
    "pitch, yaw, roll, offset, distance",
    [
        (0.0, 0.0, 0.0, (0.0, 0.0), 250.0),
        (30.0, 0.0, 0.0, (0.0, 0.0), 150.0),
        (12.0, -8.0, 5.0, (37.5, -21.0), 200.0),
        (30.0, 6.0, -4.0, (-60.0, 45.0), 400.0),
    ],
)
def test_box_coverage_is_its_projected_hull(pitch, yaw, roll, offset, distance):
    mesh = _box()
    cam = PinholeCamera.looking_at(
        (15.0, 40.0, 0.0),
        width=360,
        height=640,
        hfov_deg=69.4,
        distance_mm=distance,
        yaw_deg=yaw,
        pitch_deg=pitch,
        roll_deg=roll,
        principal_offset_px=offset,
    )
    raster = PerspectiveRaster(mesh, BOX_MM[2], supersample=4)
    cov, (row0, col0) = raster.coverage(mesh.points, cam)
    corners = np.array(
        [
            [x, y, z]
            for x in (0.0, BOX_MM[0])
            for y in (0.0, BOX_MM[1])
            for z in (-0.5 * BOX_MM[2], 0.5 * BOX_MM[2])
        ]
    )
    uv = cam.project(corners)
    hull = ConvexHull(uv)
    # the hull's area (px^2) to within the samples along its outline
    assert cov.sum() == pytest.approx(hull.volume, abs=0.5 * hull.area / 4)
    assert cov.sum() == pytest.approx(hull.volume, rel=2e-3)
    # the window holds the whole projection with a pixel to spare
    assert cov.dtype == np.float32 and cov.min() >= 0 and cov.max() == 1.0
    assert not cov[[0, -1]].any() and not cov[:, [0, -1]].any()
    # its offset: the coverage's centroid is the hull's (a convex polygon's area centroid)
    r, c = np.mgrid[: cov.shape[0], : cov.shape[1]]
    centroid_uv = np.array([(cov * c).sum(), (cov * r).sum()]) / cov.sum() + (col0, row0)
    tri = uv[hull.vertices]
    a = np.roll(tri, -1, axis=0)
    cross = tri[:, 0] * a[:, 1] - a[:, 0] * tri[:, 1]
    hull_centroid = ((tri + a) * cross[:, None]).sum(axis=0) / (3.0 * cross.sum())
    assert np.abs(centroid_uv - hull_centroid).max() < 0.05  # a sample is 0.25 px
    # a point: the front face's centre lands where the camera says
    frame = _in_frame(cov, (row0, col0), cam)
    u, v = cam.project(np.array([[15.0, 40.0, 0.5 * BOX_MM[2]]]))[0]
    if 0 <= round(v) < cam.height and 0 <= round(u) < cam.width:
        assert frame[int(round(v)), int(round(u))] == 1.0


def test_coverage_window_may_leave_the_frame_and_checks_its_input():
    mesh = _box()
    cam = PinholeCamera.looking_at(
        (15.0, 40.0, 0.0),
        width=64,
        height=64,
        hfov_deg=69.4,
        distance_mm=200.0,
        principal_offset_px=(-40.0, 50.0),
    )
    raster = PerspectiveRaster(mesh, BOX_MM[2], supersample=2)
    cov, (row0, col0) = raster.coverage(mesh.points, cam)
    assert col0 < 0 and row0 + cov.shape[0] > cam.height  # not clipped
    with pytest.raises(ValueError, match="expected 24 nodes"):
        raster.coverage(mesh.points[:-1], cam)
    behind = PinholeCamera.looking_at(
        (15.0, 40.0, 0.0), width=64, height=64, hfov_deg=69.4, distance_mm=5.0
    )
    with pytest.raises(ValueError, match="behind the camera"):
        raster.coverage(mesh.points, behind)


def test_scaled_camera_keeps_the_rays():
    cam = PinholeCamera.looking_at(
        (0.0, 0.0, 0.0),
        width=160,
        height=90,
        hfov_deg=69.4,
        distance_mm=200.0,
        yaw_deg=7.0,
        principal_offset_px=(3.25, -1.5),
    )
    fine = cam.scaled(3)
    pts = np.random.default_rng(0).uniform(-40, 40, (20, 3))
    # pixel centre (u, v) of the camera is the centre of the middle one of 3 x 3 fine pixels
    np.testing.assert_allclose(fine.project(pts), 3 * cam.project(pts) + 1.0, atol=1e-9)
    assert (fine.width, fine.height) == (480, 270)


# --------------------------------------------------- against pyvista's perspective render
CASES = [
    (d, pitch, yaw, roll)
    for d in (150.0, 400.0)
    for pitch, yaw, roll in ((0.0, 3.0, -2.0), (15.0, -4.0, 2.0), (30.0, 5.0, 3.0))
]
FRAME = (720, 1280)  # a portrait frame (width, height) px
SS = 2  # the camera views' and the viewpoint renders' supersampling


@pytest.fixture(scope="module")
def finger(tmp_path_factory):
    from finray.render.result import load_fea_result

    path = write_synthetic_fea_result(
        tmp_path_factory.mktemp("fea") / "result.npz",
        n_frames=4,
        max_displacement_mm=10.0,
        size_mm=1.0,
    )
    res = load_fea_result(path)
    return res.mesh, res.deformed_points(res.n_frames - 1)


@pytest.fixture(scope="module")
def renders(finger):
    """For each case: pyvista's fine frame and RGB image, and the raster's coverage."""
    from finray.render.pvrender import PyVistaPerspective

    mesh, pts = finger
    raster = PerspectiveRaster(mesh, 20.0, supersample=SS)
    out = {}
    with PyVistaPerspective(mesh, RenderParams(), 20.0, supersample=SS) as pv:
        for d, pitch, yaw, roll in CASES:
            cam = PinholeCamera.looking_at(
                (15.0, 40.0, 0.0),
                width=FRAME[0],
                height=FRAME[1],
                hfov_deg=69.4,
                distance_mm=d,
                yaw_deg=yaw,
                pitch_deg=pitch,
                roll_deg=roll,
                principal_offset_px=(4.0, -3.0),
            )
            fine = pv.render_fine(pts, cam).copy()
            rgb = pv.render(pts, cam)
            out[(d, pitch, yaw, roll)] = (
                fine,
                rgb,
                _in_frame(*raster.coverage(pts, cam), cam),
                cam,
            )
    return out


@pytest.mark.parametrize("case", CASES)
def test_raster_covers_what_pyvista_draws(renders, case):
    """Sample for sample: pyvista's fine pixels (no multisampling: each is finger or
    background) are the raster's samples (same centres; only ties on an edge differ)."""
    fine, rgb, cov, cam = renders[case]
    bg = to_uint8(RenderParams().background_rgb)
    drawn = (fine != bg).any(axis=-1)
    pv_cov = drawn.reshape(cam.height, SS, cam.width, SS).mean(axis=(1, 3))
    diff = np.abs(cov - pv_cov)
    assert rgb.shape == (cam.height, cam.width, 3) and rgb.dtype == np.uint8
    assert cov.sum() > 500
    assert diff.max() <= 2.0 / SS**2 + 1e-6
    assert (diff > 1e-6).sum() <= 5e-3 * (cov > 0).sum() + 2
    assert abs(cov.sum() - pv_cov.sum()) < 1.0  # px


def _iou(a, b):
    return float((a & b).sum() / (a | b).sum())


def _in_frame(window, offset, cam):
    out = np.zeros((cam.height, cam.width) + window.shape[2:], dtype=window.dtype)
    r0, c0 = offset
    rr, cc = max(r0, 0), max(c0, 0)
    r1, c1 = min(r0 + window.shape[0], cam.height), min(c0 + window.shape[1], cam.width)
    out[rr:r1, cc:c1] = window[rr - r0 : r1 - r0, cc - c0 : c1 - c0]
    return out


@pytest.mark.parametrize("case", CASES)
def test_segmented_silhouettes_agree(renders, finger, case):
    """What the predictor makes of pyvista's frame -- ``segment`` of the whole image
    (default settings), base-anchored crop, 64 x 32 input -- and what the camera views
    make of the raster's shaded window (:meth:`PerspectiveRaster.image`, segmented
    with the morphology's limits in pixels of the whole frame): IoU >= 0.98 at full
    resolution and at 64 x 32. The shaded raster gives pyvista's grey levels (side
    walls at a grazing angle darker), so the threshold cuts both at the same place."""
    from finray.dataset import segment
    from finray.dataset.imageops import base_anchored_box, silhouette_input

    mesh, pts = finger
    _, rgb, _, cam = renders[case]
    raster = PerspectiveRaster(mesh, 20.0, supersample=SS, corners_only=True)  # as the camera views
    window, offset = raster.image(pts, cam, RenderParams())
    # the shaded raster is pyvista's image: most pixels equal to within 2 levels
    placed = _in_frame(window, offset, cam)
    placed[_in_frame(np.ones(window.shape[:2], bool), offset, cam) == 0] = to_uint8(
        RenderParams().background_rgb
    )
    differ = np.abs(placed.astype(int) - rgb.astype(int)).max(axis=-1) > 2
    finger_px = (rgb != to_uint8(RenderParams().background_rgb)).any(axis=-1).sum()
    print(f"case {case}: {differ.sum()} of {finger_px} finger pixels differ by > 2 levels")
    assert differ.sum() <= 0.02 * finger_px
    scale = cam.width * cam.height / (window.shape[0] * window.shape[1])
    raster_mask = _in_frame(
        segment(window, min_object_frac=1e-3 * scale, max_hole_frac=2e-4 * scale), offset, cam
    )
    pv_mask = segment(rgb)
    small = []
    for m in (pv_mask, raster_mask):
        box = base_anchored_box(m, 30.0, (-5.0, 35.0), (0.0, 80.0), base_band=0.03)
        small.append(silhouette_input(m, box, (64, 32)) >= 128)
    full_iou, small_iou = _iou(pv_mask, raster_mask), _iou(*small)
    print(f"case {case}: IoU full {full_iou:.4f}, 64x32 {small_iou:.4f}")
    assert full_iou >= 0.98 and small_iou >= 0.98
