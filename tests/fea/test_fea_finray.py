"""The Fin Ray scene: equilibrium, no interpenetration, failures reported by step."""

import os
from dataclasses import replace
import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest
from shapely.geometry import Point

import finray
from finray.config import default_config_path, load_config
from finray.fea.scene import material_law
from finray.fea.simulate import (
    DeformableObject,
    SimulationError,
    SimulationOptions,
    simulate,
)
from finray.fea.newton import NewtonOptions
from finray.geometry.finger import FingerParams, mesh_finger
from finray.geometry.mesh import triangulate_polygon
from helpers import circle_polyline, front_contact_circle

pytestmark = pytest.mark.slow  # not in `pytest -m "not slow"`

CONFIG = load_config(default_config_path())  # the material constants
FINGER = material_law(CONFIG, "ninjaflex")


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
    r = simulate(
        finger, obj, FINGER, SimulationOptions(frame_step_mm=1.0, friction_lag_iterations=1)
    )
    assert len(r.displacement_mm) == 11
    np.testing.assert_allclose(r.displacement_mm, r.target_mm, atol=1e-3)
    check_frames(r)
    fx = r.force_N_per_mm[:, 0]
    assert fx[-1] < 0 and np.all(np.diff(fx[1:]) < 0)  # resists the push, stiffening
    assert r.n_pairs_object[-1] > 0
    # the rigid object translates rigidly
    d = r.object_displacement_mm[-1]
    np.testing.assert_allclose(d, np.broadcast_to(d[0], d.shape), atol=1e-12)


def test_contact_height_is_where_the_circle_presses(finger):
    """The centroid of the contact forces of a circle pressed at height h lies at h:
    the face deflects about the clamped base, so over a 2 mm push it moves by less
    than half the 1 mm boundary element (the nodes sample the contact patch at that
    spacing); NaN at rest (0.1 mm gap, beyond the 0.02 mm barrier)."""
    obj = front_contact_circle(FingerParams(), 30.0, 10.0, gap_mm=0.1)
    r = simulate(finger, obj, FINGER, SimulationOptions(push_mm=2.0, frame_step_mm=1.0))
    assert r.contact_y_mm.shape == (3,) and np.isnan(r.contact_y_mm[0])
    np.testing.assert_allclose(r.contact_y_mm[1:], 30.0, atol=0.5)


def test_push_stops_at_the_force_cap_and_keeps_its_frames(finger):
    """A cap the push reaches ends it at the first load step at the cap (at most 5 %
    above: steps past it are cut), that state the last frame, the frames before kept
    as without a cap; a cap it never reaches changes no array."""
    obj = front_contact_circle(FingerParams(), 30.0, 10.0, gap_mm=0.1)
    opts = SimulationOptions(push_mm=4.0, frame_step_mm=1.0, force_cap_N=None)  # no cap
    free = simulate(finger, obj, FINGER, opts)
    mag = np.hypot(*free.force_N.T)
    cap = 0.5 * (mag[2] + mag[3])  # between the frames at 2 and 3 mm
    r = simulate(finger, obj, FINGER, replace(opts, force_cap_N=cap))
    assert r.meta["stop"]["reason"] == "force_cap"
    assert free.meta["stop"] == {
        "reason": "complete",
        "push_reached_mm": free.displacement_mm[-1],
        "force_cap_N": None,
    }
    assert len(r.displacement_mm) == 4 and 2.0 < r.displacement_mm[-1] < 3.0
    assert r.meta["stop"]["push_reached_mm"] == r.displacement_mm[-1]
    assert cap <= np.hypot(*r.force_N[-1]) <= 1.05 * cap
    np.testing.assert_array_equal(r.force_N[:3], free.force_N[:3])
    check_frames(r)
    same = simulate(finger, obj, FINGER, replace(opts, force_cap_N=10 * mag.max()))
    assert same.meta["stop"]["reason"] == "complete"
    for k in ("force_N", "finger_displacement_mm", "finger_von_mises_MPa", "contact_y_mm"):
        np.testing.assert_array_equal(getattr(same, k), getattr(free, k))


def test_frame_short_of_equilibrium_tolerance_is_solved_again(finger):
    """A frame whose force and clamp reaction differ by more than equilibrium_tol after
    the Newton tolerance is met is solved again to a tenth of that tolerance, not
    failed: every frame then within the tolerance, the forces as before."""
    obj = front_contact_circle(FingerParams(), 30.0, 20.0, gap_mm=0.1)
    opts = SimulationOptions(frame_step_mm=1.0, friction_lag_iterations=1)
    r0 = simulate(finger, obj, FINGER, opts)
    assert r0.meta["equilibrium_polishes"] == 0
    tol = 0.5 * r0.equilibrium_rel_error[1:].max()  # the worst frame now fails the first test
    r = simulate(
        finger,
        obj,
        FINGER,
        SimulationOptions(frame_step_mm=1.0, friction_lag_iterations=1, equilibrium_tol=tol),
    )
    assert r.meta["equilibrium_polishes"] >= 1
    assert r.equilibrium_rel_error[1:].max() <= tol
    fx0 = np.abs(r0.force_N[:, 0]).max()
    np.testing.assert_allclose(r.force_N, r0.force_N, atol=5e-3 * fx0)


def test_deformable_ring_push_equilibrium(finger):
    c = front_contact_circle(FingerParams(), 30.0, 15.0, gap_mm=0.1).points.mean(axis=0)
    ring = Point(c).buffer(7.5, quad_segs=16).difference(Point(c).buffer(5.5, quad_segs=16))
    mesh, _ = triangulate_polygon(ring, 1.0, 25.0, order=2)
    obj = DeformableObject(mesh, material_law(CONFIG, "neoprene"), name="ring_neoprene")
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
    from finray.fea.simulate import RigidObject

    pts, edges = circle_polyline([-1.15, 0.0], 1.0, 64)  # aims at the clamped corner (0, 0)
    with pytest.raises(SimulationError, match="blocked"):
        simulate(finger, RigidObject(pts, edges), FINGER, SimulationOptions(push_mm=1.0))


@pytest.fixture(scope="module")
def scene_inputs():
    """Smoke config pushing 1 mm, its finger (1 mm mesh) and a placed steel circle."""
    from finray.config import load_config

    from helpers import ROOT
    from finray.benchmarks.fea import with_overrides
    from finray.geometry.objects import object_geometry

    cfg = load_config(ROOT / "config" / "smoke.yaml")
    cfg = with_overrides(cfg, {"fea.push_mm": 1.0, "fea.write_vtu": False})
    fp, m = FingerParams.from_config(cfg["finger"]), cfg["mesh"]
    finger = mesh_finger(fp, m["size_mm"], m["min_angle_deg"], m["order"], m["arc_chord_mm"])
    obj = object_geometry(
        "circle_d20",
        {"type": "circle", "diameter_mm": 20.0},
        fp,
        30.0,
        size_mm=m["size_mm"],
        gap_mm=cfg["placement"]["gap_mm"],
    )
    return cfg, finger, obj


def test_scene_summary_carries_the_convergence_checks(scene_inputs, tmp_path):
    import json

    from finray.fea.scene import run_scene

    cfg, finger, obj = scene_inputs
    report = tmp_path / "failed" / "c20.json"
    report.parent.mkdir()
    report.write_text("{}")  # a stale report of an earlier failure
    out = run_scene(
        cfg,
        finger,
        obj,
        "steel",
        tmp_path / "scene",
        {"scene": "c20"},
        vtu=False,
        failure_report=report,
    )
    s = json.loads((tmp_path / "scene" / "summary.json").read_text())
    assert s == json.loads(json.dumps(out))
    assert s["residual_tol"] == cfg["fea"]["residual_tol"]
    assert s["equilibrium_tol"] == cfg["fea"]["equilibrium_tol"]
    assert 0 <= s["residual_final_rel"] <= s["residual_max_rel"] <= s["residual_tol"]
    assert 0 <= s["equilibrium_max_rel_error"] <= s["equilibrium_tol"]
    assert s["fx_final_N"] > 0  # the object touched: the checks saw a load
    for k in ("line_search_failures", "gradient_fallbacks"):
        assert isinstance(s[k], int) and s[k] >= 0
    assert not report.exists()  # success removes the stale failure report


def test_equilibrium_check_fails_the_scene_and_leaves_a_report(scene_inputs, tmp_path):
    import json

    from finray.fea.scene import run_scene
    from finray.benchmarks.fea import with_overrides

    cfg, finger, obj = scene_inputs
    cfg = with_overrides(cfg, {"fea.equilibrium_tol": 1e-300})  # no frame can pass
    report = tmp_path / "failed" / "c20.json"
    with pytest.raises(SimulationError) as e:
        run_scene(
            cfg,
            finger,
            obj,
            "steel",
            tmp_path / "scene",
            {"scene": "c20"},
            vtu=False,
            failure_report=report,
        )
    msg = str(e.value)
    assert "\n" not in msg and msg.startswith("scene c20: frame ")
    assert "equilibrium error" in msg and "> tolerance 1e-300" in msg
    r = json.loads(report.read_text())
    assert r["converged"] is False and r["error"] == msg and r["cause"] == "equilibrium"


def test_scene_job_ends_a_failed_scene_with_one_line_and_logs_both_outcomes(scene_inputs, tmp_path):
    """The workflow scripts' job wrapper: a failure is returned as the job's one line
    (naming the report that outlives the job), a success returns None; both are logged."""
    import json

    from finray.benchmarks.fea import with_overrides
    from finray.fea.scene import rigid_object_cfg, scene_job

    cfg, finger, obj = scene_inputs
    finger.save(tmp_path / "finger.npz")
    obj.save(tmp_path / "object.npz")
    args = (tmp_path / "finger.npz", tmp_path / "object.npz", "steel")
    report = tmp_path / "failed" / "c20.json"
    bad = with_overrides(cfg, {"fea.equilibrium_tol": 1e-300})
    failed = scene_job(
        bad,
        *args,
        tmp_path / "bad",
        {"scene": "c20"},
        tmp_path / "bad.log",
        vtu=False,
        failure_report=report,
    )
    assert failed is not None and "\n" not in failed
    assert failed.startswith("scene c20: frame ") and failed.endswith(f"(report: {report})")
    assert json.loads(report.read_text())["converged"] is False
    assert failed in (tmp_path / "bad.log").read_text()
    assert (
        scene_job(
            cfg,
            *args,
            tmp_path / "ok",
            {"scene": "c20"},
            tmp_path / "ok.log",
            vtu=False,
            failure_report=report,
        )
        is None
    )
    assert not report.exists()
    assert "'converged': True" in (tmp_path / "ok.log").read_text()
    rigid = rigid_object_cfg(cfg["fea"], cfg["finger"], cfg["materials"][cfg["finger"]["material"]])
    assert rigid["materials"]["rigid"] == {"rigid": True}
    assert (
        rigid["materials"][cfg["finger"]["material"]] == cfg["materials"][cfg["finger"]["material"]]
    )


SCENE = """
import sys, numpy as np
from finray.config import default_config_path, load_config
from finray.fea.scene import material_law
from finray.fea.simulate import SimulationOptions, simulate
from finray.geometry.finger import FingerParams, mesh_finger
from helpers import front_contact_circle
law = material_law(load_config(default_config_path()), "ninjaflex")
r = simulate(mesh_finger(FingerParams(), size_mm=2.0, arc_chord_mm=0.25),
             front_contact_circle(FingerParams(), 30.0, 20.0, gap_mm=0.1), law,
             SimulationOptions(push_mm=2.0, frame_step_mm=1.0))
np.savez(sys.argv[1], F=r.force_N_per_mm, B=r.base_reaction_N_per_mm,
         u=r.finger_displacement_mm, s=r.finger_von_mises_MPa, n=r.n_pairs_object,
         g=r.min_gap_object_mm)
"""


def test_scene_is_bit_reproducible_across_processes(tmp_path):
    """Two processes solving the same scene write bit-identical arrays."""
    env = {
        **os.environ,
        "PYTHONPATH": os.pathsep.join(
            [
                str(Path(finray.__file__).parents[1]),
                str(Path(__file__).resolve().parents[1]),  # tests/, for helpers
                os.environ.get("PYTHONPATH", ""),
            ]
        ),
    }
    out = [tmp_path / f"run{i}.npz" for i in range(2)]
    for f in out:
        subprocess.run([sys.executable, "-c", SCENE, str(f)], check=True, env=env)
    a, b = np.load(out[0]), np.load(out[1])
    assert a["n"][-1] > 0  # in contact
    for k in a.files:
        assert np.array_equal(a[k], b[k], equal_nan=True), k


def test_chord_steps_keep_the_forces_with_fewer_factorisations(finger):
    """Reusing the last factorisation near the solution (chord steps, also right after the
    friction re-lag) ends at the same equilibrium as full Newton, to the Newton tolerance,
    with fewer factorisations; every chord solve is counted."""
    obj = front_contact_circle(FingerParams(), 30.0, 10.0)
    runs = {}
    for chord in (0.0, 1e-2):
        runs[chord] = simulate(
            finger,
            obj,
            FINGER,
            SimulationOptions(push_mm=3.0, newton=NewtonOptions(chord_dx=chord)),
        )
    full, chord = runs[0.0], runs[1e-2]
    assert full.meta["n_chord_solves"] == 0 < chord.meta["n_chord_solves"]
    assert chord.meta["n_factorizations"] < full.meta["n_factorizations"]
    assert abs(full.force_N[-1, 0]) > 0.1
    # both to the Newton tolerance (residual 1e-3 of the force scale)
    np.testing.assert_allclose(
        chord.force_N, full.force_N, rtol=0, atol=1e-3 * np.abs(full.force_N).max()
    )
    check_frames(chord)


def test_a_failed_scene_keeps_the_frames_that_converged(scene_inputs, tmp_path, monkeypatch):
    """The solver stops at its third frame: the two that converged (and the rest frame)
    are written beside the one-line reason, marked as such, in the scene's folder and
    beside the failure report (which outlives a failed workflow job)."""
    import importlib
    import json

    from finray.fea.scene import run_scene

    sim = importlib.import_module(
        "finray.fea.simulate"
    )  # (finray.fea.simulate is also the function)

    real = sim.march

    def march_then_fail(model, q, targets, frames, *a, on_frame=None, **k):
        def stop_at_third(i, s, q_, info):
            if i == 2:
                raise SimulationError("made to fail", step=7, load=float(s), cause="test")
            on_frame(i, s, q_, info)

        return real(model, q, targets, frames, *a, on_frame=stop_at_third, **k)

    monkeypatch.setattr(sim, "march", march_then_fail)
    from finray.benchmarks.fea import with_overrides

    cfg, finger, obj = scene_inputs
    cfg = with_overrides(cfg, {"fea.push_mm": 1.5})  # three frames: two converge
    report = tmp_path / "failed" / "c20.json"
    with pytest.raises(SimulationError) as e:
        run_scene(
            cfg,
            finger,
            obj,
            "steel",
            tmp_path / "scene",
            {"scene": "c20"},
            vtu=False,
            failure_report=report,
        )
    partial = tmp_path / "failed" / "c20.partial_forces.csv"
    msg = str(e.value)
    assert "\n" not in msg and msg.startswith("scene c20: made to fail at object displacement ")
    assert msg.endswith(f"; the 2 frames that converged are in {partial}")
    r = json.loads(report.read_text())
    assert r == json.loads((tmp_path / "scene" / "summary.json").read_text())
    assert (
        r["converged"] is False
        and r["frames_converged"] == 2
        and r["partial_forces"] == str(partial)
    )
    for f in (partial, tmp_path / "scene" / "partial_forces.csv"):
        t = np.loadtxt(f, delimiter=",", skiprows=1)
        assert t.shape == (3, 3) and t[0].tolist() == [0.0, 0.0, 0.0]  # the rest frame, then two
        assert np.all(np.diff(t[:, 0]) > 0)
    assert not (tmp_path / "scene" / "forces.csv").exists()  # no result passes for a whole one
