"""Closed 3D surface of the extruded finger, for rendering (mm).

The 2D mesh is extruded symmetrically to ``z = +-extrusion/2``. Every node of the
2D mesh appears once on each cap, so a deformed frame is rendered by updating the
surface points from the 2D displacements through ``node_map`` (no re-meshing).
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from .mesh import TriMesh, split_p2_edges

#: Each 6-node triangle split into four 3-node triangles (keeps the ribs' curvature).
P2_SUBTRIANGLES = np.array([[0, 3, 5], [3, 1, 4], [5, 4, 2], [3, 4, 5]])


@dataclass
class Surface:
    points: np.ndarray  # (V, 3) mm
    faces: np.ndarray  # (F, 3), outward normals
    node_map: np.ndarray  # (V,) index of the 2D node behind each surface vertex

    def deformed(self, points2d: np.ndarray) -> np.ndarray:
        """Surface points (V, 3) for deformed 2D node positions (N, 2)."""
        out = self.points.copy()
        out[:, :2] = points2d[self.node_map]
        return out

    def signed_volume(self) -> float:
        a, b, c = (self.points[self.faces[:, i]] for i in range(3))
        return float(np.einsum("ij,ij->i", a, np.cross(b, c)).sum() / 6.0)


def linear_triangles(mesh: TriMesh) -> np.ndarray:
    """3-node triangles covering the mesh (P2 elements split in four)."""
    if mesh.order == 1:
        return mesh.triangles
    return mesh.triangles[:, P2_SUBTRIANGLES].reshape(-1, 3)


def extrude(mesh: TriMesh, extrusion_mm: float) -> Surface:
    """Watertight, outward-oriented surface of the extruded 2D mesh."""
    n = len(mesh.points)
    used = np.unique(mesh.triangles)
    remap = -np.ones(n, dtype=np.int64)
    remap[used] = np.arange(len(used))
    k = len(used)
    half = 0.5 * extrusion_mm
    pts = np.vstack(
        [
            np.column_stack([mesh.points[used], np.full(k, half)]),
            np.column_stack([mesh.points[used], np.full(k, -half)]),
        ]
    )
    tri = remap[linear_triangles(mesh)]
    seg = remap[split_p2_edges(mesh.boundary_edges)]
    top = tri  # counter-clockwise seen from +z: normal +z
    bottom = tri[:, ::-1] + k
    a, b = seg[:, 0], seg[:, 1]
    # material on the left of a->b, so the outward side is on the right
    sides = np.vstack([np.column_stack([a, a + k, b]), np.column_stack([b, a + k, b + k])])
    faces = np.vstack([top, bottom, sides])
    return Surface(pts, faces, np.concatenate([used, used]))


def check_watertight(surface: Surface) -> dict:
    """Topology of the surface from pymeshlab: boundary and non-manifold edges."""
    import pymeshlab

    ms = pymeshlab.MeshSet()
    ms.add_mesh(pymeshlab.Mesh(vertex_matrix=surface.points, face_matrix=surface.faces))
    topo = ms.get_topological_measures()
    return {
        "boundary_edges": int(topo["boundary_edges"]),
        "non_manifold_edges": int(topo["non_two_manifold_edges"]),
        "non_manifold_vertices": int(topo["non_two_manifold_vertices"]),
        "connected_components": int(topo["connected_components_number"]),
        "signed_volume_mm3": surface.signed_volume(),
        "watertight": topo["boundary_edges"] == 0 and topo["non_two_manifold_edges"] == 0,
    }
