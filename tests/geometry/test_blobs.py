"""Seeded smooth random polygons (finray.geometry.blobs) and their generated objects."""

import numpy as np
import pytest
import shapely
from shapely.geometry import Polygon

from finray.geometry.blobs import (
    blob_diameter,
    blob_name,
    blob_outline,
    feret_diameter,
    generated_objects,
)
from finray.geometry.finger import FingerParams, GeometryError, outer_polygon
from finray.geometry.mesh import BOUNDARY_TAGS
from finray.geometry.objects import object_geometry, object_shape

GEN = {
    "count": 300,
    "seed": 0,
    "size_mm": [5.0, 25.0],
    "harmonics": 5,
    "amplitude": 0.4,
    "split": "train",
    "materials": ["steel"],
}


@pytest.fixture(scope="module")
def specs():
    return generated_objects(GEN)


@pytest.fixture(scope="module")
def shapes(specs):
    return {n: object_shape(s, 1.0, f"objects.{n}") for n, s in specs.items()}


def test_names_and_seeds(specs):
    assert list(specs)[:2] == ["blob_s000", "blob_s001"] and list(specs)[-1] == "blob_s299"
    assert blob_name(17) == "blob_s017" and blob_name(1234) == "blob_s1234"
    assert [s["seed"] for s in specs.values()] == list(range(300))
    assert {s["type"] for s in specs.values()} == {"blob"}


def test_deterministic_per_seed():
    a = blob_outline(17, 12.0)
    assert np.array_equal(a, blob_outline(17, 12.0))
    assert blob_diameter(17, (5, 25)) == blob_diameter(17, (5, 25))
    b = blob_outline(18, 12.0)
    assert len(a) != len(b) or not np.allclose(a, b)


def test_a_blob_does_not_depend_on_count_or_first_seed():
    """The slice's blobs are the full set's: blob_s<seed> is the same whatever count."""
    full = generated_objects(GEN)
    part = generated_objects({**GEN, "count": 10, "seed": 5})
    assert list(part) == [f"blob_s{s:03d}" for s in range(5, 15)]
    assert all(part[n] == full[n] for n in part)


def test_sizes_within_range(specs, shapes):
    d = np.array([s["diameter_mm"] for s in specs.values()])
    assert d.min() >= 5.0 and d.max() <= 25.0
    assert d.min() < 7.0 and d.max() > 23.0  # the range is covered, not one size
    for n, shape in shapes.items():
        pts = np.asarray(shape.exterior.coords)[:-1]
        brute = np.sqrt(((pts[:, None] - pts[None]) ** 2).sum(-1)).max()  # exact Feret diameter
        assert brute == pytest.approx(specs[n]["diameter_mm"], rel=1e-6), n
        assert feret_diameter(pts) == pytest.approx(brute, rel=1e-12)


def test_closed_simple_star_shaped_outlines(shapes):
    for n, shape in shapes.items():
        assert isinstance(shape, Polygon) and shape.is_valid, n
        assert shape.exterior.is_ring and shape.exterior.is_simple and not shape.interiors, n
        assert shape.exterior.is_ccw, n
        pts = np.asarray(shape.exterior.coords)[:-1]
        # one vertex per direction from the reference point: its angle rises all the way round
        ang = np.unwrap(np.arctan2(pts[:, 1], pts[:, 0]))
        assert np.all(np.diff(ang) > 0) and ang[-1] - ang[0] < 2 * np.pi, n
        # chords of at most half the mesh size (as the circles'), none degenerate
        chords = np.linalg.norm(np.roll(pts, -1, 0) - pts, axis=1)
        assert chords.max() <= 0.5 + 1e-9 and chords.min() > 0.05, n


def test_convex_and_concave_both_occur(shapes):
    solidity = np.array([s.area / s.convex_hull.area for s in shapes.values()])
    concave = solidity < 1 - 1e-3
    assert 0.2 < concave.mean() < 0.8, concave.mean()
    assert (solidity < 0.95).mean() > 0.1 and solidity.min() < 0.9  # some clearly concave


def test_smooth_ones_are_convex():
    """amplitude 0: circles; harmonics cannot dent a curve with no roughness."""
    pts = blob_outline(3, 10.0, amplitude=0.0, max_chord_mm=0.1)
    r = np.linalg.norm(pts, axis=1)
    assert r.max() - r.min() < 1e-3 and r.mean() == pytest.approx(5.0, abs=1e-3)


@pytest.mark.parametrize(
    "kwargs, key",
    [
        ({"seed": -1}, "objects.b.seed"),
        ({"seed": 1.5}, "objects.b.seed"),
        ({"diameter_mm": 0.0}, "objects.b.diameter_mm"),
        ({"diameter_mm": float("nan")}, "objects.b.diameter_mm"),
        ({"harmonics": 0}, "objects.b.harmonics"),
        ({"harmonics": 17}, "objects.b.harmonics"),
        ({"amplitude": 0.7}, "objects.b.amplitude"),
        ({"amplitude": -0.1}, "objects.b.amplitude"),
        ({"max_chord_mm": 0.0}, "objects.b.max_chord_mm"),
    ],
)
def test_bad_parameters_one_line(kwargs, key):
    args = {"seed": 1, "diameter_mm": 10.0, **kwargs}
    with pytest.raises(GeometryError) as err:
        blob_outline(key="objects.b", **args)
    assert err.value.key == key and str(err.value).startswith(key + ": must be")
    assert "\n" not in str(err.value)


def test_bad_size_range_one_line():
    with pytest.raises(GeometryError, match=r"^generated.size_mm: must be \[min, max\]") as err:
        generated_objects({**GEN, "size_mm": [25.0, 5.0]})
    assert "\n" not in str(err.value)


@pytest.mark.parametrize("height", [20.0, 30.0, 40.0])
def test_largest_blob_placed_and_meshed_as_rigid(specs, height):
    name = max(specs, key=lambda n: specs[n]["diameter_mm"])
    m = object_geometry(name, specs[name], FingerParams(), height, size_mm=1.0)
    assert m.meta["rigid"] and len(m.triangles) == 0
    assert np.all(m.boundary_tags == BOUNDARY_TAGS["object"])
    assert len(m.boundary_edges) == len(m.points)  # one closed loop
    # left of the finger's front face, 0.1 mm off it
    gap = outer_polygon(FingerParams()).distance(shapely.geometry.Polygon(m.points))
    assert gap == pytest.approx(0.1, abs=1e-3)  # (the resampled outline: chords cut in)
    assert m.meta["reference_point_mm"][1] == height


def test_deformable_blob_is_meshed(specs):
    m = object_geometry(
        "blob_s001", specs["blob_s001"], FingerParams(), 30.0, size_mm=1.0, deformable=True
    )
    assert len(m.triangles) > 0 and m.meta["quality"]["min_angle_deg"] > 20
