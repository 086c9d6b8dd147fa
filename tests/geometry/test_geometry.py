"""Geometry invariants measured on the built polygons and meshes (mm, deg)."""

import json

import numpy as np
import pytest
import shapely
from matplotlib.tri import Triangulation
from shapely.geometry import LineString, MultiLineString, Polygon

from finray.geometry.finger import (
    FingerParams,
    GeometryError,
    finger_polygon,
    mesh_finger,
)
from finray.geometry.mesh import BOUNDARY_TAGS, TriMesh, quality, signed_areas
from finray.geometry.objects import object_geometry, object_shape, place_object
from finray.geometry.surface import check_watertight, extrude
from helpers import front_face_x

P = FingerParams()


@pytest.fixture(scope="module")
def poly():
    return finger_polygon(P)


@pytest.fixture(scope="module")
def mesh():
    return mesh_finger(P, 0.5)


def material_intervals(poly, p0, p1):
    """Intervals of the segment p0-p1 inside the material, as (start, end) points."""
    inter = poly.intersection(LineString([p0, p1]))
    parts = getattr(inter, "geoms", [inter])
    return [np.asarray(g.coords) for g in parts if g.length > 0]


def rib_centre_at(poly, x, y_guess):
    """Mid-height and vertical thickness of the rib crossing x near y_guess."""
    segs = material_intervals(poly, (x, y_guess - 2.5), (x, y_guess + 2.5))
    seg = min(segs, key=lambda s: abs(s[:, 1].mean() - y_guess))
    return seg[:, 1].mean(), abs(seg[1, 1] - seg[0, 1])


def test_rib_angles_step_by_three_degrees_and_thickness(poly):
    W, t = P.base_width_mm, P.wall_thickness_mm
    angles = []
    for i, y_back in enumerate(P.rib_back_heights_mm()):
        a_expected = np.radians(P.rib_angles_deg()[i])
        # two vertical cuts through the straight middle part of the rib
        x1 = W - t - 3.0
        x0 = x1 - 3.0
        y1, h1 = rib_centre_at(poly, x1, y_back - 3.0 * np.tan(a_expected))
        y0, h0 = rib_centre_at(poly, x0, y_back - 6.0 * np.tan(a_expected))
        angle = np.arctan2(y1 - y0, x1 - x0)  # falls towards the front: positive
        angles.append(np.degrees(angle))
        # vertical cut through a strip of thickness t_r at angle a is t_r / cos(a)
        assert h1 * np.cos(angle) == pytest.approx(P.ribs.thickness_mm, abs=1e-6)
    steps = np.diff(angles)
    np.testing.assert_allclose(steps, 3.0, atol=1e-6)
    assert angles[0] == pytest.approx(P.ribs.first_angle_deg, abs=1e-6)


def test_wall_thickness(poly):
    y = 10.0  # the cut also crosses a slanted rib: keep the outermost intervals
    segs = sorted(
        material_intervals(poly, (-1, y), (P.base_width_mm + 1, y)), key=lambda s: s[:, 0].min()
    )
    front, back = segs[0], segs[-1]
    assert back[:, 0].max() == pytest.approx(P.base_width_mm)
    assert abs(back[1, 0] - back[0, 0]) == pytest.approx(P.wall_thickness_mm, abs=1e-9)
    # the front wall is inclined: horizontal width = t / cos(front angle)
    width = abs(front[1, 0] - front[0, 0])
    assert width * np.cos(np.radians(P.front_angle_deg)) == pytest.approx(
        P.wall_thickness_mm, abs=1e-9
    )
    assert front[:, 0].min() == pytest.approx(float(front_face_x(P, y)), abs=1e-9)


def test_finger_height_and_base(poly):
    minx, miny, maxx, maxy = poly.bounds
    assert (minx, miny, maxx) == pytest.approx((0.0, 0.0, P.base_width_mm), abs=1e-9)
    assert maxy == pytest.approx(P.height_mm, abs=0.01)  # polygonal arc of the tip


def fit_circle(pts):
    """Least-squares circle (Kasa): centre and radius."""
    A = np.column_stack([2 * pts, np.ones(len(pts))])
    b = (pts**2).sum(1)
    (cx, cy, c), *_ = np.linalg.lstsq(A, b, rcond=None)
    return np.array([cx, cy]), np.sqrt(c + cx**2 + cy**2)


def test_cavity_fillet_radii():
    """Every convex corner of a cavity is rounded with radius r: a region whose
    corners all have radius >= r is unchanged by a morphological opening with a disc
    of radius r, while an opening with 1.5 r cuts the corners (checked on arcs drawn
    with 0.025 mm chords, so that polygonisation stays below 1 um)."""
    r = P.fillet_radius_mm
    poly = finger_polygon(P, 0.025)
    assert len(poly.interiors) == P.ribs.count + 1
    for ring in poly.interiors:
        cav = Polygon(ring)
        q = 64
        same = cav.buffer(-r * (1 - 1e-3), quad_segs=q).buffer(r * (1 - 1e-3), quad_segs=q)
        assert cav.symmetric_difference(same).area < 1e-3 * cav.length * r
        cut = cav.buffer(-1.5 * r, quad_segs=q).buffer(1.5 * r, quad_segs=q)
        assert cav.difference(cut).area > 0.05 * r * r  # corners of radius r are cut


def test_mesh_quality_and_resolution(mesh, poly):
    q = quality(mesh)
    assert q["min_angle_deg"] >= 20.0
    assert q["n_inverted"] == 0
    assert q["area_mm2"] == pytest.approx(poly.area, rel=1e-9)
    # mid-side nodes sit at the middle of their edges
    p = mesh.points
    for k, (a, b) in enumerate([(0, 1), (1, 2), (2, 0)]):
        tri = mesh.triangles
        np.testing.assert_allclose(
            p[tri[:, 3 + k]], 0.5 * (p[tri[:, a]] + p[tri[:, b]]), atol=1e-12
        )
    # at least two elements across every rib and across the walls
    tr = Triangulation(p[:, 0], p[:, 1], mesh.corner_triangles)
    finder = tr.get_trifinder()
    cuts = []
    for yb, a in zip(P.rib_back_heights_mm(), np.radians(P.rib_angles_deg())):
        x = P.base_width_mm - P.wall_thickness_mm - 4.0
        yc = yb - 4.0 * np.tan(a)
        n = np.array([np.sin(a), -np.cos(a)])  # normal to the rib
        cuts.append((np.array([x, yc]) - n, np.array([x, yc]) + n))
    cuts.append((np.array([P.base_width_mm - 2, 10.0]), np.array([P.base_width_mm + 0.5, 10.0])))
    for p0, p1 in cuts:
        s = np.linspace(0, 1, 2001)[:, None]
        pts = p0 + s * (p1 - p0)
        hit = finder(pts[:, 0], pts[:, 1])
        assert len(np.unique(hit[hit >= 0])) >= 2


def test_boundary_tags_complete(mesh):
    tags = mesh.boundary_tags
    assert (tags > 0).all()
    for name in ("base", "front", "back", "tip", "cavity"):
        assert (tags == BOUNDARY_TAGS[name]).any(), name
    p = mesh.points
    base = mesh.edges_with_tag("base")
    np.testing.assert_allclose(p[base[:, :2], 1], 0.0, atol=1e-12)
    length = np.linalg.norm(p[base[:, 0]] - p[base[:, 1]], axis=1).sum()
    assert length == pytest.approx(P.base_width_mm, abs=1e-9)
    back = mesh.edges_with_tag("back")
    np.testing.assert_allclose(p[back[:, :2], 0], P.base_width_mm, atol=1e-9)
    # boundary edges form closed loops: each node starts and ends exactly one edge
    e = mesh.boundary_edges[:, :2]
    assert np.array_equal(np.sort(e[:, 0]), np.sort(e[:, 1]))
    # material on the left of every boundary edge
    mid = 0.5 * (p[e[:, 0]] + p[e[:, 1]])
    d = p[e[:, 1]] - p[e[:, 0]]
    left = mid + 1e-4 * np.column_stack([-d[:, 1], d[:, 0]]) / np.linalg.norm(d, axis=1)[:, None]
    tr = Triangulation(p[:, 0], p[:, 1], mesh.corner_triangles)
    assert (tr.get_trifinder()(left[:, 0], left[:, 1]) >= 0).all()


def test_no_self_intersection(mesh, poly):
    assert poly.is_valid
    e = mesh.boundary_edges
    segs = np.concatenate([mesh.points[e[:, [0, 2]]], mesh.points[e[:, [2, 1]]]])
    assert MultiLineString(list(segs)).is_simple


def test_surface_watertight(mesh):
    surf = extrude(mesh, P.extrusion_mm)
    topo = check_watertight(surf)
    assert topo["watertight"] and topo["connected_components"] == 1
    assert topo["signed_volume_mm3"] == pytest.approx(
        quality(mesh)["area_mm2"] * P.extrusion_mm, rel=1e-9
    )


def test_mesh_round_trip(tmp_path, mesh):
    import meshio

    mesh.save(tmp_path / "m.npz")
    back = TriMesh.load(tmp_path / "m.npz")
    for k in ("points", "triangles", "boundary_edges", "boundary_tags"):
        assert np.array_equal(getattr(mesh, k), getattr(back, k))
    assert back.meta["quality"] == mesh.meta["quality"]
    mesh.to_meshio().write(tmp_path / "m.vtu")
    m = meshio.read(tmp_path / "m.vtu")
    assert m.cells[0].type == "triangle6" and len(m.cells[0].data) == len(mesh.triangles)


SPECS = {
    "circle": ({"type": "circle", "diameter_mm": 10}, np.pi * 25),
    "square": (
        {"type": "square", "side_mm": 10, "angle_deg": 30, "fillet_mm": 0.5},
        100 - (4 - np.pi) * 0.25,
    ),
    "ring": ({"type": "ring", "diameter_mm": 15, "wall_mm": 2}, np.pi * (7.5**2 - 5.5**2)),
    "ellipse": ({"type": "ellipse", "width_mm": 16, "height_mm": 9}, np.pi * 8 * 4.5),
}


@pytest.mark.parametrize("name", list(SPECS))
@pytest.mark.parametrize("height", [20.0, 30.0, 40.0])
def test_objects_placed_with_gap(name, height, poly):
    spec, area = SPECS[name]
    obj = object_geometry(name, spec, P, height, deformable=(name == "ring"))
    ref = np.array(obj.meta["reference_point_mm"])
    assert ref[1] == height
    e = obj.boundary_edges
    segs = (
        obj.points[e[:, :2]]
        if obj.order == 1
        else np.concatenate([obj.points[e[:, [0, 2]]], obj.points[e[:, [2, 1]]]])
    )
    gap = shapely.distance(poly, MultiLineString(list(segs)))
    assert gap == pytest.approx(0.1, abs=1e-6)
    assert obj.meta["area_mm2"] == pytest.approx(area, rel=5e-3)  # polygonised arcs
    # the reference point is the shape's own origin, moved rigidly
    shape = object_shape(spec)
    assert obj.meta["area_mm2"] == pytest.approx(shape.area, rel=1e-12)
    if name == "ring":
        q = quality(obj)
        assert q["min_angle_deg"] >= 20 and q["n_inverted"] == 0
        assert set(np.unique(obj.boundary_tags)) == {
            BOUNDARY_TAGS["object"],
            BOUNDARY_TAGS["object_inner"],
        }
    else:
        assert len(obj.triangles) == 0  # rigid: boundary only
        assert (obj.boundary_tags == BOUNDARY_TAGS["object"]).all()


def test_square_fillets_and_rotation():
    shape = object_shape({"type": "square", "side_mm": 15, "angle_deg": 45, "fillet_mm": 0.5})
    # rotated 45 deg: the half-diagonal of the rounded square along x
    half_diag = 7.5 * np.sqrt(2) - 0.5 * (np.sqrt(2) - 1)
    # the arc is a polygon whose vertices lie on the fillet circle: sagitta < 5 um
    assert shape.bounds[2] == pytest.approx(half_diag, abs=5e-3)
    assert shape.bounds[2] <= half_diag + 1e-9
    # every vertex of the rounded corners lies on a 0.5 mm circle
    c = np.asarray(shape.exterior.coords)[:-1]
    corner = c[c[:, 0] > 10.0]  # vertices of the corner pointing along +x
    assert len(corner) >= 3
    assert fit_circle(corner)[1] == pytest.approx(0.5, rel=1e-6)


def test_bad_geometry_raises():
    with pytest.raises(GeometryError, match="first_height_mm"):
        finger_polygon(FingerParams(ribs=type(P.ribs)(first_height_mm=3.0)))
    with pytest.raises(GeometryError, match="heights_mm"):
        place_object(object_shape({"type": "circle", "diameter_mm": 5}), P, 85.0)
    with pytest.raises(GeometryError, match="below the clamped base"):
        place_object(object_shape({"type": "circle", "diameter_mm": 20}), P, 5.0)


def test_polygon_file_validation(tmp_path):
    good = tmp_path / "tri.json"
    good.write_text(json.dumps([[-5, -4], [6, -3], [0, 6], [-5, -4]]))
    obj = object_geometry("tri", {"type": "polygon_file", "path": str(good)}, P, 30.0)
    assert obj.meta["area_mm2"] == pytest.approx(Polygon([(-5, -4), (6, -3), (0, 6)]).area)
    cases = {
        "bowtie": ([[0, 0], [4, 4], [4, 0], [0, 4]], "intersects itself"),
        "flat": ([[0, 0], [1, 1], [2, 2]], "zero area"),
        "two": ([[0, 0], [1, 1]], "at least 3"),
        "bad": ("not a polygon", "list of"),
    }
    for name, (pts, msg) in cases.items():
        f = tmp_path / f"{name}.json"
        f.write_text(json.dumps(pts))
        with pytest.raises(GeometryError, match=msg):
            object_shape({"type": "polygon_file", "path": str(f)})
    with pytest.raises(GeometryError, match="does not exist"):
        object_shape({"type": "polygon_file", "path": str(tmp_path / "none.json")})


def test_signed_areas_orientation():
    pts = np.array([[0, 0], [1, 0], [0, 1]], float)
    assert signed_areas(pts, np.array([[0, 1, 2]]))[0] == pytest.approx(0.5)
    assert signed_areas(pts, np.array([[0, 2, 1]]))[0] == pytest.approx(-0.5)


def test_fillet_chords_follow_arc_chord_not_mesh_size():
    """Arcs are drawn with chords <= mesh.arc_chord_mm whatever the element size, and the
    polygonal (inscribed) fillets converge to the round ones from the material side."""
    from finray.geometry.finger import _arc_segments

    r = P.fillet_radius_mm
    for chord in (0.25, 0.1, 0.05):
        assert 0.5 * np.pi * r / _arc_segments(r, chord) <= chord + 1e-12
    areas = [finger_polygon(P, c).area for c in (0.25, 0.1, 0.05)]
    assert areas[0] > areas[1] > areas[2]  # less material as the fillets get rounder
    m1, m2 = mesh_finger(P, 1.0, arc_chord_mm=0.1), mesh_finger(P, 0.5, arc_chord_mm=0.1)
    assert m1.meta["area_mm2"] == pytest.approx(m2.meta["area_mm2"], rel=1e-12)
    assert m1.meta["arc_chord_mm"] == 0.1
