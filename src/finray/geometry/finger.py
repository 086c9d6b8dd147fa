"""Parametric Fin Ray finger profile (mm).

Frame: the base (clamped) lies on ``y = 0`` from ``x = 0`` to ``x = base_width``;
the back wall is vertical at ``x = base_width``; the angled front (contact) face
runs from ``(0, 0)`` towards the tip, which is rounded and tops out at ``height``. Objects approach from
``x < 0`` and are pushed in ``+x``.

Rib ``i`` (0 = lowest) crosses the cavity between the inner faces of the walls.
Its centre line meets the inner face of the back wall at
``first_height + i * spacing`` and falls towards the front face at
``first_angle + i * angle_step`` degrees below the horizontal (a negative angle
makes it rise). The re-entrant corners of the cavities are filleted so that the
stress and the contact stay regular.
"""

from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np
import shapely
from shapely.geometry import LineString, MultiPolygon, Polygon, box

from .mesh import BOUNDARY_TAGS, TriMesh, quality, triangulate_polygon
from ..errors import GeometryError
from ..schema import schema_default


@dataclass
class RibParams:
    count: int = schema_default("finger.ribs.count")
    thickness_mm: float = schema_default("finger.ribs.thickness_mm")
    first_height_mm: float = schema_default("finger.ribs.first_height_mm")
    spacing_mm: float = schema_default("finger.ribs.spacing_mm")
    first_angle_deg: float = schema_default("finger.ribs.first_angle_deg")
    angle_step_deg: float = schema_default("finger.ribs.angle_step_deg")


@dataclass
class FingerParams:
    height_mm: float = schema_default("finger.height_mm")
    base_width_mm: float = schema_default("finger.base_width_mm")
    wall_thickness_mm: float = schema_default("finger.wall_thickness_mm")
    base_thickness_mm: float = schema_default("finger.base_thickness_mm")
    tip_radius_mm: float = schema_default("finger.tip_radius_mm")
    fillet_radius_mm: float = schema_default("finger.fillet_radius_mm")
    extrusion_mm: float = schema_default("finger.extrusion_mm")
    material: str = schema_default("finger.material")
    ribs: RibParams = field(default_factory=RibParams)

    @classmethod
    def from_config(cls, cfg: dict) -> "FingerParams":
        cfg = dict(cfg)
        ribs = RibParams(**cfg.pop("ribs", {}))
        return cls(ribs=ribs, **cfg)

    @property
    def apex_height_mm(self) -> float:
        """Height of the sharp apex of the profile triangle, chosen so that the
        rounded tip (radius ``tip_radius_mm``) tops out at ``height_mm``."""
        apex = self.height_mm
        for _ in range(50):  # fixed point: apex = height + drop of the rounded tip
            # (the tip circle touches the vertical back wall: its centre lies
            # r / tan(half-angle) below the apex)
            half = 0.5 * np.arctan2(self.base_width_mm, apex)
            apex = self.height_mm + self.tip_radius_mm * (1 / np.tan(half) - 1)
        return float(apex)

    @property
    def front_angle_deg(self) -> float:
        """Angle of the front face from the vertical, degrees."""
        return float(np.degrees(np.arctan2(self.base_width_mm, self.apex_height_mm)))

    def rib_angles_deg(self) -> np.ndarray:
        r = self.ribs
        return r.first_angle_deg + r.angle_step_deg * np.arange(r.count)

    def rib_back_heights_mm(self) -> np.ndarray:
        r = self.ribs
        return r.first_height_mm + r.spacing_mm * np.arange(r.count)


def _front_normal(p: FingerParams) -> np.ndarray:
    """Unit normal of the front face pointing into the finger (+x side)."""
    n = np.array([p.apex_height_mm, -p.base_width_mm])
    return n / np.linalg.norm(n)


#: Default longest chord of a fillet or tip arc (mm), independent of the element size
#: (config ``mesh.arc_chord_mm``). The polygonal fillets of the cavities are inscribed
#: in the round ones, so they add material at the rib joints, where the finger bends:
#: Fx at 10 mm is ~2 % too high with 0.25 mm chords (two per quarter of a 0.3 mm
#: fillet), 0.3 % with 0.1 mm, and the error falls as chord^2 (results/benchmarks/
#: fea_pareto.md). The short chords also grade the mesh: Triangle puts small
#: elements at the joints and large ones elsewhere.
ARC_CHORD_MM = 0.1


def _arc_segments(radius: float, chord_mm: float = ARC_CHORD_MM) -> int:
    """Segments per quarter circle of ``radius`` (mm): chords of at most ``chord_mm``."""
    if not chord_mm > 0:
        raise GeometryError("mesh.arc_chord_mm", f"must be > 0, got {chord_mm}")
    return max(2, int(np.ceil(0.5 * np.pi * radius / chord_mm)))


def rib_centrelines(p: FingerParams) -> list[tuple[np.ndarray, np.ndarray]]:
    """(back point, front point) of each rib centre line on the inner wall faces."""
    t, W = p.wall_thickness_mm, p.base_width_mm
    n = _front_normal(p)
    out = []
    for y, a in zip(p.rib_back_heights_mm(), np.radians(p.rib_angles_deg())):
        b = np.array([W - t, y])
        d = np.array([-np.cos(a), -np.sin(a)])
        s = (t - n @ b) / (n @ d)  # inner front face: n . x = t
        out.append((b, b + s * d))
    return out


def check_ribs(p: FingerParams) -> None:
    """Raise :class:`GeometryError` if a rib does not fit between the walls."""
    r = p.ribs
    key = "finger.ribs"
    tip_y = _inner_tip_height(p)
    t_wall = p.wall_thickness_mm
    n = _front_normal(p)
    clearance = r.thickness_mm / 2 + 2 * p.fillet_radius_mm
    for i, (b, f) in enumerate(rib_centrelines(p)):
        a = np.radians(p.rib_angles_deg()[i])
        half = r.thickness_mm / (2 * np.cos(a))  # half-thickness measured vertically
        if b[1] + half + 2 * p.fillet_radius_mm >= tip_y:
            raise GeometryError(
                f"{key}.spacing_mm",
                (
                    f"rib {i + 1} meets the back wall at y={b[1]:.2f} mm, above the cavity "
                    f"tip at y={tip_y:.2f} mm; use fewer ribs or a smaller spacing"
                ),
            )
        # width of the cavity at the rib's back end, along the horizontal
        width = b[0] - (t_wall - n[1] * b[1]) / n[0]  # inner front face: n . x = t
        if width < 2 * clearance + r.thickness_mm:
            raise GeometryError(
                f"{key}.spacing_mm",
                (
                    f"rib {i + 1} meets the back wall at y={b[1]:.2f} mm, where the cavity "
                    f"is only {max(width, 0):.2f} mm wide; use fewer ribs or a smaller spacing"
                ),
            )
        if f[0] >= b[0] - 2 * clearance:
            raise GeometryError(
                f"{key}.first_angle_deg",
                (
                    f"rib {i + 1} does not reach the front wall (angle "
                    f"{p.rib_angles_deg()[i]:.1f} deg is too steep)"
                ),
            )
        floor = p.base_thickness_mm + 2 * p.fillet_radius_mm
        if min(f[1], b[1]) - half < floor:
            raise GeometryError(
                f"{key}.first_height_mm",
                (
                    f"rib {i + 1} runs into the base plate (its lower edge reaches "
                    f"y={min(f[1], b[1]) - half:.2f} mm; it must stay above y={floor:.2f} mm, "
                    "the base plate plus two fillet radii)"
                ),
            )
        if f[1] + half + 2 * p.fillet_radius_mm >= tip_y:
            raise GeometryError(
                f"{key}.first_angle_deg", (f"rib {i + 1} meets the front wall above the cavity tip")
            )
    ends = rib_centrelines(p)
    for i in range(r.count - 1):
        (b0, f0), (b1, f1) = ends[i], ends[i + 1]
        gap = min(b1[1] - b0[1], f1[1] - f0[1]) - r.thickness_mm
        if gap < 2 * p.fillet_radius_mm + 0.1:
            raise GeometryError(
                f"{key}.spacing_mm",
                (
                    f"ribs {i + 1} and {i + 2} touch or cross (vertical gap {gap:.2f} mm at "
                    f"the walls); increase spacing or reduce angle_step_deg"
                ),
            )


def _inner_tip_height(p: FingerParams) -> float:
    """Height (mm) of the apex of the cavity triangle."""
    t, W = p.wall_thickness_mm, p.base_width_mm
    n = _front_normal(p)
    # intersection of x = W - t with n . x = t
    return float((t - n[0] * (W - t)) / n[1])


def outer_polygon(p: FingerParams, arc_chord_mm: float = ARC_CHORD_MM) -> Polygon:
    """Finger outline with a rounded tip (chords <= ``arc_chord_mm``) and square base
    corners."""
    W, H = p.base_width_mm, p.apex_height_mm
    tri = Polygon([(0, 0), (W, 0), (W, H)])
    q = _arc_segments(p.tip_radius_mm, arc_chord_mm)
    rounded = tri.buffer(-p.tip_radius_mm, quad_segs=q).buffer(p.tip_radius_mm, quad_segs=q)
    base = tri.intersection(box(-1, -1, W + 1, p.base_thickness_mm))
    return rounded.union(base)


def cavities(p: FingerParams, arc_chord_mm: float = ARC_CHORD_MM) -> list[Polygon]:
    """The hollow cells between ribs, with filleted corners (chords <= ``arc_chord_mm``)."""
    W, H, t = p.base_width_mm, p.apex_height_mm, p.wall_thickness_mm
    tri = Polygon([(0, 0), (W, 0), (W, H)])
    hollow = tri.buffer(-t, join_style="mitre").intersection(
        box(-1, p.base_thickness_mm, W + 1, H + 1)
    )
    strips = []
    for b, f in rib_centrelines(p):
        d = (f - b) / np.linalg.norm(f - b)
        line = LineString([b - 2 * t * d, f + 2 * t * d])  # overshoot into the walls
        strips.append(line.buffer(p.ribs.thickness_mm / 2, cap_style="flat"))
    cells = hollow.difference(shapely.union_all(strips))
    parts = list(cells.geoms) if isinstance(cells, MultiPolygon) else [cells]
    if len(parts) != p.ribs.count + 1:
        raise GeometryError(
            "finger.ribs",
            (
                f"the ribs split the cavity into {len(parts)} cells, expected "
                f"{p.ribs.count + 1}; check spacing_mm and the angles"
            ),
        )
    r = p.fillet_radius_mm
    q = _arc_segments(r, arc_chord_mm)
    out = []
    for i, c in enumerate(sorted(parts, key=lambda c: c.centroid.y)):
        rc = c.buffer(-r, quad_segs=q).buffer(r, quad_segs=q) if r > 0 else c
        if not isinstance(rc, Polygon) or rc.is_empty or rc.area < 0.5 * c.area:
            raise GeometryError(
                "finger.fillet_radius_mm",
                (
                    f"a {r} mm fillet does not fit in cavity {i + 1} (area {c.area:.2f} mm^2, "
                    f"below rib {i + 1}); reduce the fillet, the number of ribs or angle_step_deg"
                ),
            )
        out.append(shapely.set_precision(rc, 1e-9))
    return out


def finger_polygon(p: FingerParams, arc_chord_mm: float = ARC_CHORD_MM) -> Polygon:
    """Material region of the finger profile; arcs drawn with chords <= ``arc_chord_mm``
    (mm), whatever the element size."""
    check_ribs(p)
    poly = outer_polygon(p, arc_chord_mm).difference(shapely.union_all(cavities(p, arc_chord_mm)))
    poly = poly.simplify(1e-4)  # drop collinear points left by the boolean operations
    if not isinstance(poly, Polygon) or not poly.is_valid:
        raise GeometryError("finger", "the finger profile is not a single valid polygon")
    return poly


def tag_finger_boundary(mesh: TriMesh, poly: Polygon, p: FingerParams) -> None:
    """Classify every boundary edge of a finger mesh (in place)."""
    e = mesh.boundary_edges
    mid = 0.5 * (mesh.points[e[:, 0]] + mesh.points[e[:, 1]])
    pts = shapely.points(mid)
    on_outer = shapely.distance(poly.exterior, pts) < 1e-6
    tol = 1e-6
    n = _front_normal(p)
    tags = np.full(len(e), BOUNDARY_TAGS["cavity"])
    ext = on_outer
    tags[ext] = BOUNDARY_TAGS["tip"]
    tags[ext & (np.abs(mid @ n) < tol)] = BOUNDARY_TAGS["front"]
    tags[ext & (np.abs(mid[:, 0] - p.base_width_mm) < tol)] = BOUNDARY_TAGS["back"]
    tags[ext & (np.abs(mid[:, 1]) < tol)] = BOUNDARY_TAGS["base"]
    mesh.boundary_tags = tags


def mesh_finger(
    p: FingerParams,
    size_mm: float = 0.5,
    min_angle_deg: float = schema_default("mesh.min_angle_deg"),
    order: int = schema_default("mesh.order"),
    arc_chord_mm: float = ARC_CHORD_MM,
) -> TriMesh:
    """Quadratic triangle mesh of the finger with tagged boundaries.

    ``size_mm``: element edge length (mm) away from the arcs; ``arc_chord_mm``: longest
    chord of the fillet and tip arcs (mm), which also sets the element size there.
    """
    poly = finger_polygon(p, arc_chord_mm)
    mesh, _ = triangulate_polygon(poly, size_mm, min_angle_deg, order)
    tag_finger_boundary(mesh, poly, p)
    mesh.meta.update(
        {
            "kind": "finger",
            "size_mm": size_mm,
            "min_angle_deg": min_angle_deg,
            "arc_chord_mm": arc_chord_mm,
            "front_angle_deg": p.front_angle_deg,
            "rib_angles_deg": p.rib_angles_deg().tolist(),
            "rib_back_heights_mm": p.rib_back_heights_mm().tolist(),
            "extrusion_mm": p.extrusion_mm,
            "area_mm2": poly.area,
            "tag_ids": BOUNDARY_TAGS,
        }
    )
    mesh.meta["quality"] = quality(mesh)
    return mesh
