"""Objects pressed into the finger (mm).

Every shape is built around its reference point at the origin (the point that is
placed at the contact height and moved by the load), then placed left of the
front face at the height of the contact with a gap of ``gap_mm`` to the finger.
Rigid objects are boundaries only; deformable ones are meshed.
"""

from __future__ import annotations

import json
from pathlib import Path

import numpy as np
import shapely
from shapely import affinity
from shapely.geometry import Point, Polygon, box

from .blobs import blob_outline
from .finger import FingerParams, GeometryError, outer_polygon
from .mesh import BOUNDARY_TAGS, TriMesh, polygon_rings, quality, triangulate_polygon
from ..schema import schema_default

OBJECT_TYPES = ("circle", "square", "ring", "ellipse", "polygon", "polygon_file", "blob")


def _circle(d: float, size_mm: float) -> Polygon:
    q = max(4, int(np.ceil(np.pi * d / 4 / (0.5 * size_mm))))  # segments per quarter
    return Point(0, 0).buffer(d / 2, quad_segs=q)


def _rounded(poly: Polygon, fillet: float, size_mm: float) -> Polygon:
    """Round convex and concave corners with radius ``fillet``."""
    if fillet <= 0:
        return poly
    q = max(2, int(np.ceil(0.5 * np.pi * fillet / (0.25 * size_mm))))
    out = poly.buffer(-fillet, quad_segs=q).buffer(fillet, quad_segs=q)
    if poly.convex_hull.area > poly.area * (1 + 1e-9):  # concave corners too
        out = out.buffer(fillet, quad_segs=q).buffer(-fillet, quad_segs=q)
    return out


def read_polygon_file(path: str | Path, key: str = "path") -> np.ndarray:
    """Read a user polygon: a JSON list of [x, y] in mm around the reference point."""
    path = Path(path)
    if not path.is_file():
        raise GeometryError(key, f"polygon file '{path}' does not exist")
    try:
        pts = np.asarray(json.loads(path.read_text()), dtype=float)
    except (ValueError, TypeError) as exc:
        raise GeometryError(key, f"'{path}' is not a JSON list of [x, y] pairs ({exc})")
    return pts


def validate_vertices(pts, key: str) -> Polygon:
    """Closed, simple polygon of positive area; a repeated last vertex is dropped."""
    pts = np.asarray(pts, dtype=float)
    if pts.ndim != 2 or pts.shape[1] != 2:
        raise GeometryError(key, "a polygon must be a list of [x, y] pairs in mm")
    if len(pts) > 1 and np.allclose(pts[0], pts[-1]):
        pts = pts[:-1]
    if len(pts) < 3:
        raise GeometryError(key, f"a polygon needs at least 3 distinct vertices, got {len(pts)}")
    if not np.isfinite(pts).all():
        raise GeometryError(key, "polygon vertices must be finite numbers")
    if np.linalg.matrix_rank(pts - pts.mean(0), tol=1e-9) < 2:
        raise GeometryError(key, "the polygon has zero area (its vertices are collinear)")
    ring = shapely.geometry.LinearRing(pts)
    if not ring.is_simple:
        raise GeometryError(key, "the polygon intersects itself (it must be simple)")
    poly = Polygon(pts)
    if poly.area <= 1e-9:
        raise GeometryError(key, "the polygon has zero area")
    return shapely.geometry.polygon.orient(poly, 1.0)


def object_shape(spec: dict, size_mm: float = 0.5, key: str = "object") -> Polygon:
    """Shape of an object spec (config ``objects.<name>``) with its reference point at 0."""
    kind = spec["type"]
    if kind == "circle":
        shape = _circle(spec["diameter_mm"], size_mm)
    elif kind == "ring":
        wall = spec["wall_mm"]
        if 2 * wall >= spec["diameter_mm"]:
            raise GeometryError(
                f"{key}.wall_mm",
                (f"a {wall} mm wall does not fit in a {spec['diameter_mm']} mm ring"),
            )
        shape = _circle(spec["diameter_mm"], size_mm).difference(
            _circle(spec["diameter_mm"] - 2 * wall, size_mm)
        )
    elif kind == "square":
        s = spec["side_mm"]
        f = spec.get("fillet_mm", 0.5)
        if 2 * f >= s:
            raise GeometryError(f"{key}.fillet_mm", f"a {f} mm fillet does not fit a {s} mm square")
        shape = _rounded(box(-s / 2, -s / 2, s / 2, s / 2), f, size_mm)
    elif kind == "ellipse":
        c = _circle(1.0, size_mm / max(spec["width_mm"], spec["height_mm"]))
        shape = affinity.scale(c, spec["width_mm"], spec["height_mm"], origin=(0, 0))
    elif kind in ("polygon", "polygon_file"):
        if kind == "polygon":
            pts = spec["vertices_mm"]
            vkey = f"{key}.vertices_mm"
        else:
            vkey = f"{key}.path"
            pts = read_polygon_file(spec["path"], vkey)
        shape = _rounded(validate_vertices(pts, vkey), spec.get("fillet_mm", 0.0), size_mm)
        if not isinstance(shape, Polygon) or shape.is_empty:
            raise GeometryError(f"{key}.fillet_mm", "the fillet removes the whole polygon")
    elif kind == "blob":  # seeded smooth random polygon (finray.geometry.blobs)
        shape = Polygon(
            blob_outline(
                spec["seed"],
                spec["diameter_mm"],
                spec.get("harmonics", 5),
                spec.get("amplitude", 0.4),
                0.5 * size_mm,
                key,
            )
        )
    else:
        raise GeometryError(
            f"{key}.type", (f"unknown object type '{kind}' (one of {', '.join(OBJECT_TYPES)})")
        )
    angle = spec.get("angle_deg", 0.0)
    if angle:
        shape = affinity.rotate(shape, angle, origin=(0, 0))
    return shapely.geometry.polygon.orient(shape, 1.0)


def place_object(
    shape: Polygon,
    finger: FingerParams,
    height_mm: float,
    gap_mm: float = schema_default("placement.gap_mm"),
    key: str = "object",
) -> tuple[Polygon, np.ndarray]:
    """Translate ``shape`` to contact height ``height_mm``, ``gap_mm`` left of the finger.

    The x offset is found by bisection on the distance to the finger outline, which
    decreases monotonically as the object approaches from the left. Returns the
    placed shape and its reference point (mm).
    """
    outline = outer_polygon(finger)
    if not 0 < height_mm < finger.height_mm:
        raise GeometryError(
            "heights_mm",
            (f"contact height {height_mm} mm is outside the finger (0, {finger.height_mm}) mm"),
        )
    s = affinity.translate(shape, 0.0, height_mm)
    if s.bounds[1] < 0:
        raise GeometryError(
            key,
            (
                f"at contact height {height_mm} mm the object reaches y={s.bounds[1]:.2f} mm, "
                "below the clamped base"
            ),
        )
    width = s.bounds[2] - s.bounds[0]
    lo = -(width + 10.0) - s.bounds[2]  # fully left of the finger: positive distance
    hi = finger.base_width_mm - s.bounds[0]  # right of the finger's left edge
    if s.bounds[1] > finger.height_mm or s.bounds[3] < 0:
        raise GeometryError(key, "the object does not face the finger at this height")
    for _ in range(80):
        mid = 0.5 * (lo + hi)
        d = outline.distance(affinity.translate(s, mid, 0.0))
        lo, hi = (mid, hi) if d > gap_mm else (lo, mid)
    placed = affinity.translate(s, lo, 0.0)
    if abs(outline.distance(placed) - gap_mm) > 1e-6:
        raise GeometryError(key, f"the object cannot be placed {gap_mm} mm off the finger")
    ref = np.array([lo, height_mm])
    return placed, ref


def object_geometry(
    name: str,
    spec: dict,
    finger: FingerParams,
    height_mm: float,
    size_mm: float = 0.5,
    deformable: bool = False,
    gap_mm: float = schema_default("placement.gap_mm"),
    min_angle_deg: float = schema_default("mesh.min_angle_deg"),
) -> TriMesh:
    """Placed object as a :class:`TriMesh`.

    Rigid objects carry no triangles: ``points`` are their boundary vertices and
    ``boundary_edges`` the closed loops (``mid = -1``). Deformable objects are
    quadratic meshes; edges of holes get the tag ``object_inner``.
    """
    key = f"objects.{name}"
    shape = object_shape(spec, size_mm, key)
    placed, ref = place_object(shape, finger, height_mm, gap_mm, key)
    if deformable:
        mesh, _ = triangulate_polygon(placed, size_mm, min_angle_deg, order=2)
        mid = 0.5 * (
            mesh.points[mesh.boundary_edges[:, 0]] + mesh.points[mesh.boundary_edges[:, 1]]
        )
        on_outer = shapely.distance(placed.exterior, shapely.points(mid)) < 1e-6
        mesh.boundary_tags = np.where(
            on_outer, BOUNDARY_TAGS["object"], BOUNDARY_TAGS["object_inner"]
        )
    else:
        rings = polygon_rings(placed, size_mm)
        pts, edges, tags, off = [], [], [], 0
        for k, r in enumerate(rings):
            idx = off + np.arange(len(r))
            pts.append(r)
            edges.append(np.column_stack([idx, np.roll(idx, -1), -np.ones(len(r), int)]))
            tags.append(np.full(len(r), BOUNDARY_TAGS["object" if k == 0 else "object_inner"]))
            off += len(r)
        mesh = TriMesh(
            np.vstack(pts), np.zeros((0, 3), np.int64), np.vstack(edges), np.concatenate(tags)
        )
    mesh.meta.update(
        {
            "kind": "object",
            "name": name,
            "spec": spec,
            "rigid": not deformable,
            "height_mm": height_mm,
            "reference_point_mm": ref.tolist(),
            "gap_mm": gap_mm,
            "area_mm2": placed.area,
            "size_mm": size_mm,
            "tag_ids": BOUNDARY_TAGS,
        }
    )
    if deformable:
        mesh.meta["quality"] = quality(mesh)
    return mesh
