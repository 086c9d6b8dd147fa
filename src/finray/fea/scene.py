"""One FEA scene from the config to files: inputs, run, ``result.npz``, CSV, JSON, VTU.

Files written into a scene directory (lengths mm, forces N for the extruded finger,
stresses MPa):

- ``result.npz``: the compact result the render stage reads (see
  :mod:`finray.render.result` for the keys); forces are those the object applies to
  the finger (positive along the push), equal and opposite to the force on the
  object and to the clamp's reaction; ``stop_reason`` ("complete", or "force_cap":
  the push ended at ``fea.force_cap_N``, its frames kept) and ``push_reached_mm``;
- ``forces.csv``: ``displacement_mm,fx_N,fy_N`` per frame;
- ``summary.json``: convergence checks (Newton residual, per-frame equilibrium error,
  line-search failures, gradient fallbacks), timings, peak stress, smallest gap,
  contact pairs;
- ``finger.pvd`` + ``vtu/finger_NNNN.vtu`` (and ``object.pvd`` for deformable
  objects): the deformation series with displacement and von Mises stress, for
  ParaView (apply "Warp By Vector" on ``u``).
"""

from __future__ import annotations

import json
import time
import zlib
from pathlib import Path

import numpy as np

from ..geometry.mesh import BOUNDARY_TAGS, TriMesh
from .contact import ContactParams, split_p2_edges
from .material import NeoHookean
from ..errors import SimulationError
from .simulate import DeformableObject, RigidObject, SimulationOptions, SimulationResult, simulate
from .newton import NewtonOptions


def material_law(cfg: dict, name: str) -> NeoHookean:
    """Neo-Hookean law of a deformable material of the config."""
    m = cfg["materials"][name]
    if m["rigid"]:
        raise ValueError(f"material {name} is rigid: it has no elastic law")
    return NeoHookean.from_E_nu(m["youngs_modulus_MPa"], m["poisson_ratio"], name=name)


def simulation_options(cfg: dict) -> SimulationOptions:
    f = cfg["fea"]
    contact = ContactParams(
        dhat=f["dhat_mm"],
        kappa=f["barrier_stiffness_MPa"],
        mu=f["friction"],
        eps_v=f["static_slip_mm"],
        self_contact=f["self_contact"],
    )
    return SimulationOptions(
        push_mm=f["push_mm"],
        frame_step_mm=f["frame_step_mm"],
        contact=contact,
        max_step_mm=f["max_step_mm"],
        initial_step_mm=f["max_step_mm"],
        min_step_mm=f["min_step_mm"],
        max_retries=f["max_retries"],
        newton=NewtonOptions(tol_residual=f["residual_tol"]),
        equilibrium_tol=f["equilibrium_tol"],
        extrusion_mm=cfg["finger"]["extrusion_mm"],
        force_cap_N=f["force_cap_N"],
    )


def scene_object(obj_mesh: TriMesh, material: str, cfg: dict):
    """The solver's object: rigid boundary or deformable mesh in ``material``."""
    name = obj_mesh.meta.get("name", "object")
    if cfg["materials"][material]["rigid"]:
        # only the outer loop can touch the finger (the bore of a ring never does)
        outer = obj_mesh.boundary_edges[obj_mesh.boundary_tags == BOUNDARY_TAGS["object"]]
        segs = split_p2_edges(outer)
        used = np.unique(segs)
        remap = -np.ones(len(obj_mesh.points), np.int64)
        remap[used] = np.arange(len(used))
        return RigidObject(obj_mesh.points[used], remap[segs], name=name)
    return DeformableObject(obj_mesh, material_law(cfg, material), name=name)


def object_segments(obj, result: SimulationResult) -> tuple[np.ndarray, np.ndarray]:
    """Object node positions per frame (F, K, 2) and its boundary segments (E, 2)."""
    if isinstance(obj, RigidObject):
        pts, segs = obj.points, np.asarray(obj.edges)[:, :2]
    else:
        pts = obj.mesh.points
        segs = split_p2_edges(obj.mesh.boundary_edges)
    return pts[None] + result.object_displacement_mm, segs


def write_result_npz(path: Path, finger: TriMesh, obj, result: SimulationResult) -> None:
    """The compact per-scene file of the render stage (forces on the finger, N)."""
    obj_pts, obj_segs = object_segments(obj, result)
    np.savez_compressed(
        path,
        points=finger.points,
        triangles=finger.triangles,
        boundary_edges=finger.boundary_edges,
        boundary_tags=finger.boundary_tags,
        displacement_mm=result.displacement_mm,
        u_mm=result.finger_displacement_mm.astype(np.float32),
        von_mises_MPa=result.finger_von_mises_MPa.astype(np.float32),
        fx_N=-result.force_N[:, 0],
        fy_N=-result.force_N[:, 1],
        object_points_mm=obj_pts.astype(np.float32),
        object_edges=obj_segs,
        n_pairs_self=result.n_pairs_self,
        n_pairs_object=result.n_pairs_object,
        min_gap_self_mm=result.min_gap_self_mm,
        min_gap_object_mm=result.min_gap_object_mm,
        contact_y_mm=result.contact_y_mm,
        stop_reason=np.str_(result.meta["stop"]["reason"]),
        push_reached_mm=result.meta["stop"]["push_reached_mm"],
    )


class _Zlib1:
    """zlib at level 1 for meshio's VTU writer, which compresses at zlib's default (6):
    2.5x faster on these arrays for files ~1 % larger (any level decompresses alike).
    A block met before (the points and cells, the same in every frame of a series) is
    compressed once: two thirds of a frame's bytes."""

    def __init__(self):
        self._seen: dict[bytes, bytes] = {}

    def compress(self, block: bytes) -> bytes:
        out = self._seen.get(block)
        if out is None:
            out = self._seen[block] = zlib.compress(block, 1)
        return out

    decompress = staticmethod(zlib.decompress)


def write_vtu_series(outdir: Path, finger: TriMesh, obj, result: SimulationResult) -> None:
    """ParaView series: reference mesh + displacement ``u`` and ``von_mises_MPa``."""
    import meshio.vtu._vtu as vtu

    saved, vtu.zlib = vtu.zlib, _Zlib1()
    try:
        _write_vtu_series(outdir, finger, obj, result)
    finally:
        vtu.zlib = saved


def _write_vtu_series(outdir: Path, finger: TriMesh, obj, result: SimulationResult) -> None:
    import meshio

    vdir = outdir / "vtu"
    vdir.mkdir(parents=True, exist_ok=True)
    series = {"finger": [], "object": []}
    z = lambda a: np.column_stack([a, np.zeros(len(a))]).astype(np.float32)  # noqa: E731
    cell = "triangle6" if finger.order == 2 else "triangle"
    for k, d in enumerate(result.displacement_mm):
        name = f"finger_{k:04d}.vtu"
        meshio.Mesh(
            z(finger.points),
            [(cell, finger.triangles)],
            point_data={
                "u": z(result.finger_displacement_mm[k]),
                "von_mises_MPa": result.finger_von_mises_MPa[k].astype(np.float32),
            },
        ).write(vdir / name, compression="zlib")
        series["finger"].append((float(d), f"vtu/{name}"))
        if isinstance(obj, DeformableObject):
            name = f"object_{k:04d}.vtu"
            point_data = {"u": z(result.object_displacement_mm[k])}
            if result.object_von_mises_MPa is not None:
                point_data["von_mises_MPa"] = result.object_von_mises_MPa[k].astype(np.float32)
            meshio.Mesh(
                z(obj.mesh.points),
                [(cell, obj.mesh.triangles)],
                point_data=point_data,
            ).write(vdir / name, compression="zlib")
            series["object"].append((float(d), f"vtu/{name}"))
    for body, items in series.items():
        if not items:
            continue
        rows = "\n".join(f'    <DataSet timestep="{t:.6g}" part="0" file="{f}"/>' for t, f in items)
        (outdir / f"{body}.pvd").write_text(
            '<?xml version="1.0"?>\n<VTKFile type="Collection" version="0.1">\n'
            f"  <Collection>\n{rows}\n  </Collection>\n</VTKFile>\n"
        )


def summary(result: SimulationResult, wall_time_s: float, scene: dict) -> dict:
    """Headline numbers of a converged run (forces on the finger, N).

    Checks: ``residual_final_rel`` (the last load step) and ``residual_max_rel`` (all
    load steps) are Newton's free-DOF residual relative to the support forces
    (:meth:`~finray.fea.problem.Model.residual_norm`), each at most ``residual_tol``;
    ``equilibrium_max_rel_error`` is the largest per-frame ``|force on object - clamp
    reaction| / |force|`` of the solved frames (1 on), at most ``equilibrium_tol``; ``line_search_failures`` and
    ``gradient_fallbacks`` count the solver's stalled line searches (including those
    of load steps then cut and retried) and non-descent Newton directions.
    """
    gaps = np.concatenate([result.min_gap_object_mm, result.min_gap_self_mm])
    gaps = gaps[np.isfinite(gaps)]
    m = result.meta
    return {
        **scene,
        "converged": True,
        "stop": m["stop"],
        "wall_time_s": round(wall_time_s, 3),
        "n_frames": int(len(result.displacement_mm)),
        "n_steps": int(result.load_steps[-1]),
        "newton_iterations": int(result.newton_iterations.sum()),
        "max_von_mises_MPa": float(result.finger_von_mises_MPa.max()),
        "min_gap_mm": float(gaps.min()) if len(gaps) else None,
        "self_contact_max_pairs": int(result.n_pairs_self.max()),
        "self_contact_first_mm": (
            float(result.displacement_mm[np.argmax(result.n_pairs_self > 0)])
            if (result.n_pairs_self > 0).any()
            else None
        ),
        "object_contact_max_pairs": int(result.n_pairs_object.max()),
        "fx_final_N": float(-result.force_N[-1, 0]),
        "fy_final_N": float(-result.force_N[-1, 1]),
        "residual_tol": m["residual_tol"],
        "residual_final_rel": float(result.residual_rel[-1]),
        "residual_max_rel": float(m["residual_max_rel"]),
        "equilibrium_tol": m["equilibrium_tol"],
        "equilibrium_max_rel_error": float(result.equilibrium_rel_error[1:].max(initial=0.0)),
        "line_search_failures": int(m["line_search_failures"]),
        "gradient_fallbacks": int(m["gradient_fallbacks"]),
        "solver": m,
    }


def run_scene(
    cfg: dict,
    finger: TriMesh,
    obj_mesh: TriMesh,
    material: str,
    outdir: str | Path,
    scene: dict | None = None,
    vtu: bool = True,
    failure_report: str | Path | None = None,
    shown_dir: str | Path | None = None,
) -> dict:
    """Simulate one scene and write its files.

    A failed solve writes ``summary.json`` with ``converged: false`` and the cause
    into ``outdir`` and, when given, the same report to ``failure_report`` (a path
    that is no output of the workflow rule, so that it survives the failed job), and
    the frames that converged before it to ``partial_forces.csv`` (in ``outdir`` and
    beside the report, ``<report>.partial_forces.csv``), then raises
    :class:`SimulationError` with a one-line message naming the scene.
    A successful run removes a stale ``failure_report``. ``shown_dir``: where
    ``outdir``'s files will be once moved into place (``finray simulate`` writes under a
    temporary name), the folder that the report and the message name.
    """
    outdir = Path(outdir)
    outdir.mkdir(parents=True, exist_ok=True)
    scene = dict(scene or {})
    name = scene.get("scene", "?")
    obj = scene_object(obj_mesh, material, cfg)
    t0 = time.perf_counter()

    def fail(exc: SimulationError) -> SimulationError:
        msg = f"scene {name}: {exc}"
        report = {
            **scene,
            "converged": False,
            "wall_time_s": round(time.perf_counter() - t0, 3),
            "error": msg,
            "cause": exc.cause,
            "failed_step": exc.step,
            "load_factor": exc.load,
            "frames_converged": 0,
        }
        homes = [outdir] + ([Path(failure_report).parent] if failure_report is not None else [])
        for home in homes:
            home.mkdir(parents=True, exist_ok=True)
        part = exc.partial
        if part is not None and len(part["displacement_mm"]) > 1:
            # the frames that converged (and the rest frame) kept beside the reason: the
            # force on the finger (N), as forces.csv; beside the failure report too,
            # which outlives a failed workflow job
            n = report["frames_converged"] = int(len(part["displacement_mm"]) - 1)
            rows = np.column_stack([part["displacement_mm"], -part["force_N"]])
            paths = [outdir / "partial_forces.csv"] + (
                [Path(failure_report).with_suffix(".partial_forces.csv")] if failure_report else []
            )
            for path in paths:
                np.savetxt(
                    path,
                    rows,
                    delimiter=",",
                    header="displacement_mm,fx_N,fy_N",
                    comments="",
                    fmt="%.8g",
                )
            shown = paths[-1]
            if failure_report is None and shown_dir is not None:
                shown = Path(shown_dir) / shown.name
            report["partial_forces"] = str(shown)
            msg = report["error"] = f"{msg}; the {n} frames that converged are in {shown}"
        text = json.dumps(report, indent=2)
        (outdir / "summary.json").write_text(text)
        if failure_report is not None:
            Path(failure_report).write_text(text)
        return SimulationError(msg, step=exc.step, load=exc.load, cause=exc.cause, partial=part)

    try:
        res = simulate(
            finger, obj, material_law(cfg, cfg["finger"]["material"]), simulation_options(cfg)
        )
    except SimulationError as exc:
        raise fail(exc) from None
    wall = time.perf_counter() - t0
    for what, arr in (
        ("displacement", res.finger_displacement_mm),
        ("force", res.force_N),
        ("stress", res.finger_von_mises_MPa),
    ):
        if not np.isfinite(arr).all():
            raise fail(
                SimulationError(f"non-finite {what} in the result", cause="non-finite result")
            )
    if failure_report is not None:
        Path(failure_report).unlink(missing_ok=True)
    write_result_npz(outdir / "result.npz", finger, obj, res)
    np.savetxt(
        outdir / "forces.csv",
        np.column_stack([res.displacement_mm, -res.force_N]),
        delimiter=",",
        header="displacement_mm,fx_N,fy_N",
        comments="",
        fmt="%.8g",
    )
    if vtu:
        write_vtu_series(outdir, finger, obj, res)
    out = summary(res, wall, scene)
    (outdir / "summary.json").write_text(json.dumps(out, indent=2))
    return out


def scene_job(
    cfg: dict,
    finger_npz,
    object_npz,
    material: str,
    outdir: str | Path,
    scene: dict,
    log: str | Path,
    vtu: bool = True,
    failure_report: str | Path | None = None,
) -> str | None:
    """A workflow job's scene (:func:`run_scene` on the meshes' files), its output sent to
    ``log``. Returns None, or the one line a failed scene ends the job with (the report
    at ``failure_report`` outlives the job: Snakemake deletes a failed job's outputs)."""
    from ..logs import log_to

    with log_to(log):
        try:
            out = run_scene(
                cfg,
                TriMesh.load(finger_npz),
                TriMesh.load(object_npz),
                material,
                outdir,
                scene=scene,
                vtu=vtu,
                failure_report=failure_report,
            )
            print({k: v for k, v in out.items() if k != "solver"})
        except SimulationError as e:
            failed = f"{e} (report: {failure_report})"
            print(failed)
            return failed
    return None


def rigid_object_cfg(fea: dict, finger: dict, finger_material: dict) -> dict:
    """A scene config whose object is rigid (material ``"rigid"``): a printed PLA object
    or a steel one against the TPU finger."""
    return {
        "fea": fea,
        "finger": finger,
        "materials": {"rigid": {"rigid": True}, finger["material"]: finger_material},
    }
