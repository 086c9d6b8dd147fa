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
- ``toy``, ``CFG``: a learnable toy training set and a quick training configuration.
"""

from __future__ import annotations

from pathlib import Path

import numpy as np

from finray.geometry.finger import FingerParams, front_face_x, mesh_finger

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
