"""Test-problem geometry (mm): simple meshes and polylines for the FEA verification
problems, the benchmarks and the rigid objects of a scene.

Structured (optionally graded) rectangle meshes of linear or quadratic
triangles, and polylines for rigid bodies (circles, segments).
"""

from __future__ import annotations

import numpy as np

from .mesh import TriMesh, elevate_to_p2
from ..schema import schema_default


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
