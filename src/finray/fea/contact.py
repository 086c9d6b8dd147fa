"""Incremental-potential contact (IPC) with friction, through ``ipctk`` (mm, N, MPa).

The collision mesh is a set of straight segments between nodes of the full node
array (each quadratic boundary edge ``[a, b, mid]`` gives the segments ``a-mid`` and
``mid-b``). Bodies are labelled per node; pairs of nodes that both belong to a
*rigid* body never collide (:func:`ipctk.make_static_obstacle_filter`), every
other pair does, so one finger touches the object *and* itself (rib on rib, rib
on wall). Segments that share a vertex never interact (ipctk).

Barrier: the convergent, area-weighted IPC formulation (Li et al. 2023, "improved
max approximator") with the *physical* barrier scaling, so that the barrier
stiffness ``kappa`` is a pressure (MPa) and results do not depend on the mesh.
The barrier acts below the distance ``dhat`` (mm); no state is ever
interpenetrating because every Newton step is limited by continuous collision
detection (:meth:`ContactModel.max_step`).

Friction: smoothed Coulomb friction with lagged normal forces and tangent bases
(Li et al. 2020), ``mu`` (-) and the slip regularisation ``eps_v`` (mm of slip per
load step below which friction acts as a stiff spring).

Energies are per unit out-of-plane thickness (N mm / mm), gradients are nodal
forces (N/mm), Hessians N/mm^2. All full-size vectors are node-major
``[x0, y0, x1, y1, ...]`` over the full node array.
"""

from __future__ import annotations

from dataclasses import dataclass

import ipctk
import numpy as np

from ..geometry.mesh import split_p2_edges  # noqa: F401  (shared with the fea modules)
from ..schema import schema_default

ipctk.set_logger_level(ipctk.LoggerLevel.error)
# one thread: ipctk's TBB loops add per-thread partial sums (energy, gradient, Hessian,
# collision sets) in a schedule-dependent order, so results drifted ~1e-11 N run to run;
# contact is ~10 % of a scene's time and workflow jobs get one core each anyway.
ipctk.set_num_threads(1)


@dataclass
class ContactParams:
    """Contact constants.

    dhat : barrier activation distance (mm); must be below the smallest rest
        distance between non-adjacent boundary segments (at the finger's fillets:
        0.037 mm with 0.1 mm arc chords, 0.021 mm with 0.05 mm chords).
    kappa : barrier stiffness (MPa, physical barrier); the contact pressure is
        ~4.3 kappa at a gap of dhat/2 and ~21 kappa at dhat/10 (mesh independent).
        The default suits the finger's contact pressures (0.05-1 MPa): the force
        hardly depends on it (Fx at 10 mm changes < 0.1 % from 0.05 to 10 MPa),
        the Newton iteration count does.
    mu : Coulomb friction coefficient (-); 0 disables friction.
    eps_v : slip (mm per load step) below which static friction is regularised.
    self_contact : let bodies touch themselves (rib on rib).
    projection : PSD projection of the contact Hessians, "abs" (eigenvalues made
        absolute, Chen et al. 2024: faster Newton convergence) or "clamp".
    ccd, ccd_max_iterations : narrow-phase continuous collision detection,
        "additive" (Li et al. 2021; default, ~10 % fewer Newton iterations here) or
        "tight_inclusion" (Wang et al. 2021), and its iteration cap (both stay
        conservative when the cap is hit; ipctk's default cap of 1e7 let single
        degenerate queries run for seconds).
    """

    dhat: float = schema_default("fea.dhat_mm")
    kappa: float = schema_default("fea.barrier_stiffness_MPa")
    mu: float = schema_default("fea.friction")
    eps_v: float = schema_default("fea.static_slip_mm")
    self_contact: bool = schema_default("fea.self_contact")
    projection: str = "abs"
    ccd: str = "additive"
    ccd_max_iterations: int = 100_000


def point_segment_distance(p: np.ndarray, a: np.ndarray, b: np.ndarray) -> np.ndarray:
    """Distances (K,) of points p from segments a-b, all (K, 2)."""
    ab = b - a
    t = np.einsum("ki,ki->k", p - a, ab) / np.maximum(np.einsum("ki,ki->k", ab, ab), 1e-300)
    t = np.clip(t, 0.0, 1.0)
    return np.linalg.norm(p - (a + t[:, None] * ab), axis=1)


class ContactModel:
    """Barrier + friction potentials on a collision mesh over the full node array.

    Parameters
    ----------
    rest_points : (N, 2) reference coordinates of all nodes (mm).
    segments : (K, 2) node ids of the collision segments.
    body : (N,) body label of each node (any int).
    rigid_bodies : labels of rigid bodies (their node pairs never collide).
    params : :class:`ContactParams`.
    """

    # mm: broad-phase candidates are reused while no vertex moved more than this from
    # where they were found (0.05 mm: about 45 % less contact CPU on a steel scene)
    CANDIDATE_MARGIN_MM = 0.05
    # fraction of the smallest gap that every collision vertex may move in a step known
    # to be collision free without a CCD (see max_step); below 0.5, so that a tenth of
    # the gap is left
    SAFE_MOVE = 0.45

    def __init__(
        self,
        rest_points: np.ndarray,
        segments: np.ndarray,
        body: np.ndarray,
        rigid_bodies=(),
        params: ContactParams | None = None,
    ):
        self.params = params or ContactParams()
        self.n_full = len(rest_points)
        segments = np.asarray(segments, np.int32)
        # collision vertices in ascending full id, rigid-body vertices last so that
        # make_static_obstacle_filter blocks rigid-rigid pairs
        used = np.unique(segments)
        body = np.asarray(body)
        is_rigid = np.isin(body[used], list(rigid_bodies))
        order = np.concatenate([used[~is_rigid], used[is_rigid]])
        self.full_ids = order  # collision vertex -> full node
        inv = -np.ones(self.n_full, np.int64)
        inv[order] = np.arange(len(order))
        self.seg = inv[segments].astype(np.int32)
        self.rest = np.asarray(rest_points, float)[order]
        self.body = body[order]
        self.n_dynamic = int((~is_rigid).sum())
        self.mesh = ipctk.CollisionMesh(self.rest, self.seg)
        filt = None
        if len(order) > self.n_dynamic:
            filt = ipctk.make_static_obstacle_filter(self.n_dynamic)
        if not self.params.self_contact:
            patches = ipctk.make_vertex_patches_filter(self.body.astype(np.int32))
            filt = patches if filt is None else (filt & patches)
        if filt is not None:
            self.mesh.can_collide = filt
        self.barrier = ipctk.BarrierPotential(self.params.dhat, self.params.kappa, True)
        self.friction = ipctk.FrictionPotential(self.params.eps_v)
        if self.params.ccd == "additive":
            self.ccd = ipctk.AdditiveCCD(self.params.ccd_max_iterations, 0.9)
        else:
            self.ccd = ipctk.TightInclusionCCD(1e-6, self.params.ccd_max_iterations, 0.8)
        # a linear BVH: on a steel scene, CCD 25 % and the 1 mm pair probe 35 % faster
        # than with ipctk's HashGrid
        self.broad_phase = ipctk.LBVH()
        self._cand = None  # (ipctk.Candidates, the vertices they were found at)
        self._last_set = None  # (vertices, their barrier pair set) of the last evaluation
        self._tangential = None
        self._proj = {
            "abs": ipctk.PSDProjectionMethod.ABS,
            "clamp": ipctk.PSDProjectionMethod.CLAMP,
        }[self.params.projection]

    # -- helpers -------------------------------------------------------------------
    def vertices(self, U_full: np.ndarray) -> np.ndarray:
        """Deformed collision vertex positions (nV, 2) from nodal displacements (N, 2)."""
        return np.asfortranarray(self.rest + U_full[self.full_ids])

    def _new_collisions(self, V: np.ndarray, dhat: float | None = None) -> ipctk.NormalCollisions:
        col = ipctk.NormalCollisions()
        col.use_area_weighting = True
        col.collision_set_type = ipctk.NormalCollisions.CollisionSetType.IMPROVED_MAX_APPROX
        if dhat is not None and dhat != self.params.dhat:
            # a probe (pairs(), not the barrier): the same pairs without their weights,
            # which cost a third of the build
            col.use_area_weighting = False
            col.build(self.mesh, V, dhat, 0.0, self.broad_phase)
        else:  # the same pairs as a fresh broad phase, at a fraction of its cost
            col.build(self._candidates(V), self.mesh, V, self.params.dhat, 0.0)
        return col

    def _candidates(self, V: np.ndarray) -> ipctk.Candidates:
        """Broad-phase candidates for pairs within dhat at V: those within dhat + 2
        CANDIDATE_MARGIN_MM where they were found, reused while no vertex has moved
        more than the margin from there (a distance changes by at most twice that),
        else found anew. Line-search trials and Newton iterates stay close."""
        if self._cand is not None:
            cand, V_ref = self._cand
            if (
                V_ref.shape == V.shape
                and np.square(V - V_ref).sum(axis=1).max(initial=0.0) <= self.CANDIDATE_MARGIN_MM**2
            ):
                return cand
        cand = ipctk.Candidates()
        cand.build(
            self.mesh, V, 0.5 * self.params.dhat + self.CANDIDATE_MARGIN_MM, self.broad_phase
        )
        self._cand = (cand, V.copy())
        return cand

    def full_dof_index(self) -> np.ndarray:
        """(2 nV,) full DOF index of each collision DOF."""
        return (2 * self.full_ids[:, None] + np.arange(2)[None, :]).ravel()

    # -- potentials ----------------------------------------------------------------
    def evaluate(
        self,
        U_full: np.ndarray,
        U_step_start: np.ndarray | None = None,
        order: int = 2,
        project: bool = True,
    ):
        """Contact energy, gradient (2 nV,) and Hessian (csc, 2 nV square, PSD-projected).

        Gradient and Hessian are in *collision DOFs* (see :meth:`full_dof_index`).
        ``project``: make each contact Hessian PSD (else the exact Hessian).
        Friction is included when :meth:`update_friction` has built a lagged set;
        its slip is measured from ``U_step_start``.
        """
        V = self.vertices(U_full)
        col = self._new_collisions(V)
        self._last_set = (V, col)
        E = self.barrier(col, self.mesh, V)
        g = H = None
        if order >= 1:
            g = self.barrier.gradient(col, self.mesh, V)
        if order >= 2:
            proj = self._proj if project else ipctk.PSDProjectionMethod.NONE
            H = self.barrier.hessian(col, self.mesh, V, proj)
        if self._tangential is not None and self.params.mu > 0 and U_step_start is not None:
            dV = np.asfortranarray(V - self.vertices(U_step_start))
            E += self.friction(self._tangential, self.mesh, dV)
            if order >= 1:
                g = g + self.friction.gradient(self._tangential, self.mesh, dV)
            if order >= 2:
                H = H + self.friction.hessian(self._tangential, self.mesh, dV, proj)
        return E, g, H

    def energy(self, U_full, U_step_start=None) -> float:
        return self.evaluate(U_full, U_step_start, order=0)[0]

    def update_friction(self, U_lagged: np.ndarray | None) -> None:
        """Lag normal forces and tangent bases at ``U_lagged`` (None: no friction)."""
        if U_lagged is None or self.params.mu <= 0:
            self._tangential = None
            return
        V = self.vertices(U_lagged)
        col = self._new_collisions(V)
        tc = ipctk.TangentialCollisions()
        tc.build(self.mesh, V, col, self.barrier, self.params.mu)
        self._tangential = tc if len(tc) else None

    def friction_gradient(self, U_full: np.ndarray, U_step_start: np.ndarray) -> np.ndarray:
        """Friction force gradient alone (collision DOFs), zero without a lagged set."""
        if self._tangential is None or self.params.mu <= 0:
            return np.zeros(2 * len(self.full_ids))
        dV = np.asfortranarray(self.vertices(U_full) - self.vertices(U_step_start))
        return self.friction.gradient(self._tangential, self.mesh, dV)

    # -- geometry queries ----------------------------------------------------------
    def max_step(self, U0: np.ndarray, U1: np.ndarray) -> float:
        """Largest collision-free fraction of the step U0 -> U1 (conservative CCD).

        A step in which no collision vertex moves more than SAFE_MOVE of the smallest
        gap at U0 is whole without a CCD: a point-segment distance falls by at most the
        point's move plus the larger of its ends' moves, so no gap closes, and the
        additive CCD cuts only a step that collides (to 0.9 of its time of impact). The
        smallest gap is that of the last evaluation's pair set when it was at U0 (pairs
        outside it are at least dhat apart); Newton's chord steps are mostly that small.
        """
        V0, V1 = self.vertices(U0), self.vertices(U1)
        if self._last_set is not None and np.array_equal(self._last_set[0], V0):
            col = self._last_set[1]
            # (ipctk gives the squared distance)
            gap = min(
                self.params.dhat,
                np.sqrt(col.compute_minimum_distance(self.mesh, V0)) if len(col) else np.inf,
            )
            move = np.sqrt(np.square(V1 - V0).sum(axis=1).max(initial=0.0))
            if move < self.SAFE_MOVE * gap:
                return 1.0
        return float(
            ipctk.compute_collision_free_stepsize(
                self.mesh, V0, V1, 0.0, self.broad_phase, self.ccd
            )
        )

    def has_intersections(self, U_full: np.ndarray) -> bool:
        return bool(ipctk.has_intersections(self.mesh, self.vertices(U_full)))

    def pairs(self, U_full: np.ndarray, dhat: float | None = None) -> dict:
        """Close pairs (within ``dhat``, default the barrier's).

        Returns arrays ``b0, b1`` (body labels of the two sides), ``d`` (distance,
        mm), ``v0, v1`` (a collision vertex of each side: the edge's first vertex
        and the point, or the two points).
        """
        V = self.vertices(U_full)
        col = self._new_collisions(V, dhat)
        ev = col.ev_collisions
        vv = col.vv_collisions
        ne, nv = len(ev), len(vv)
        v0 = np.empty(ne + nv, np.int64)
        v1 = np.empty(ne + nv, np.int64)
        d = np.empty(ne + nv)
        if ne:
            ids = np.array([(c.edge_id, c.vertex_id) for c in ev], dtype=np.int64)
            e = self.seg[ids[:, 0]]
            p = ids[:, 1]
            d[:ne] = point_segment_distance(V[p], V[e[:, 0]], V[e[:, 1]])
            v0[:ne] = e[:, 0]
            v1[:ne] = p
        if nv:
            ids = np.array([(c.vertex0_id, c.vertex1_id) for c in vv], dtype=np.int64)
            d[ne:] = np.linalg.norm(V[ids[:, 0]] - V[ids[:, 1]], axis=1)
            v0[ne:] = ids[:, 0]
            v1[ne:] = ids[:, 1]
        return {"b0": self.body[v0], "b1": self.body[v1], "d": d, "v0": v0, "v1": v1}

    def near_vertices(self, U_full: np.ndarray, radius: float) -> np.ndarray:
        """(K, 3) collision vertices of the pairs closer than ``radius`` (mm): an edge's
        two vertices and the point (a vertex pair repeats its second vertex), the
        vertices a barrier or friction Hessian couples once the pair is within dhat."""
        col = self._new_collisions(self.vertices(U_full), radius)
        # (ids by attribute: six times faster than vertex_ids() per collision)
        ev = np.array([(c.edge_id, c.vertex_id) for c in col.ev_collisions], np.int64)
        vv = np.array([(c.vertex0_id, c.vertex1_id) for c in col.vv_collisions], np.int64)
        out = np.empty((len(ev) + len(vv), 3), np.int64)
        if len(ev):
            out[: len(ev), :2] = self.seg[ev[:, 0]]
            out[: len(ev), 2] = ev[:, 1]
        if len(vv):
            out[len(ev) :] = vv[:, [0, 1, 1]]
        return out

    def boundary_arclength(self) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """(loop id, arc length s (mm, rest), loop length) of each collision vertex.

        Loops are the connected chains of segments (closed or open).
        """
        nV = len(self.rest)
        adj = [[] for _ in range(nV)]
        for a, b in self.seg:
            adj[a].append(b)
            adj[b].append(a)
        loop = -np.ones(nV, np.int64)
        s = np.zeros(nV)
        lengths = []
        lid = 0
        # start open chains at their ends, then closed loops anywhere
        starts = [v for v in range(nV) if len(adj[v]) == 1] + list(range(nV))
        for v0 in starts:
            if loop[v0] >= 0:
                continue
            prev, v, acc = -1, v0, 0.0
            while True:
                loop[v] = lid
                s[v] = acc
                nxt = [w for w in adj[v] if w != prev and loop[w] < 0]
                if not nxt:
                    closing = [w for w in adj[v] if w == v0 and prev != v0]
                    if closing and v != v0:
                        acc += float(np.linalg.norm(self.rest[v] - self.rest[v0]))
                    break
                w = nxt[0]
                acc += float(np.linalg.norm(self.rest[w] - self.rest[v]))
                prev, v = v, w
            lengths.append(acc)
            lid += 1
        L = np.asarray(lengths)
        return loop, s, L[loop]
