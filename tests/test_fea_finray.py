"""The Fin Ray scene: equilibrium, no interpenetration, failures reported by step."""
import numpy as np
import pytest
from shapely.geometry import Point

from finray.fea.material import NeoHookean, material_from_name
from finray.fea.simulate import (DeformableObject, SimulationError, SimulationOptions,
                                 front_contact_circle, simulate)
from finray.fea.solver import NewtonOptions
from finray.geometry.finger import FingerParams, mesh_finger
from finray.geometry.mesh import triangulate_polygon

FINGER = NeoHookean.from_E_nu(12.0, 0.45, "ninjaflex")


@pytest.fixture(scope="module")
def finger():
    return mesh_finger(FingerParams(), size_mm=1.0)


def check_frames(r, rtol=5e-3):
    F, B = r.force_N_per_mm, r.base_reaction_N_per_mm
    assert np.all(np.isfinite(F)) and np.all(np.isfinite(B))
    for f, b in zip(F[1:], B[1:]):
        # the force of the finger on the object equals the clamp's reaction
        assert np.linalg.norm(f - b) <= rtol * np.linalg.norm(f)
    assert np.all(np.isfinite(r.finger_displacement_mm))
    assert np.all(np.isfinite(r.finger_von_mises_MPa)) and r.finger_von_mises_MPa.min() >= 0
    assert np.nanmin(r.min_gap_object_mm) > 0  # never interpenetrating
    np.testing.assert_allclose(r.force_N, F * r.meta["extrusion_mm"])


def test_rigid_circle_push_equilibrium_every_frame(finger):
    obj = front_contact_circle(FingerParams(), 30.0, 20.0, gap_mm=0.1)
    r = simulate(finger, obj, FINGER, SimulationOptions(frame_step_mm=1.0,
                                                        friction_lag_iterations=1))
    assert len(r.displacement_mm) == 11
    np.testing.assert_allclose(r.displacement_mm, r.target_mm, atol=1e-3)
    check_frames(r)
    fx = r.force_N_per_mm[:, 0]
    assert fx[-1] < 0 and np.all(np.diff(fx[1:]) < 0)  # resists the push, stiffening
    assert r.n_pairs_object[-1] > 0
    # the rigid object translates rigidly
    d = r.object_displacement_mm[-1]
    np.testing.assert_allclose(d, np.broadcast_to(d[0], d.shape), atol=1e-12)


def test_deformable_ring_push_equilibrium(finger):
    c = front_contact_circle(FingerParams(), 30.0, 15.0, gap_mm=0.1).points.mean(axis=0)
    ring = Point(c).buffer(7.5, quad_segs=16).difference(Point(c).buffer(5.5, quad_segs=16))
    mesh, _ = triangulate_polygon(ring, 1.0, 25.0, order=2)
    obj = DeformableObject(mesh, material_from_name("neoprene"), name="ring_neoprene")
    r = simulate(finger, obj, FINGER, SimulationOptions(push_mm=4.0, frame_step_mm=1.0))
    check_frames(r)
    assert r.object_von_mises_MPa is not None and np.nanmax(r.object_von_mises_MPa[-1]) > 0
    # the back half of the bore is driven: it follows the push
    u = r.object_displacement_mm[-1][:, 0]
    p = mesh.points - c
    bore = np.hypot(p[:, 0], p[:, 1]) < 5.5 + 1e-6
    assert np.allclose(u[bore & (p[:, 0] <= 1e-9)], 4.0, atol=0.01)
    # the ring's front, against the finger, lags behind: the ring is squeezed
    front = np.argmax(p[:, 0])
    assert u[front] < 4.0 - 1e-3


def test_failure_names_the_step_and_cause(finger):
    obj = front_contact_circle(FingerParams(), 30.0, 20.0, gap_mm=0.1)
    opts = SimulationOptions(push_mm=2.0, newton=NewtonOptions(max_iterations=1), max_retries=1)
    with pytest.raises(SimulationError) as e:
        simulate(finger, obj, FINGER, opts)
    assert e.value.step >= 1 and "no convergence" in e.value.cause
    assert "load step" in str(e.value) and "mm" in str(e.value)


def test_initial_intersection_is_refused(finger):
    obj = front_contact_circle(FingerParams(), 30.0, 20.0, gap_mm=-1.0)
    with pytest.raises(SimulationError, match="intersects"):
        simulate(finger, obj, FINGER, SimulationOptions(push_mm=1.0))


def test_object_blocked_by_the_clamp_is_reported(finger):
    from finray.fea.benchmarks import circle_polyline
    from finray.fea.simulate import RigidObject

    pts, edges = circle_polyline([-1.15, 0.0], 1.0, 64)  # aims at the clamped corner (0, 0)
    with pytest.raises(SimulationError, match="blocked"):
        simulate(finger, RigidObject(pts, edges), FINGER, SimulationOptions(push_mm=1.0))
