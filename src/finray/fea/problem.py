"""The discrete problem of a load step: elastic bodies, contact and a driven node set.

Units: mm, N, MPa; energies per unit out-of-plane thickness (N mm / mm), forces
N/mm. The total potential of a load step is minimised over the reduced unknowns ``q``::

    Pi(q) = E_elastic(U) + B_barrier(U) + D_friction(U - U_step_start)
            + k/2 |t - t_target|^2 - s f_ext . U

``t`` (2 unknowns) is the rigid translation of the *driven* nodes (the rigid
object, or the inner loop of a deformable ring): it is pulled to its target by a
stiff penalty spring ``k`` (as the IPC paper enforces moving boundary
conditions), so that every step of the solve is a line search on one energy and
the object never enters the finger. The force the finger exerts on the object is
``k (t - t_target)``, equal to ``-d(B + D)/dt`` at equilibrium.
"""

from __future__ import annotations

import time

import numpy as np
import scipy.sparse as sp

from .assembly import ElasticAssembler, ElementBlock
from .contact import ContactModel
from .linear import LinearSolver, SplitMatrix


class Model:
    """Elastic bodies + contact + a rigidly driven node set, on reduced unknowns.

    Parameters
    ----------
    points : (N, 2) reference coordinates (mm) of every node (finger, deformable
        objects, rigid object vertices).
    blocks : elastic element blocks (global node ids).
    fixed_nodes : nodes with prescribed displacement (``prescribed``, default 0).
    driven_nodes : nodes that translate rigidly with ``t`` (may be empty).
    contact : :class:`ContactModel` over the same node array, or None.
    driver_stiffness : penalty k (N/mm per mm thickness) pulling t to its target.
    external_force : (N, 2) nodal forces (N/mm) applied with the load factor.
    psd : "auto" (default): exact Hessian first; when its factorisation fails,
        material tangents projected to PSD per Gauss point and contact Hessians
        per contact; True: always projected; False: never.
    """

    #: mm beyond dhat: contact pairs this close get their Hessian entries in the linear
    #: solver's analysed pattern whenever it is analysed anew
    #: (0.1 mm: 13 analyses instead of 36 on a steel scene, for a little more fill-in)
    PATTERN_MARGIN_MM = 0.1

    def __init__(
        self,
        points,
        blocks: list[ElementBlock],
        fixed_nodes=(),
        driven_nodes=(),
        contact: ContactModel | None = None,
        driver_stiffness: float = 1e5,
        external_force: np.ndarray | None = None,
        psd="auto",
        quad_degree: int | None = None,
        linear_solver: str = "auto",
    ):
        self.points = np.asarray(points, float)
        N = len(self.points)
        self.N = N
        fixed = np.zeros(N, bool)
        fixed[np.asarray(fixed_nodes, int)] = True
        driven = np.zeros(N, bool)
        driven[np.asarray(driven_nodes, int)] = True
        if (fixed & driven).any():
            raise ValueError("a node cannot be both fixed and driven")
        in_elem = np.zeros(N, bool)
        for b in blocks:
            in_elem[b.triangles.ravel()] = True
        # nodes that belong to no element and are not driven are static
        fixed |= ~in_elem & ~driven
        free = ~fixed & ~driven
        dof_map = -np.ones((N, 2), np.int64)
        n_free = int(free.sum())
        dof_map[free] = np.arange(2 * n_free).reshape(-1, 2)
        self.has_driver = bool(driven.any())
        if self.has_driver:
            dof_map[driven] = [2 * n_free, 2 * n_free + 1]
        self.n_free_dofs = 2 * n_free
        self.n = 2 * n_free + (2 if self.has_driver else 0)
        self.t_index = np.array([2 * n_free, 2 * n_free + 1]) if self.has_driver else None
        self.dof_map = dof_map
        # the node DOFs that are unknowns (flat index) and their reduced index
        self._unknown = np.flatnonzero(dof_map.reshape(-1) >= 0)
        self._unknown_dof = dof_map.reshape(-1)[self._unknown]
        self.fixed = fixed
        self.driven = driven
        self.free = free
        self.U_presc = np.zeros((N, 2))
        self.k_drive = float(driver_stiffness)
        self.f_ext = (
            np.zeros((N, 2)) if external_force is None else np.asarray(external_force, float)
        )
        self.psd = psd
        self.elastic = ElasticAssembler(self.points, blocks, dof_map, self.n, quad_degree)
        self.contact = contact
        if contact is not None:
            self.coll_red = dof_map.reshape(-1)[contact.full_dof_index()]
            self.coll_full = contact.full_dof_index()
        self.linsolve = LinearSolver(linear_solver)
        # load-step context
        self.t_target = np.zeros(2)
        self.load = 0.0
        self.U_step_start: np.ndarray | None = None
        self.stats = {
            "assembly_s": 0.0,
            "contact_s": 0.0,
            "solve_s": 0.0,
            "ccd_s": 0.0,
            "line_search_s": 0.0,
        }
        # per model (scene): backtracking that found no decrease, non-descent Newton
        # directions replaced by scaled gradient descent, the largest relative
        # residual of a converged solve, chord steps refused (a Hessian assembled and
        # factorised instead), and load-step predictions solved with the last
        # factorisation (stepping's "tangent" predictor), and frames solved again to a
        # tenth of the residual tolerance to meet the equilibrium tolerance (simulate)
        self.counters = {
            "line_search_failures": 0,
            "gradient_fallbacks": 0,
            "residual_max_rel": 0.0,
            "chord_refused": 0,
            "predictor_solves": 0,
            "equilibrium_polishes": 0,
        }
        self._fixed_dofs = np.flatnonzero(np.repeat(fixed, 2))
        self.force_scale = 0.0  # N/mm, set by evaluate() (see residual_norm)

    # -- state mapping -------------------------------------------------------------
    def U(self, q: np.ndarray) -> np.ndarray:
        """Nodal displacements (N, 2) of the reduced vector q."""
        U = self.U_presc.copy()
        U.reshape(-1)[self._unknown] = q[self._unknown_dof]
        return U

    def t(self, q: np.ndarray) -> np.ndarray:
        return q[self.t_index] if self.has_driver else np.zeros(2)

    # -- energy --------------------------------------------------------------------
    def energy(self, q: np.ndarray) -> float:
        U = self.U(q)
        E = self.elastic.energy(U)
        if not np.isfinite(E):
            return np.inf
        if self.contact is not None:
            E += self.contact.energy(U, self.U_step_start)
        E += self._driver_energy(q) - self.load * float((self.f_ext * U).sum())
        return E

    def _driver_energy(self, q):
        if not self.has_driver:
            return 0.0
        dt = self.t(q) - self.t_target
        return 0.5 * self.k_drive * float(dt @ dt)

    def evaluate(self, q: np.ndarray, order: int = 2, psd: bool | None = None):
        """(E, g, H): energy, reduced gradient, reduced Hessian at q (a
        :class:`SplitMatrix`: elasticity on its fixed pattern + contact and driver).

        ``psd``: project the material tangents and the contact Hessians to PSD
        (default: the model's ``psd`` setting; with "auto" the exact Hessian is
        tried first and projected only when its factorisation fails).
        """
        U = self.U(q)
        if psd is None:
            psd = self.psd is True
        t0 = time.perf_counter()
        E, g_full, Hdata = self.elastic.evaluate(U, order, psd=psd)
        self.stats["assembly_s"] += time.perf_counter() - t0
        if not np.isfinite(E):
            return np.inf, None, None
        g_full = g_full - self.load * self.f_ext.reshape(-1)
        E -= self.load * float((self.f_ext * U).sum())
        extra_r, extra_c, extra_v = [], [], []
        if self.contact is not None:
            t0 = time.perf_counter()
            Ec, gc, Hc = self.contact.evaluate(U, self.U_step_start, order, project=psd)
            E += Ec
            g_full = g_full.copy()
            g_full[self.coll_full] += gc
            if order >= 2 and Hc.nnz:
                Hc = Hc.tocoo()
                r = self.coll_red[Hc.row]
                c = self.coll_red[Hc.col]
                keep = (r >= 0) & (c >= 0)
                extra_r.append(r[keep])
                extra_c.append(c[keep])
                extra_v.append(Hc.data[keep])
            self.stats["contact_s"] += time.perf_counter() - t0
        g = self.elastic.reduce_gradient(g_full)
        # support reactions (fixed DOFs) and applied loads: the force scale of the residual
        scale2 = float(g_full[self._fixed_dofs] @ g_full[self._fixed_dofs])
        if self.load:
            scale2 += self.load**2 * float((self.f_ext * self.f_ext).sum())
        if self.has_driver:
            dt = self.t(q) - self.t_target
            E += 0.5 * self.k_drive * float(dt @ dt)
            g[self.t_index] += self.k_drive * dt
            scale2 += self.k_drive**2 * float(dt @ dt)
            extra_r.append(self.t_index)
            extra_c.append(self.t_index)
            extra_v.append(np.full(2, self.k_drive))
        self.force_scale = float(np.sqrt(scale2))
        if order < 2:
            return E, g, None
        C = None
        if extra_r:
            C = sp.coo_matrix(
                (np.concatenate(extra_v), (np.concatenate(extra_r), np.concatenate(extra_c))),
                shape=(self.n, self.n),
            )
        margin = None
        if self.contact is not None:
            margin = lambda: self._contact_pattern(U)  # noqa: E731 - only on a re-analysis
        return E, g, SplitMatrix(self.elastic.pattern.matrix(Hdata), C, margin)

    def _contact_pattern(self, U: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """(rows, cols) of the reduced Hessian entries of the contact pairs closer than
        dhat + PATTERN_MARGIN_MM at U: a re-analysis of the linear solver's pattern
        includes them, so that pairs forming over the next iterations find their
        entries there."""
        tri = self.contact.near_vertices(U, self.contact.params.dhat + self.PATTERN_MARGIN_MM)
        dofs = self.dof_map[self.contact.full_ids[tri]].reshape(len(tri), 6)
        r = np.repeat(dofs, dofs.shape[1], axis=1).ravel()
        c = np.tile(dofs, (1, dofs.shape[1])).ravel()
        keep = (r >= 0) & (c >= 0)
        return r[keep], c[keep]

    # -- reactions -----------------------------------------------------------------
    def contact_force(
        self, q: np.ndarray, nodes: np.ndarray, friction_only: bool = False
    ) -> np.ndarray:
        """Total contact force (barrier + friction, N/mm) acting on the given nodes
        (bool mask or ids), ``-sum d(B + D)/dx`` over them."""
        if self.contact is None:
            return np.zeros(2)
        return self.contact_nodal_forces(q, nodes, friction_only).sum(axis=0)

    def contact_nodal_forces(
        self, q: np.ndarray, nodes: np.ndarray, friction_only: bool = False
    ) -> np.ndarray:
        """Contact force (barrier + friction, N/mm) on each of the given nodes (bool
        mask or ids), ``-d(B + D)/dx`` (n, 2)."""
        if self.contact is None:
            return np.zeros(
                (int(np.count_nonzero(nodes)) if np.asarray(nodes).dtype == bool else len(nodes), 2)
            )
        U = self.U(q)
        if friction_only:
            gc = (
                self.contact.friction_gradient(U, self.U_step_start)
                if self.U_step_start is not None
                else np.zeros(len(self.coll_full))
            )
        else:
            gc = self.contact.evaluate(U, self.U_step_start, order=1)[1]
        g = np.zeros(2 * self.N)
        g[self.coll_full] += gc
        return -g.reshape(-1, 2)[nodes]

    def elastic_force(self, q: np.ndarray, nodes: np.ndarray) -> np.ndarray:
        """Sum of the elastic internal forces dE/du (N/mm) at the given nodes; at
        clamped nodes this is the reaction of the support on the body."""
        _, g, _ = self.elastic.evaluate(self.U(q), 1, psd=False)
        return g.reshape(-1, 2)[nodes].sum(axis=0)

    def driver_force(self, q: np.ndarray) -> np.ndarray:
        """k (t - t_target) (N/mm): at equilibrium, the force of the surroundings on
        the driven nodes (contact + elasticity of the body they belong to)."""
        if not self.has_driver:
            return np.zeros(2)
        return self.k_drive * (self.t(q) - self.t_target)

    def residual(self, q: np.ndarray) -> np.ndarray:
        """Reduced gradient of the potential (out-of-balance forces, N/mm)."""
        return self.evaluate(q, order=1)[1]

    def residual_norm(self, g: np.ndarray, floor: float = 1e-12) -> float:
        """Force balance of the free nodes: ``|g_free|_2 / max(F, floor)``, dimensionless.

        ``g`` is the reduced gradient returned by :meth:`evaluate` (out-of-balance
        nodal forces, N/mm); its free-node part is used (the driver's two unknowns
        only carry the penalty spring). ``F`` (N/mm) is the 2-norm of the nodal
        forces that hold the bodies: the support reactions at the fixed nodes, the
        driver spring and the applied loads, from the same evaluation. The scenes are
        displacement driven (no applied load), so the reaction is the only load
        scale they have; where a load is applied it equals the reaction at
        equilibrium. ``floor`` (N/mm) stands in for F when nothing is loaded.
        """
        r = float(np.linalg.norm(g[: self.n_free_dofs]))
        return r / max(self.force_scale, floor)
