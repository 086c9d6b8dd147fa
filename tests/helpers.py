"""Helpers shared by several test modules (plain functions and constants; the shared
fixtures are in conftest.py). No test module imports another test module: what two of
them need lives here. ``tests/`` is on ``sys.path`` (pyproject's ``pythonpath``), so a
test module anywhere under it writes ``from helpers import ...``.

- ``write_synthetic_fea_result``: TEST FIXTURE ONLY, a fabricated FEA ``result.npz`` for
  the render and dataset tests. It builds the real default finger mesh and moves it with
  a smooth analytic field (a bend towards the object growing with the frame, plus a local
  dent at the contact height) and an analytic, strictly positive von Mises field. It
  follows the solver's ``result.npz`` contract exactly, but it is not physics and is never
  used by the pipeline (tests/render/test_synthetic_result.py checks that it honours the
  contract).
- ``ROOT``, ``DATA``: the repository's root and tests/data (whatever folder a test is in).
- ``PREPROCESS``: the preprocessing block of the small exported test networks.
- ``CAMERA_PREPROCESS``: the same with the base band of a camera frame's crop.
- ``toy``, ``CFG``: a learnable toy training set and a quick training configuration.
- Test geometry and FEA oracles (none used by the package): ``graded_coords``,
  ``rectangle_mesh``, ``circle_polyline``, ``arc_polyline``, ``segment_polyline``,
  ``edge_load`` (meshes, polylines and loads of the verification problems),
  ``front_face_x`` and ``front_contact_circle`` (a rigid circle at the finger's front
  face), ``plane_strain_modulus`` of a material, ``q_from_U`` of an FEA model and
  ``mm_to_px`` of a render's image plane.
"""

from __future__ import annotations

from pathlib import Path

import numpy as np

from finray.geometry.finger import FingerParams, mesh_finger
from finray.geometry.mesh import TriMesh, elevate_to_p2
from finray.schema import schema_default

ROOT = Path(__file__).resolve().parents[1]  # the repository (this file is tests/helpers.py)
DATA = ROOT / "tests" / "data"

PREPROCESS = {
    "base_width_mm": 30.0,
    "crop_x_mm": [-5.0, 35.0],
    "crop_y_mm": [0.0, 80.0],
    "segment": {
        "threshold": "isodata",
        "foreground": "bright",
        "min_object_frac": 1e-3,
        "max_hole_frac": 2e-4,
        "keep_largest": True,
    },
}


#: PREPROCESS with the base band a camera frame's crop uses (the validity tests and the
#: real-time study's synthetic finger)
CAMERA_PREPROCESS = {**PREPROCESS, "base_band": 0.03}

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


def toy(n=96, seed=0):
    """A learnable toy set: the force is the brightness of the upper half (N)."""
    rng = np.random.default_rng(seed)
    x = rng.random((n, 3, 32, 16)).astype("f4")
    x[:, :, :16] *= rng.random((n, 1, 1, 1)).astype("f4")
    f = 5.0 * x[:, :, :16].mean((1, 2, 3))[:, None]
    s = x.mean(1, keepdims=True)
    return x, s, f


CFG = dict(epochs=2, batch_size=16, progress=False, lr=1e-3, contact_weight=0.0)  # no contact head


# -- test geometry (mm) and FEA oracles ------------------------------------------------


def graded_coords(
    a: float, b: float, n: int, grading: float = 1.0, towards: str = "a"
) -> np.ndarray:
    """n + 1 coordinates from a to b; cells shrink geometrically by ``grading`` per
    cell towards ``a``, ``b`` or "both" ends (grading 1: uniform)."""
    if grading == 1.0:
        return np.linspace(a, b, n + 1)
    if towards == "both":
        h = n // 2
        left = graded_coords(a, 0.5 * (a + b), h, grading, "a")
        right = graded_coords(0.5 * (a + b), b, n - h, grading, "b")
        return np.concatenate([left, right[1:]])
    w = grading ** np.arange(n)  # growing away from a
    x = np.concatenate([[0.0], np.cumsum(w)]) / w.sum()
    if towards == "b":
        x = 1.0 - x[::-1]
    return a + (b - a) * x


def rectangle_mesh(
    x: np.ndarray, y: np.ndarray, order: int = schema_default("mesh.order")
) -> TriMesh:
    """Structured triangle mesh on the tensor grid x (nx+1,) by y (ny+1,).

    Each cell is split along alternating diagonals (a 'union jack'-free crossed
    pattern would bias bending; alternating diagonals do not). Boundary edges are
    oriented with the material on the left and tagged 0.
    """
    x, y = np.asarray(x, float), np.asarray(y, float)
    nx, ny = len(x) - 1, len(y) - 1
    X, Y = np.meshgrid(x, y, indexing="xy")
    pts = np.column_stack([X.ravel(), Y.ravel()])
    idx = np.arange((nx + 1) * (ny + 1)).reshape(ny + 1, nx + 1)
    tris = []
    for j in range(ny):
        for i in range(nx):
            a, b = idx[j, i], idx[j, i + 1]
            c, d = idx[j + 1, i + 1], idx[j + 1, i]
            if (i + j) % 2 == 0:
                tris += [[a, b, c], [a, c, d]]
            else:
                tris += [[a, b, d], [b, c, d]]
    tris = np.array(tris, dtype=np.int64)
    # boundary, counter-clockwise
    ring = np.concatenate([idx[0, :], idx[1:, -1], idx[-1, -2::-1], idx[-2:0:-1, 0]])
    be = np.column_stack([ring, np.roll(ring, -1), -np.ones(len(ring), int)])
    mesh = TriMesh(pts, tris, be, np.zeros(len(be), int))
    return elevate_to_p2(mesh) if order == 2 else mesh


def circle_polyline(center, radius: float, n: int) -> tuple[np.ndarray, np.ndarray]:
    """Closed polygon (n vertices, counter-clockwise) and its edges."""
    th = 2 * np.pi * np.arange(n) / n
    pts = np.asarray(center, float) + radius * np.column_stack([np.cos(th), np.sin(th)])
    edges = np.column_stack([np.arange(n), np.roll(np.arange(n), -1)])
    return pts, edges


def arc_polyline(
    center, radius: float, theta0: float, theta1: float, n: int
) -> tuple[np.ndarray, np.ndarray]:
    """Open arc polyline (n segments) from angle theta0 to theta1 (radians)."""
    th = np.linspace(theta0, theta1, n + 1)
    pts = np.asarray(center, float) + radius * np.column_stack([np.cos(th), np.sin(th)])
    edges = np.column_stack([np.arange(n), np.arange(1, n + 1)])
    return pts, edges


def segment_polyline(p0, p1, n: int) -> tuple[np.ndarray, np.ndarray]:
    """Straight polyline of n segments from p0 to p1."""
    s = np.linspace(0, 1, n + 1)[:, None]
    pts = np.asarray(p0, float) * (1 - s) + np.asarray(p1, float) * s
    edges = np.column_stack([np.arange(n), np.arange(1, n + 1)])
    return pts, edges


def edge_load(mesh: TriMesh, edges: np.ndarray, traction) -> np.ndarray:
    """Consistent nodal forces (N, 2) of a uniform traction (N/mm^2 per mm thickness
    -> N/mm) on boundary edges [a, b, mid] of the reference configuration."""
    f = np.zeros((len(mesh.points), 2))
    tr = np.asarray(traction, float)
    for a, b, m in edges:
        L = np.linalg.norm(mesh.points[b] - mesh.points[a])
        if m >= 0:
            f[a] += tr * L / 6
            f[b] += tr * L / 6
            f[m] += tr * L * 4 / 6
        else:
            f[a] += tr * L / 2
            f[b] += tr * L / 2
    return f


def front_face_x(p: FingerParams, y_mm):
    """x (mm) of the outer front face at height y."""
    return np.asarray(y_mm) * p.base_width_mm / p.apex_height_mm


def front_contact_circle(
    params,
    height_mm: float,
    diameter_mm: float,
    gap_mm: float = schema_default("placement.gap_mm"),
    n: int | None = None,
    size_mm: float = 0.25,
):
    """A rigid circle (``finray.fea.simulate.RigidObject``) touching the finger's front
    face at ``height_mm`` with ``gap_mm`` clearance (the project's placement lives in the
    geometry stage)."""
    from finray.fea.simulate import RigidObject

    W, H = params.base_width_mm, params.apex_height_mm
    t = np.array([W, H]) / np.hypot(W, H)  # along the front face
    nrm = np.array([H, -W]) / np.hypot(W, H)  # into the finger
    p = t * (height_mm / t[1])
    R = 0.5 * diameter_mm
    c = p - nrm * (R + gap_mm)
    n = n or max(16, int(np.ceil(2 * np.pi * R / size_mm)))
    pts, edges = circle_polyline(c, R, n)
    return RigidObject(pts, edges, name=f"circle_d{diameter_mm:g}")


def plane_strain_modulus(mat) -> float:
    """E / (1 - nu^2) (MPa) of a ``NeoHookean`` material."""
    return mat.E / (1 - mat.nu**2)


def q_from_U(model, U: np.ndarray) -> np.ndarray:
    """The reduced vector q of an FEA ``Model`` with nodal displacements U (N, 2)."""
    q = np.zeros(model.n)
    m = model.dof_map >= 0
    q[model.dof_map[m]] = U[m]
    return q


def mm_to_px(params, uv: np.ndarray) -> np.ndarray:
    """Continuous pixel coordinates (col, row) of image-plane points (..., 2) mm of a
    ``RenderParams``' window; pixel centres sit at integers."""
    col = (uv[..., 0] - params.window_x_mm[0]) * params.px_per_mm - 0.5
    row = (params.window_y_mm[1] - uv[..., 1]) * params.px_per_mm - 0.5
    return np.stack([col, row], axis=-1)


def start_finray(args, cwd):
    """The ``finray`` command (``python -m finray``, as its console script starts) as a
    subprocess with pipes, SIGINT at its default (a pytest-xdist worker ignores SIGINT,
    and a child inherits that): for the tests that signal it part way."""
    import signal
    import subprocess
    import sys

    return subprocess.Popen(
        [sys.executable, "-m", "finray", *args],
        cwd=cwd,
        stdout=subprocess.PIPE,
        stderr=subprocess.PIPE,
        text=True,
        preexec_fn=lambda: signal.signal(signal.SIGINT, signal.SIG_DFL),
    )
