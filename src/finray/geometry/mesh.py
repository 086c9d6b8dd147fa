"""2D triangle meshes with named boundaries (lengths in mm).

A :class:`TriMesh` holds quadratic (6-node) or linear (3-node) triangles.
Node order of a 6-node triangle: corners ``0, 1, 2`` counter-clockwise, then
the mid-side nodes of edges ``(0, 1)``, ``(1, 2)`` and ``(2, 0)`` (the VTK
``quadratic_triangle`` / meshio ``triangle6`` order, so files open in ParaView).

Boundary edges are stored as ``[a, b, mid]`` (``mid = -1`` for linear meshes),
oriented so that the material lies on the left of ``a -> b``: exterior rings run
counter-clockwise, hole rings clockwise.
"""

from __future__ import annotations

import json
from dataclasses import dataclass, field
from pathlib import Path
from typing import TYPE_CHECKING

import numpy as np
import triangle
from ..schema import schema_default

if TYPE_CHECKING:  # shapely (40 ms of import) only where polygons are meshed
    from shapely.geometry import Polygon

#: Boundary tag ids. ``cavity`` are the surfaces inside the finger (rib faces,
#: inner faces of the walls and the base), which touch each other when the ribs jam.
#: ``object_inner`` are the hole boundaries of an object (the bore of the ring).
BOUNDARY_TAGS = {
    "base": 1,
    "front": 2,
    "back": 3,
    "tip": 4,
    "cavity": 5,
    "object": 6,
    "object_inner": 7,
}


@dataclass
class TriMesh:
    """Triangle mesh: ``points`` (N, 2) mm, ``triangles`` (M, 3 or 6)."""

    points: np.ndarray
    triangles: np.ndarray
    boundary_edges: np.ndarray  # (E, 3) [a, b, mid]
    boundary_tags: np.ndarray  # (E,) ids of BOUNDARY_TAGS
    meta: dict = field(default_factory=dict)

    @property
    def order(self) -> int:
        return 2 if self.triangles.shape[1] == 6 else 1

    @property
    def corner_triangles(self) -> np.ndarray:
        return self.triangles[:, :3]

    def edges_with_tag(self, name: str) -> np.ndarray:
        return self.boundary_edges[self.boundary_tags == BOUNDARY_TAGS[name]]

    def nodes_with_tag(self, name: str) -> np.ndarray:
        e = self.edges_with_tag(name)
        return np.unique(e[e >= 0])

    def save(self, path: str | Path) -> None:
        np.savez_compressed(
            path,
            points=self.points,
            triangles=self.triangles,
            boundary_edges=self.boundary_edges,
            boundary_tags=self.boundary_tags,
            meta=json.dumps(self.meta),
        )

    @classmethod
    def load(cls, path: str | Path) -> "TriMesh":
        with np.load(path) as f:
            return cls(
                f["points"],
                f["triangles"],
                f["boundary_edges"],
                f["boundary_tags"],
                json.loads(str(f["meta"])),
            )

    def to_meshio(self):
        import meshio

        pts3 = np.column_stack([self.points, np.zeros(len(self.points))])
        if len(self.triangles) == 0:  # rigid object: its boundary loops only
            return meshio.Mesh(
                pts3,
                [("line", self.boundary_edges[:, :2])],
                cell_data={"tag": [self.boundary_tags]},
            )
        ctype = "triangle6" if self.order == 2 else "triangle"
        return meshio.Mesh(pts3, [(ctype, self.triangles)])


def split_p2_edges(edges: np.ndarray) -> np.ndarray:
    """Boundary edges ``[a, b, mid]`` as straight 2-node segments: ``a-mid, mid-b`` for
    quadratic edges, ``a-b`` for linear ones (``mid < 0``); order and orientation kept."""
    edges = np.asarray(edges)
    if edges.shape[1] == 2 or (edges[:, 2] < 0).all():
        return edges[:, :2].astype(np.int32)
    return np.vstack([edges[:, [0, 2]], edges[:, [2, 1]]]).astype(np.int32)


def signed_areas(points: np.ndarray, tri: np.ndarray) -> np.ndarray:
    """Signed area (mm^2) of each triangle from its first three nodes."""
    a, b, c = (points[tri[:, i]] for i in range(3))
    return 0.5 * (
        (b[:, 0] - a[:, 0]) * (c[:, 1] - a[:, 1]) - (b[:, 1] - a[:, 1]) * (c[:, 0] - a[:, 0])
    )


def triangle_angles_deg(points: np.ndarray, tri: np.ndarray) -> np.ndarray:
    """(M, 3) interior angles of the corner triangles, degrees."""
    p = points[tri[:, :3]]
    out = np.empty((len(tri), 3))
    for i in range(3):
        u = p[:, (i + 1) % 3] - p[:, i]
        v = p[:, (i + 2) % 3] - p[:, i]
        cosang = (u * v).sum(1) / (np.linalg.norm(u, axis=1) * np.linalg.norm(v, axis=1))
        out[:, i] = np.degrees(np.arccos(np.clip(cosang, -1.0, 1.0)))
    return out


def quality(mesh: TriMesh) -> dict:
    """Mesh quality summary: angles (deg), edge lengths (mm), inverted count."""
    ang = triangle_angles_deg(mesh.points, mesh.triangles)
    p = mesh.points[mesh.corner_triangles]
    edge = np.linalg.norm(p - np.roll(p, -1, axis=1), axis=2)
    area = signed_areas(mesh.points, mesh.triangles)
    return {
        "n_nodes": int(len(mesh.points)),
        "n_triangles": int(len(mesh.triangles)),
        "order": mesh.order,
        "min_angle_deg": float(ang.min()),
        "max_angle_deg": float(ang.max()),
        "min_edge_mm": float(edge.min()),
        "max_edge_mm": float(edge.max()),
        "mean_edge_mm": float(edge.mean()),
        "n_inverted": int((area <= 0).sum()),
        "area_mm2": float(area.sum()),
    }


def resample_ring(coords: np.ndarray, max_len: float) -> np.ndarray:
    """Split every segment of a closed ring (K, 2), first != last, to length <= max_len."""
    nxt = np.roll(coords, -1, axis=0)
    n_sub = np.maximum(1, np.ceil(np.linalg.norm(nxt - coords, axis=1) / max_len)).astype(int)
    seg = np.repeat(np.arange(len(coords)), n_sub)
    t = np.arange(n_sub.sum()) - np.repeat(np.cumsum(n_sub) - n_sub, n_sub)
    t = t / np.repeat(n_sub, n_sub)
    return coords[seg] + t[:, None] * (nxt[seg] - coords[seg])


def polygon_rings(poly: Polygon, max_len: float) -> list[np.ndarray]:
    """Resampled rings of a polygon, exterior counter-clockwise then holes clockwise."""
    from shapely.geometry.polygon import orient

    poly = orient(poly, sign=1.0)
    rings = [poly.exterior] + list(poly.interiors)
    return [resample_ring(np.asarray(r.coords)[:-1], max_len) for r in rings]


def triangulate_polygon(
    poly: Polygon,
    size_mm: float,
    min_angle_deg: float = schema_default("mesh.min_angle_deg"),
    order: int = schema_default("mesh.order"),
) -> tuple[TriMesh, list[np.ndarray]]:
    """Quality-triangulate a (multiply connected) polygon.

    Returns the mesh (boundary tags left 0 for the caller to classify) and the
    resampled rings used as constraints. Triangle's ``q`` switch bounds the
    minimum angle; ``a`` bounds the area to that of an equilateral triangle of
    edge ``size_mm``.
    """
    from shapely.geometry import Polygon

    rings = polygon_rings(poly, size_mm)
    verts, segs, holes, offset = [], [], [], 0
    for k, r in enumerate(rings):
        n = len(r)
        verts.append(r)
        idx = offset + np.arange(n)
        segs.append(np.column_stack([idx, np.roll(idx, -1)]))
        offset += n
        if k > 0:  # a point strictly inside each hole
            holes.append(np.asarray(Polygon(r).representative_point().coords[0]))
    tri_in = {"vertices": np.vstack(verts), "segments": np.vstack(segs)}
    if holes:
        tri_in["holes"] = np.array(holes)
    max_area = np.sqrt(3) / 4 * size_mm**2
    out = triangle.triangulate(tri_in, f"pq{min_angle_deg:g}a{max_area:.6g}Q")
    pts, tris = out["vertices"], out["triangles"].astype(np.int64)
    area = signed_areas(pts, tris)
    tris[area < 0] = tris[area < 0][:, [0, 2, 1]]
    # boundary edges: edges used by exactly one triangle, oriented with the triangle
    e = np.concatenate([tris[:, [0, 1]], tris[:, [1, 2]], tris[:, [2, 0]]])
    key = np.sort(e, axis=1)
    _, inv, cnt = np.unique(key, axis=0, return_inverse=True, return_counts=True)
    bedges = e[cnt[inv.ravel()] == 1]
    mesh = TriMesh(
        pts, tris, np.column_stack([bedges, -np.ones(len(bedges), int)]), np.zeros(len(bedges), int)
    )
    if order == 2:
        mesh = elevate_to_p2(mesh)
    return mesh, rings


def elevate_to_p2(mesh: TriMesh) -> TriMesh:
    """Add mid-side nodes (straight-sided P2); boundary edges get their mid node."""
    tri = mesh.triangles[:, :3]
    n = len(mesh.points)
    e = np.concatenate([tri[:, [0, 1]], tri[:, [1, 2]], tri[:, [2, 0]]])
    key = np.sort(e, axis=1)
    uniq, inv = np.unique(key, axis=0, return_inverse=True)
    inv = inv.ravel()
    mids = 0.5 * (mesh.points[uniq[:, 0]] + mesh.points[uniq[:, 1]])
    m = len(tri)
    tri6 = np.column_stack([tri, n + inv[:m], n + inv[m : 2 * m], n + inv[2 * m :]])
    be = mesh.boundary_edges[:, :2]
    # locate each boundary edge among the unique (lexicographically sorted) edges
    bkey = np.sort(be, axis=1)
    code = uniq[:, 0] * n + uniq[:, 1]
    bmid = np.searchsorted(code, bkey[:, 0] * n + bkey[:, 1]) + n
    return TriMesh(
        np.vstack([mesh.points, mids]),
        tri6,
        np.column_stack([be, bmid]),
        mesh.boundary_tags.copy(),
        dict(mesh.meta),
    )
