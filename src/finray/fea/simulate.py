"""Fin Ray finger pushed by an object: the simulation entry point (pure compute).

Units: lengths mm, forces N per mm of out-of-plane thickness (``*_N_per_mm``) and
N for the extruded finger (``*_N``, times ``extrusion_mm``), stresses MPa, times s.

:func:`simulate` clamps the finger's ``base`` edges, moves the object by
``push_mm`` along ``direction`` (default +x) in adaptive load steps and records a
frame every ``frame_step_mm`` (frame 0 is the undeformed state). Rigid objects
(:class:`RigidObject`, e.g. steel) are closed polylines that translate rigidly and
are never meshed; deformable ones (:class:`DeformableObject`) are P2 meshes driven
by the back half of their inner loop (a pusher inside the ring, so that the ring
can ovalise against the finger). No file is written here.

Sign conventions: ``force_*`` is the force that the finger exerts *on the object*
(a +x push gives a negative Fx); ``base_reaction_*`` is the force of the clamp on
the finger. At equilibrium they are equal (the finger's free-body balance), and
every solved frame is checked: a relative difference above
``SimulationOptions.equilibrium_tol`` stops the run with a :class:`SimulationError`
naming the frame and the error.
"""

from __future__ import annotations

import logging
import time
from dataclasses import asdict, dataclass, field, replace

import numpy as np

from ..geometry.mesh import BOUNDARY_TAGS, TriMesh
from ..logs import Progress
from .assembly import ElementBlock
from .contact import ContactModel, ContactParams, split_p2_edges
from .material import NeoHookean
from ..errors import SimulationError
from .newton import NewtonOptions, newton
from .problem import Model
from .stepping import StepOptions, march
from ..schema import schema_default

__all__ = [
    "RigidObject",
    "DeformableObject",
    "SimulationOptions",
    "SimulationResult",
    "simulate",
    "boundary_loops",
]

log = logging.getLogger(__name__)
#: mm: the record's first, cheap gap probe (one seventh of the 1 mm probe's cost on a
#: steel scene with self contact)
NEAR_PROBE_MM = 0.1


@dataclass
class RigidObject:
    """Rigid object boundary: ``points`` (K, 2) mm, ``edges`` (E, 2) closed loops."""

    points: np.ndarray
    edges: np.ndarray
    name: str = "rigid"


@dataclass
class DeformableObject:
    """Deformable object: a (P2) mesh and its material.

    ``driven_nodes``: nodes translated rigidly with the push (default: the nodes of
    the inner loop(s) on the back half, away from the finger: ``(p - c) . d <= 0``
    with ``c`` the loop's centroid and ``d`` the push direction. Driving the whole
    inner loop would make a ring's hoop rigid, and only its wall thickness could
    compress: a neoprene ring would push like a steel one).
    ``contact_edges``: boundary edges ``[a, b, mid]`` that can touch the finger
    (default: the outer loop).
    """

    mesh: TriMesh
    material: NeoHookean
    driven_nodes: np.ndarray | None = None
    contact_edges: np.ndarray | None = None
    name: str = "deformable"


@dataclass
class SimulationOptions:
    """Options of :func:`simulate`; the defaults of those that are config keys
    (``fea.*``) are the schema's.

    push_mm, direction : prescribed object translation (mm) and its direction.
    frame_step_mm : a frame every this many mm of push (frame 0 = rest).
    contact : :class:`ContactParams` (dhat mm, kappa MPa, mu, eps_v mm).
    driver_stiffness : penalty (N/mm per mm) pulling the object to its target;
        the object lags its target by force / stiffness (~1e-6 mm).
    initial_step_mm, max_step_mm, min_step_mm, max_retries : load stepping.
    friction_lag_iterations : re-lags of friction within each step's Newton solve,
        each at a converged solution (:class:`StepOptions`; 0: lagged at the step
        start only; 1 makes Fy ~3 % and Fx ~0.6 % more accurate at about 2 more Newton
        iterations per step).
    newton : :class:`NewtonOptions` (tol_dx mm, tol_residual, max_iterations).
    equilibrium_tol : largest ``|force on object - clamp reaction| / max(|force|,
        |reaction|, equilibrium_floor_N_per_mm)`` allowed at a recorded frame.
    equilibrium_floor_N_per_mm : force (N/mm) below which the equilibrium error is
        taken relative to this floor (frames before contact carry no force).
    extrusion_mm : out-of-plane width for the ``*_N`` forces.
    gap_probe_mm : gaps larger than this are reported as NaN.
    self_neighbour_mm : finger self pairs closer than this along the boundary are
        neighbours, not contacts.
    linear_solver : "auto", "cholmod", "cvxopt", "cholespy" or "splu"
        (:class:`~finray.fea.linear.LinearSolver`).
    psd : "auto" (exact Hessian, projected when not positive definite), True, False.
    stress : compute nodal von Mises stresses.
    force_cap_N : a physical limit on the contact force (N, for the extruded finger):
        the push ends at the first load step whose force magnitude reaches it (within
        :attr:`StepOptions.limit_overshoot` above), that state the last frame, and
        ``meta["stop"]`` says so; None: the whole push (default: the config's
        ``fea.force_cap_N``, 40 N).
    log_every_s : a progress line (frame k/n, travel mm, load steps, elapsed s) in the
        ``finray.fea`` log at most this often (s), and at the last frame.
    """

    push_mm: float = schema_default("fea.push_mm")
    direction: tuple = (1.0, 0.0)
    frame_step_mm: float = schema_default("fea.frame_step_mm")
    contact: ContactParams = field(default_factory=ContactParams)
    driver_stiffness: float = 1e5  # N/mm per mm of thickness
    initial_step_mm: float = 0.5
    max_step_mm: float = schema_default("fea.max_step_mm")
    min_step_mm: float = schema_default("fea.min_step_mm")
    max_retries: int = schema_default("fea.max_retries")
    friction_lag_iterations: int = 1
    newton: NewtonOptions = field(default_factory=NewtonOptions)
    equilibrium_tol: float = schema_default("fea.equilibrium_tol")
    equilibrium_floor_N_per_mm: float = 1e-6
    extrusion_mm: float | None = None  # default: finger_mesh.meta["extrusion_mm"] or 20
    gap_probe_mm: float = 1.0  # gaps above this are reported as NaN
    self_neighbour_mm: float = 1.0  # self pairs closer than this along the boundary are ignored
    linear_solver: str = "auto"
    psd: object = "auto"
    stress: bool = True
    log_every_s: float = 30.0
    force_cap_N: float | None = schema_default("fea.force_cap_N")


@dataclass
class SimulationResult:
    """Per-frame arrays (first axis: frame)."""

    displacement_mm: np.ndarray  # (F,) object displacement along the push direction
    target_mm: np.ndarray  # (F,) prescribed displacement
    force_N_per_mm: np.ndarray  # (F, 2) force of the finger on the object
    force_N: np.ndarray  # (F, 2) same, times the extrusion
    base_reaction_N_per_mm: np.ndarray  # (F, 2) force of the clamp on the finger
    base_reaction_N: np.ndarray  # (F, 2)
    friction_force_N_per_mm: np.ndarray  # (F, 2) friction part of force_N_per_mm
    finger_displacement_mm: np.ndarray  # (F, Nf, 2) nodal displacements of the finger
    finger_von_mises_MPa: np.ndarray  # (F, Nf) nodal von Mises Cauchy stress (plane strain)
    object_displacement_mm: np.ndarray  # (F, No, 2) object nodes (polyline vertices if rigid)
    object_von_mises_MPa: np.ndarray | None  # (F, No) deformable objects only
    min_gap_object_mm: np.ndarray  # (F,) NaN above gap_probe_mm
    min_gap_self_mm: np.ndarray  # (F,) finger-finger, points > self_neighbour_mm apart along
    #   the boundary (includes the acute apex of the top cavity, ~0.7 mm at rest)
    n_pairs_object: np.ndarray  # (F,) active barrier pairs finger-object
    n_pairs_self: np.ndarray  # (F,) active barrier pairs finger-finger
    newton_iterations: np.ndarray  # (F,) since the previous frame
    residual_rel: np.ndarray  # (F,) Newton residual of the solve that reached the frame
    equilibrium_rel_error: np.ndarray  # (F,) |force - base reaction| / |force| (see options);
    #   checked from frame 1 (frame 0 is the rest state, not solved: an object placed
    #   within dhat already feels the barrier there)
    load_steps: np.ndarray  # (F,) cumulative
    wall_time_s: np.ndarray  # (F,) since the previous frame
    meta: dict
    #: (F,) mm: height (y) of the centroid of the contact forces on the object, their
    #: magnitudes the weights (the object's nodes at the frame); NaN without contact force
    contact_y_mm: np.ndarray | None = None


def boundary_loops(edges: np.ndarray) -> list[np.ndarray]:
    """Split boundary edges [a, b, ...] into loops; returns lists of edge indices."""
    edges = np.asarray(edges)
    nxt = {int(a): i for i, a in enumerate(edges[:, 0])}
    seen = np.zeros(len(edges), bool)
    loops = []
    for i0 in range(len(edges)):
        if seen[i0]:
            continue
        loop, i = [], i0
        while not seen[i]:
            seen[i] = True
            loop.append(i)
            i = nxt.get(int(edges[i, 1]), i)
        loops.append(np.array(loop))
    return loops


def _signed_area(points, edges):
    a, b = points[edges[:, 0]], points[edges[:, 1]]
    return 0.5 * float((a[:, 0] * b[:, 1] - b[:, 0] * a[:, 1]).sum())


def _deformable_defaults(obj: DeformableObject, direction=(1.0, 0.0)):
    m = obj.mesh
    loops = boundary_loops(m.boundary_edges)
    areas = [abs(_signed_area(m.points, m.boundary_edges[l])) for l in loops]
    outer = int(np.argmax(areas))
    contact = obj.contact_edges if obj.contact_edges is not None else m.boundary_edges[loops[outer]]
    if obj.driven_nodes is not None:
        driven = np.asarray(obj.driven_nodes)
    else:
        inner = [m.boundary_edges[l] for k, l in enumerate(loops) if k != outer]
        if not inner:
            raise ValueError("deformable object without an inner loop: give driven_nodes")
        d = np.asarray(direction, float) / np.linalg.norm(direction)
        driven = []
        for e in inner:
            nodes = np.unique(e[e >= 0])
            c = m.points[nodes].mean(0)
            driven.append(nodes[(m.points[nodes] - c) @ d <= 1e-9])
        driven = np.concatenate(driven)
    return contact, driven


def simulate(
    finger_mesh: TriMesh,
    obj: RigidObject | DeformableObject,
    material: NeoHookean,
    options: SimulationOptions | None = None,
    **kw,
) -> SimulationResult:
    """Push ``obj`` into the clamped finger and record frames.

    ``material``: the finger's elastic law. Keyword arguments override fields of
    ``options`` (e.g. ``push_mm=5``). Raises :class:`SimulationError` (naming the
    load step and the cause) when the solve fails.

    The steps: assemble the finger and the object into one model
    (:func:`_assemble`), record the rest state, march the load steps to every frame
    (:func:`_push`, each frame checked and recorded by :class:`_Frames`), then
    gather the arrays and the run's metadata (:func:`_metadata`).
    """
    t_start = time.perf_counter()
    opts = options or SimulationOptions()
    if kw:
        opts = SimulationOptions(**{**asdict_shallow(opts), **kw})
    scene = _assemble(finger_mesh, obj, material, opts)
    direction = np.asarray(opts.direction, float)
    direction = direction / np.linalg.norm(direction)
    push = float(opts.push_mm)
    extrusion = opts.extrusion_mm or float(finger_mesh.meta.get("extrusion_mm", 20.0))
    frames = _Frames(scene, opts, push, direction)
    stopped = _push(
        scene, frames, opts, push, direction, extrusion, f"FEA {getattr(obj, 'name', 'object')}"
    )
    meta = _metadata(
        scene,
        obj,
        material,
        opts,
        push,
        direction,
        extrusion,
        stopped,
        frames.rec["displacement_mm"][-1],
        t_start,
    )
    return frames.result(opts, extrusion, isinstance(obj, DeformableObject), meta)


@dataclass
class _Scene:
    """The finger and the object as one model: nodes ``[finger..., object...]``
    (``n_finger`` of the finger's), the contact model, the clamped base's and the
    object's nodes as masks."""

    model: Model
    contact: ContactModel
    points: np.ndarray
    n_finger: int
    base_mask: np.ndarray
    obj_nodes: np.ndarray


def _assemble(fm: TriMesh, obj, material: NeoHookean, opts: SimulationOptions) -> _Scene:
    """The model of the clamped finger and the driven object (rigid: a polyline that
    translates; deformable: its mesh, driven by the back of its inner loop); a
    :class:`SimulationError` where the object starts inside the finger."""
    Nf = len(fm.points)
    base_nodes = fm.nodes_with_tag("base")
    finger_edges = fm.boundary_edges[fm.boundary_tags != BOUNDARY_TAGS["base"]]
    blocks = [ElementBlock(fm.triangles, material)]
    if isinstance(obj, RigidObject):
        obj_pts = np.asarray(obj.points, float)
        obj_segs = np.asarray(obj.edges, np.int64)[:, :2] + Nf
        driven = np.arange(Nf, Nf + len(obj_pts))
        rigid = [1]
    elif isinstance(obj, DeformableObject):
        obj_pts = np.asarray(obj.mesh.points, float)
        contact_edges, drv = _deformable_defaults(obj, opts.direction)
        obj_segs = split_p2_edges(contact_edges).astype(np.int64) + Nf
        driven = drv + Nf
        blocks.append(ElementBlock(obj.mesh.triangles + Nf, obj.material))
        rigid = []
    else:
        raise TypeError(f"unsupported object {type(obj).__name__}")
    points = np.vstack([fm.points, obj_pts])
    body = np.r_[np.zeros(Nf, int), np.ones(len(obj_pts), int)]
    segs = np.vstack([split_p2_edges(finger_edges).astype(np.int64), obj_segs])
    cm = ContactModel(points, segs, body, rigid_bodies=rigid, params=opts.contact)
    model = Model(
        points,
        blocks,
        fixed_nodes=base_nodes,
        driven_nodes=driven,
        contact=cm,
        driver_stiffness=opts.driver_stiffness,
        psd=opts.psd,
        linear_solver=opts.linear_solver,
    )
    if cm.has_intersections(np.zeros((len(points), 2))):
        raise SimulationError(
            "the object intersects the finger in the initial state",
            step=0,
            load=0.0,
            cause="initial intersection",
        )
    obj_nodes = np.zeros(len(points), bool)
    obj_nodes[Nf:] = True
    base_mask = np.zeros(len(points), bool)
    base_mask[base_nodes] = True
    return _Scene(model, cm, points, Nf, base_mask, obj_nodes)


class _Frames:
    """The recorded frames: :meth:`record` checks a solved state (finite, in
    equilibrium) and appends its forces, displacements, stresses and contact gaps;
    :meth:`result` makes them a :class:`SimulationResult`."""

    KEYS = (
        "displacement_mm",
        "target_mm",
        "force",
        "base",
        "friction",
        "Uf",
        "vmf",
        "Uo",
        "vmo",
        "gap_obj",
        "gap_self",
        "n_obj",
        "n_self",
        "iters",
        "steps",
        "wall",
        "res",
        "eq",
        "contact_y",
    )

    def __init__(self, scene: _Scene, opts: SimulationOptions, push: float, direction: np.ndarray):
        self.scene, self.opts, self.push, self.direction = scene, opts, push, direction
        self.rec: dict[str, list] = {k: [] for k in self.KEYS}
        # which self pairs are real contacts (not neighbours along the same boundary)
        self.loop_id, self.arc, self.loop_len = scene.contact.boundary_arclength()

    def _self_real(self, v0, v1):
        same = self.loop_id[v0] == self.loop_id[v1]
        ds = np.abs(self.arc[v0] - self.arc[v1])
        ds = np.minimum(ds, self.loop_len[v0] - ds)
        return ~same | (ds > self.opts.self_neighbour_mm)

    def balance(self, q):
        """Force on the object, clamp reaction (N/mm), their relative difference and
        the height (mm) of the object's contact-force centroid (NaN without force)."""
        sc, model = self.scene, self.scene.model
        f_nodes = model.contact_nodal_forces(q, sc.obj_nodes)
        f_obj, f_base = f_nodes.sum(axis=0), model.elastic_force(q, sc.base_mask)
        return (
            f_obj,
            f_base,
            float(
                np.linalg.norm(f_obj - f_base)
                / max(
                    np.linalg.norm(f_obj),
                    np.linalg.norm(f_base),
                    self.opts.equilibrium_floor_N_per_mm,
                )
            ),
            contact_centroid_y(sc.points[sc.n_finger :, 1] + model.U(q)[sc.n_finger :, 1], f_nodes),
        )

    def _equilibrium(self, k, s, q, info):
        """The frame's state (q, or q polished to ``equilibrium_tol``) and its
        :meth:`balance`; a :class:`SimulationError` where it is not finite or not in
        equilibrium."""
        opts, model = self.opts, self.scene.model
        if not np.all(np.isfinite(q)):
            raise SimulationError(
                f"non-finite state at frame {k} (load factor {s:.4f})",
                step=info.get("steps"),
                load=s,
                cause="non-finite state",
            )
        f_obj, f_base, err, y_c = self.balance(q)
        if k > 0 and not err <= opts.equilibrium_tol:  # frame 0: the rest state, not solved
            # the residual test (relative to all loads) passed, yet the object's force
            # and the clamp's reaction differ by more than the tolerance: the same
            # solve, its residual tolerance a tenth, before giving up on the frame
            res = newton(model, q, replace(opts.newton, tol_residual=opts.newton.tol_residual / 10))
            if res.converged:
                q = res.q
                f_obj, f_base, err, y_c = self.balance(q)
                model.counters["equilibrium_polishes"] += 1
            if not err <= opts.equilibrium_tol:
                raise SimulationError(
                    f"frame {k}: equilibrium error {err:.2e} > tolerance "
                    f"{opts.equilibrium_tol:.0e} (|force on object - clamp reaction| / |force|)",
                    step=info.get("steps"),
                    load=s,
                    cause="equilibrium",
                )
        return q, f_obj, f_base, err, y_c

    def _gaps(self, U):
        """Smallest finger-object and finger-finger gaps (mm; NaN beyond the probe) and
        the active barrier pairs of each kind at displacements ``U``."""
        opts, cm = self.opts, self.scene.contact
        # a probe within NEAR_PROBE_MM first: below that distance it has the full
        # probe's pairs, so where both kinds have one there the gaps are the same; the
        # full probe (most of the record's cost) only where a kind has none
        probe = max(opts.gap_probe_mm, opts.contact.dhat)
        for radius in sorted({max(min(NEAR_PROBE_MM, probe), opts.contact.dhat), probe}):
            pr = cm.pairs(U, radius)
            fo = pr["b0"] != pr["b1"]
            fs = (pr["b0"] == 0) & (pr["b1"] == 0) & self._self_real(pr["v0"], pr["v1"])
            if fo.any() and fs.any():
                break
        d = pr["d"]
        act = d < opts.contact.dhat
        return (
            float(d[fo].min()) if fo.any() else np.nan,
            float(d[fs].min()) if fs.any() else np.nan,
            int((fo & act).sum()),
            int((fs & act).sum()),
        )

    def record(self, k, s, q, info):
        """Record frame k at load factor s; returns its state (q, or q polished to
        equilibrium_tol)."""
        rec, opts, model, Nf = self.rec, self.opts, self.scene.model, self.scene.n_finger
        q, f_obj, f_base, err, y_c = self._equilibrium(k, s, q, info)
        U = model.U(q)
        t = model.t(q)
        rec["displacement_mm"].append(float(t @ self.direction))
        rec["target_mm"].append(s * self.push)
        rec["eq"].append(err)
        rec["contact_y"].append(y_c)
        rec["res"].append(info.get("residual_rel", 0.0))
        rec["force"].append(f_obj)
        rec["friction"].append(model.contact_force(q, self.scene.obj_nodes, friction_only=True))
        rec["base"].append(f_base)
        rec["Uf"].append(U[:Nf].copy())
        rec["Uo"].append(U[Nf:].copy())
        if opts.stress:
            st = model.elastic.nodal_stress(U)["von_mises"]
            rec["vmf"].append(st[:Nf])
            rec["vmo"].append(st[Nf:])
        gap_obj, gap_self, n_obj, n_self = self._gaps(U)
        rec["gap_obj"].append(gap_obj)
        rec["gap_self"].append(gap_self)
        rec["n_obj"].append(n_obj)
        rec["n_self"].append(n_self)
        rec["iters"].append(info.get("newton_iterations", 0))
        rec["steps"].append(info.get("steps", 0))
        rec["wall"].append(info.get("wall_time_s", 0.0))
        return q

    def partial(self, extrusion: float) -> dict:
        """The frames recorded whole (a frame that failed its check is not), for a
        :class:`SimulationError`'s ``partial``."""
        n_ok = len(self.rec["force"])
        return {
            "displacement_mm": np.array(self.rec["displacement_mm"][:n_ok]),
            "force_N": np.array(self.rec["force"]).reshape(n_ok, 2) * extrusion,
        }

    def result(
        self, opts: SimulationOptions, extrusion: float, deformable: bool, meta: dict
    ) -> SimulationResult:
        rec = self.rec
        F = np.array(rec["force"])
        B = np.array(rec["base"])
        vmo = np.array(rec["vmo"]) if (opts.stress and deformable) else None
        return SimulationResult(
            displacement_mm=np.array(rec["displacement_mm"]),
            target_mm=np.array(rec["target_mm"]),
            force_N_per_mm=F,
            force_N=F * extrusion,
            base_reaction_N_per_mm=B,
            base_reaction_N=B * extrusion,
            friction_force_N_per_mm=np.array(rec["friction"]),
            finger_displacement_mm=np.array(rec["Uf"]),
            finger_von_mises_MPa=np.array(rec["vmf"]) if opts.stress else None,
            object_displacement_mm=np.array(rec["Uo"]),
            object_von_mises_MPa=vmo,
            min_gap_object_mm=np.array(rec["gap_obj"]),
            min_gap_self_mm=np.array(rec["gap_self"]),
            n_pairs_object=np.array(rec["n_obj"]),
            n_pairs_self=np.array(rec["n_self"]),
            newton_iterations=np.array(rec["iters"]),
            residual_rel=np.array(rec["res"]),
            equilibrium_rel_error=np.array(rec["eq"]),
            load_steps=np.array(rec["steps"]),
            wall_time_s=np.array(rec["wall"]),
            meta=meta,
            contact_y_mm=np.array(rec["contact_y"], float),
        )


def _force_limit(model: Model, opts: SimulationOptions, extrusion: float):
    """``limit(q)`` of :func:`~finray.fea.stepping.march`: the contact force over
    ``force_cap_N`` (None without a cap)."""
    if opts.force_cap_N is None:
        return None
    if not opts.force_cap_N > 0:
        raise ValueError(f"force_cap_N must be > 0 N, got {opts.force_cap_N}")

    def limit(q):
        # the driving spring's force: the object's contact force at equilibrium, free
        return float(np.linalg.norm(model.driver_force(q))) * extrusion / opts.force_cap_N

    return limit


def _push(
    scene: _Scene,
    frames: _Frames,
    opts: SimulationOptions,
    push: float,
    direction: np.ndarray,
    extrusion: float,
    what: str,
) -> bool:
    """Record the rest state, then move the object ``push`` mm in load steps, a frame
    every ``frame_step_mm``; whether the push stopped at ``force_cap_N``. A failed
    step's :class:`SimulationError` is told the displacement and the frames before it."""
    model = scene.model
    n_frames = max(1, int(round(push / opts.frame_step_mm)))
    frames_s = np.linspace(0.0, 1.0, n_frames + 1)
    q0 = np.zeros(model.n)
    model.U_step_start = model.U(q0)
    frames.record(0, 0.0, q0, {})
    log.info(f"{what}: push {push:g} mm in {n_frames} frames, {model.n} DOFs")
    progress = Progress(log, what, n_frames, opts.log_every_s)
    stopped = []

    def on_frame(k, s, q, info):
        if info.get("stop"):
            stopped.append(s)
        q = frames.record(k + 1, s, q, info)
        progress(
            k + 1,
            f"travel {frames.rec['displacement_mm'][-1]:.2f}/{push:g} mm, "
            f"{info.get('steps', 0)} load steps",
        )
        return q

    so = StepOptions(
        initial_step=opts.initial_step_mm / push,
        max_step=opts.max_step_mm / push,
        min_step=opts.min_step_mm / push,
        max_retries=opts.max_retries,
        friction_lag_iterations=opts.friction_lag_iterations,
    )
    limit = _force_limit(model, opts, extrusion)
    try:
        march(
            model,
            q0,
            lambda s: s * push * direction,
            frames_s[1:],
            so,
            opts.newton,
            on_frame=on_frame,
            friction=opts.contact.mu > 0,
            limit=limit,
        )
    except SimulationError as e:
        e.args = (f"{e.args[0]} at object displacement {e.load * push:.4f} mm (push {push} mm)",)
        e.partial = frames.partial(extrusion)
        raise
    return bool(stopped)


def _metadata(
    scene: _Scene,
    obj,
    material: NeoHookean,
    opts: SimulationOptions,
    push: float,
    direction: np.ndarray,
    extrusion: float,
    stopped: bool,
    push_reached_mm: float,
    t_start: float,
) -> dict:
    """``SimulationResult.meta``: the scene's sizes and materials, the options, the
    solver's counters and timings, and why the push ended."""
    model = scene.model
    return {
        "n_finger_nodes": scene.n_finger,
        "n_object_nodes": len(scene.points) - scene.n_finger,
        "n_dofs": model.n,
        "object": getattr(obj, "name", type(obj).__name__),
        "object_kind": "rigid" if isinstance(obj, RigidObject) else "deformable",
        "finger_material": {"name": material.name, "E_MPa": material.E, "nu": material.nu},
        "object_material": (
            None
            if isinstance(obj, RigidObject)
            else {"name": obj.material.name, "E_MPa": obj.material.E, "nu": obj.material.nu}
        ),
        "extrusion_mm": extrusion,
        "push_mm": push,
        "direction": direction.tolist(),
        "contact": asdict(opts.contact),
        "driver_stiffness": opts.driver_stiffness,
        "linear_solver": model.linsolve.backend,
        "cholmod_mode": model.linsolve.mode,
        "n_ldl_fallbacks": model.linsolve.n_ldl_fallbacks,  # "hybrid": LL' failed, LDL'
        "n_factorizations": model.linsolve.n_factorizations,
        # with an earlier factorisation: chord steps, and the load steps' predictions
        "n_chord_solves": model.linsolve.n_resolves - model.counters["predictor_solves"],
        "n_predictor_solves": model.counters["predictor_solves"],
        "n_chord_refused": model.counters["chord_refused"],
        "line_search_failures": model.counters["line_search_failures"],
        "gradient_fallbacks": model.counters["gradient_fallbacks"],
        "equilibrium_polishes": model.counters["equilibrium_polishes"],
        "residual_max_rel": model.counters["residual_max_rel"],
        "residual_tol": opts.newton.tol_residual,
        "equilibrium_tol": opts.equilibrium_tol,
        "n_analyses": model.linsolve.n_analyses,
        "timings_s": {
            **{k: round(v, 4) for k, v in model.stats.items()},
            "factor": round(model.linsolve.time_factor, 4),
            "analyse": round(model.linsolve.time_analyse, 4),
            "total": round(time.perf_counter() - t_start, 4),
        },
        "sign_convention": "force_*: finger on object; base_reaction_*: clamp on finger",
        # "complete": the whole push; "force_cap": ended at force_cap_N (frames kept)
        "stop": {
            "reason": "force_cap" if stopped else "complete",
            "push_reached_mm": float(push_reached_mm),
            "force_cap_N": opts.force_cap_N,
        },
    }


def contact_centroid_y(y_mm: np.ndarray, f_nodes: np.ndarray) -> float:
    """Height (mm) of the centroid of nodal contact forces ``f_nodes`` (n, 2) at node
    heights ``y_mm`` (n,), each weighted by its force's magnitude; NaN where no node
    carries a force."""
    w = np.hypot(f_nodes[:, 0], f_nodes[:, 1])
    total = float(w.sum())
    return float(w @ y_mm) / total if total > 0 else float("nan")


def asdict_shallow(o) -> dict:
    return {f: getattr(o, f) for f in o.__dataclass_fields__}
