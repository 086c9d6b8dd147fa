"""TEST FIXTURE ONLY: a fabricated FEA ``result.npz`` for the render and dataset tests.

``write_synthetic_fea_result`` builds the real default finger mesh and moves it with
a smooth analytic field (a bend towards the object growing with the frame, plus a
local dent at the contact height) and an analytic, strictly positive von Mises
field. It follows the solver's ``result.npz`` contract exactly, but it is not
physics and is never used by the pipeline. The tests in this file check that the
fixture itself honours the contract.
"""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest

from finray.geometry.finger import FingerParams, front_face_x, mesh_finger
from finray.geometry.mesh import signed_areas
from finray.render import load_fea_result

FIXTURE_HEIGHT_MM = 30.0  # contact height of the fabricated object


def synthetic_fields(
    points: np.ndarray, t: float, height_mm: float = FIXTURE_HEIGHT_MM, length_mm: float = 80.0
) -> tuple[np.ndarray, np.ndarray]:
    """Analytic displacement (N, 2) mm and von Mises stress (N,) MPa at load fraction t."""
    x, y = points[:, 0], points[:, 1]
    eta = y / length_mm
    bend = 8.0 * t  # tip travel towards -x (mm)
    ux = -bend * eta**2
    uy = 2.0 * bend * (x - 15.0) * y / length_mm**2 * 0.5
    dent = 2.5 * t * np.exp(-0.5 * ((y - height_mm) / 5.0) ** 2) * np.exp(-x / 6.0)
    ux = ux + dent
    r2 = x**2 + (y - height_mm) ** 2
    vm = 0.002 + t * (0.6 * np.exp(-r2 / (2 * 6.0**2)) + 0.15 * (1.0 - eta) ** 2)
    return np.column_stack([ux, uy]), vm


def write_synthetic_fea_result(
    path: str | Path,
    n_frames: int = 6,
    size_mm: float = 0.5,
    max_displacement_mm: float = 5.0,
    height_mm: float = FIXTURE_HEIGHT_MM,
) -> Path:
    """Write a contract-conforming fake ``result.npz`` (test fixture only)."""
    p = FingerParams()
    mesh = mesh_finger(p, size_mm)
    t = np.linspace(0.0, 1.0, n_frames)
    u = np.empty((n_frames, len(mesh.points), 2), dtype=np.float32)
    vm = np.empty((n_frames, len(mesh.points)), dtype=np.float32)
    for k, tk in enumerate(t):
        uk, vk = synthetic_fields(mesh.points, tk, height_mm, p.height_mm)
        u[k], vm[k] = uk, vk
    # a 10 mm circle approaching the front face at the contact height
    ang = np.linspace(0, 2 * np.pi, 48, endpoint=False)
    k_pts = len(ang)
    cx0 = float(front_face_x(p, height_mm)) - 5.0 - 0.1
    disp = max_displacement_mm * t
    obj = np.stack(
        [
            np.column_stack([cx0 + d + 5.0 * np.cos(ang), height_mm + 5.0 * np.sin(ang)])
            for d in disp
        ]
    )
    edges = np.column_stack([np.arange(k_pts), (np.arange(k_pts) + 1) % k_pts])
    path = Path(path)
    np.savez_compressed(
        path,
        points=mesh.points,
        triangles=mesh.triangles,
        boundary_edges=mesh.boundary_edges,
        displacement_mm=disp,
        u_mm=u,
        von_mises_MPa=vm,
        fx_N=(3.0 * t**1.5),
        fy_N=(0.2 * t),
        object_points_mm=obj,
        object_edges=edges,
    )
    return path


@pytest.fixture(scope="module")
def synthetic_result(tmp_path_factory) -> Path:
    return write_synthetic_fea_result(tmp_path_factory.mktemp("fea") / "result.npz")


def test_fixture_follows_the_result_contract(synthetic_result):
    res = load_fea_result(synthetic_result)
    n, f = len(res.points), res.n_frames
    assert f == 6 and res.triangles.shape[1] == 6
    assert res.u_mm.shape == (f, n, 2) and res.u_mm.dtype == np.float32
    assert res.von_mises_MPa.shape == (f, n) and res.von_mises_MPa.dtype == np.float32
    assert (res.von_mises_MPa > 0).all()
    assert res.object_points_mm.shape[0] == f and res.object_edges.shape[1] == 2
    np.testing.assert_array_equal(res.u_mm[0], 0.0)
    # the analytic field keeps every element (and every linear sub-triangle) upright
    for k in range(f):
        assert (signed_areas(res.deformed_points(k), res.triangles) > 0).all()
    # the bend grows with the frame: the tip moves towards the object
    tip = np.argmax(res.points[:, 1])
    assert np.all(np.diff(res.u_mm[:, tip, 0]) < 0)
