"""Quasi-static Newton solver with CCD-bounded line search and load stepping.

Units: mm, N, MPa; energies per unit out-of-plane thickness (N mm / mm), forces
N/mm.

The total potential of a load step is minimised over the reduced unknowns ``q``::

    Pi(q) = E_elastic(U) + B_barrier(U) + D_friction(U - U_step_start)
            + k/2 |t - t_target|^2 - s f_ext . U

``t`` (2 unknowns) is the rigid translation of the *driven* nodes (the rigid
object, or the inner loop of a deformable ring): it is pulled to its target by a
stiff penalty spring ``k`` (as the IPC paper enforces moving boundary
conditions), so that every step of the solve is a line search on one energy and
the object never enters the finger. The force the finger exerts on the object is
``k (t - t_target)``, equal to ``-d(B + D)/dt`` at equilibrium.

Newton: the exact Hessian is factorised first (quadratic convergence); when it is
not positive definite, the material tangents are projected to PSD per Gauss point
and the contact Hessians per contact (ipctk's "abs" projection) and the system is
factorised again. The sparse Cholesky (CHOLMOD, from scikit-sparse or cvxopt's wheels)
reuses its symbolic analysis while the pattern stays inside the analysed one. Near the
solution (after a full step below ``chord_dx``, or a friction re-lag) the direction is
first computed with the last factorisation (a chord step, for which no Hessian is
assembled), kept only when it contracts (``chord_contraction``). Each step is cut to the collision-free
fraction found by continuous collision detection, then backtracked (Armijo) so
that the energy decreases: no accepted state is interpenetrating or has an
inverted element. Convergence needs both criteria of :class:`NewtonOptions`: the
infinity norm of the Newton step below ``tol_dx`` (mm) and the force residual of the
free DOFs below ``tol_residual`` relative to the support and load forces
(:meth:`Model.residual_norm`, from the gradient already assembled for the step); that
last, tiny step is taken too. Line-search failures and gradient-descent fallbacks
are counted in ``Model.counters``, never silent.

Load stepping (:func:`march`): adaptive steps (halved on failure, doubled after
easy steps, bounded by the frame spacing), a linear predictor from the previous
increment, and friction normal forces/tangents lagged at the step start and
re-lagged ``friction_lag_iterations`` times within the step's Newton solve, at each
convergence (or first once its step falls below ``friction_relag_dx``, off by default).
"""
from __future__ import annotations

import time
from dataclasses import dataclass, field

import numpy as np
import scipy.sparse as sp

from .assembly import ElasticAssembler, ElementBlock
from .contact import ContactModel

try:  # CHOLMOD (scikit-sparse): symbolic analysis reused across Newton iterations
    from sksparse.cholmod import CholmodNotPositiveDefiniteError
    from sksparse.cholmod import analyze as _cholmod_analyze
    HAVE_CHOLMOD = True
except Exception:  # pragma: no cover - depends on the machine
    HAVE_CHOLMOD = False
try:  # CHOLMOD bundled in cvxopt's wheels: the same reuse without SuiteSparse's headers
    import cvxopt as _cvxopt
    import cvxopt.cholmod as _cvx_cholmod
    HAVE_CVXOPT = True
except Exception:  # pragma: no cover
    HAVE_CVXOPT = False
try:
    import cholespy as _cholespy
    HAVE_CHOLESPY = True
except Exception:  # pragma: no cover
    HAVE_CHOLESPY = False


class NotPositiveDefinite(np.linalg.LinAlgError):
    """The Cholesky factorisation met a non-positive pivot."""


class SimulationError(RuntimeError):
    """The solve failed; ``step`` is the load-step index, ``load`` the load factor
    (fraction of the push) it aimed at, ``cause`` a short reason."""

    def __init__(self, message: str, step: int | None = None, load: float | None = None,
                 cause: str = ""):
        super().__init__(message)
        self.step = step
        self.load = load
        self.cause = cause


# ----------------------------------------------------------------------------------
# Linear solver
# ----------------------------------------------------------------------------------
class SplitMatrix:
    """A symmetric matrix held as ``base + extra``: ``base`` CSR on a pattern fixed for
    the model (elasticity), ``extra`` COO whose pattern varies (contact, driver spring).

    :class:`LinearSolver`'s cvxopt path scatters both into its analysed pattern, so
    the sum is formed only where something asks for it (:meth:`tocsr`).
    """

    def __init__(self, base: sp.csr_matrix, extra: sp.coo_matrix | None = None):
        self.base = base
        self.extra = extra
        self.shape = base.shape
        self._sum = None

    def tocsr(self) -> sp.csr_matrix:
        if self._sum is None:
            self._sum = self.base if self.extra is None else (self.base + self.extra).tocsr()
        return self._sum

    def __matmul__(self, v: np.ndarray) -> np.ndarray:
        out = self.base @ v
        return out if self.extra is None else out + self.extra @ v

    def diagonal(self) -> np.ndarray:
        d = self.base.diagonal()
        return d if self.extra is None else d + self.extra.diagonal()

    def all_finite(self) -> bool:
        return bool(np.isfinite(self.base.data).all() and
                    (self.extra is None or np.isfinite(self.extra.data).all()))


def _csr_keys(indptr: np.ndarray, indices: np.ndarray, n: int) -> np.ndarray:
    """row * n + col of each entry of a CSR pattern (sorted when its indices are)."""
    rows = np.repeat(np.arange(n, dtype=np.int64), np.diff(indptr))
    return rows * n + indices


def available_backends() -> list[str]:
    """The linear solver backends that import here, in the order "auto" prefers them
    (SuperLU, always there, last)."""
    return [b for b, ok in (("cholmod", HAVE_CHOLMOD), ("cvxopt", HAVE_CVXOPT),
                            ("cholespy", HAVE_CHOLESPY), ("splu", True)) if ok]


class LinearSolver:
    """Sparse SPD solver.

    ``backend``: "cholmod" (scikit-sparse; the symbolic factorisation is kept and
    reused while the matrix pattern is a subset of the analysed one; ``mode``
    "simplicial" by default (faster than "supernodal" for these 2D systems with
    Debian's reference BLAS and still with OpenBLAS); "auto" times one of each and
    keeps the faster, at the cost of a run-to-run dependence), "cvxopt" (the CHOLMOD
    that cvxopt's wheels bundle, no system package needed; the same reuse of the
    analysis and the same ``mode``: "simplicial" LDL' like scikit-sparse's, which
    solves indefinite systems and raises only on a zero pivot, or "supernodal" LL',
    which raises on any non-positive pivot), "cholespy" (a fresh analysis and
    factorisation each call), "splu" (scipy SuperLU), or "auto" (the first one
    available in that order).
    """

    def __init__(self, backend: str = "auto", mode: str = "simplicial"):
        self.mode = mode  # CHOLMOD: "simplicial", "supernodal" or "auto" (timed once)
        if backend == "auto":
            backend = available_backends()[0]
        if backend not in ("cholmod", "cvxopt", "cholespy", "splu"):
            raise ValueError(f"unknown linear solver {backend!r}: use auto, cholmod, cvxopt, "
                             f"cholespy or splu")
        self.backend = backend
        self._factor = None
        self._base = None  # sorted int64 keys (row * n + col) of the base pattern
        self._base_csr = None
        self._base_n = -1
        self._extra = None  # sorted keys of the varying part seen so far
        self._upper = None  # cvxopt: (indptr, indices) of the analysed upper triangle
        self._upper_keys = None  # cvxopt: its sorted keys
        self._base_up = None  # cvxopt: the base's upper-triangle entries (CSR positions)
        self._base_pos = None  # cvxopt: their positions in the analysed upper triangle
        self._spm = None  # cvxopt: its transpose, a cvxopt matrix (values replaced)
        self._spm_base = None  # cvxopt: the base pattern's lower triangle
        self.n_analyses = 0
        self.n_factorizations = 0
        self.n_resolves = 0  # solves with an earlier factorisation (resolve)
        self._last = None  # b -> x with the last factorisation
        self.time_analyse = 0.0
        self.time_factor = 0.0
        self.time_solve = 0.0

    @staticmethod
    def _keys(A: sp.csr_matrix) -> np.ndarray:
        return _csr_keys(A.indptr, A.indices, A.shape[0])

    @staticmethod
    def _missing(keys: np.ndarray, sorted_keys: np.ndarray | None) -> np.ndarray:
        """Keys not in sorted_keys."""
        if sorted_keys is None or len(sorted_keys) == 0:
            return keys
        pos = np.searchsorted(sorted_keys, keys)
        pos[pos >= len(sorted_keys)] = 0
        return keys[sorted_keys[pos] != keys]

    @staticmethod
    def _pick_mode(A: sp.csr_matrix) -> str:
        """Time one simplicial and one supernodal factorisation of A (CHOLMOD's
        supernodal mode pays off only with an optimised BLAS)."""
        Ac = sp.csc_matrix((A.data, A.indices, A.indptr), shape=A.shape)
        best, best_t = "simplicial", np.inf
        for mode in ("simplicial", "supernodal"):
            try:
                f = _cholmod_analyze(Ac, mode=mode)
                t0 = time.perf_counter()
                f.cholesky_inplace(Ac, beta=float(np.abs(A.data).max()))  # surely SPD
                dt = time.perf_counter() - t0
            except Exception:
                continue
            if dt < best_t:
                best, best_t = mode, dt
        return best

    def _ensure_analysis(self, A: sp.csr_matrix, extra: sp.spmatrix | None) -> None:
        """Analyse the union of the base pattern and every extra pattern seen so far;
        re-analyse only when an extra entry falls outside it.

        ``extra``: the part of A whose pattern varies (contact); A minus extra is the
        fixed base pattern, taken from the first call. Without ``extra`` all of A is
        checked against the analysed pattern.
        """
        n = A.shape[0]
        if self._base is None or self._base_n != n:
            self._base = self._keys(A)  # sorted: CSR with sorted indices
            self._base_csr = sp.csr_matrix((np.ones(len(self._base)), A.indices.copy(),
                                            A.indptr.copy()), shape=A.shape)
            self._base_n = n
            self._base_up = np.flatnonzero(self._base % n >= self._base // n)
            self._extra = np.empty(0, np.int64)
            self._factor = None
            self._spm_base = None
        else:
            if extra is None:
                keys = self._keys(A)
            else:
                e = extra.tocoo()
                keys = np.unique(e.row.astype(np.int64) * n + e.col)
            new = self._missing(self._missing(keys, self._extra), self._base)
            if len(new) == 0 and self._factor is not None:
                return
            self._extra = np.union1d(self._extra, new)
        t0 = time.perf_counter()
        if self.backend == "cvxopt":
            self._factor = self._cvxopt_analyse(n)
        else:
            P = self._base_csr
            if len(self._extra):
                r, c = np.divmod(self._extra, n)
                P = P + sp.csr_matrix((np.ones(len(r)), (r, c)), shape=(n, n))
            P = P.tocsr()
            P.sort_indices()
            # symmetric pattern: its CSR arrays are also its CSC arrays
            Pc = sp.csc_matrix((P.data, P.indices, P.indptr), shape=P.shape)
            if self.mode == "auto":
                self.mode = self._pick_mode(A)
            self._factor = _cholmod_analyze(Pc, mode=self.mode)
        self.n_analyses += 1
        self.time_analyse += time.perf_counter() - t0

    @staticmethod
    def _cvxopt_lower(r: np.ndarray, c: np.ndarray, n: int):
        """cvxopt pattern (ones) of the lower triangle of the symmetric entries (r, c)."""
        up = c >= r  # upper entry (r, c) is lower entry (c, r)
        return _cvxopt.spmatrix(1.0, _cvxopt.matrix(c[up]), _cvxopt.matrix(r[up]), (n, n))

    def _cvxopt_analyse(self, n: int):
        """Symbolic factorisation by cvxopt's CHOLMOD of the lower triangle of the base
        pattern plus the extra entries. The base's cvxopt matrix is built once; the
        union is a cvxopt sum (in C): building the whole pattern from triplets cost
        more than the analysis itself. The lower triangle in CSC has the arrays of the
        upper triangle in CSR (``_upper``, for the values' scatter)."""
        if self._spm_base is None or self._spm_base.size != (n, n):
            r, c = np.divmod(self._base, n)
            self._spm_base = self._cvxopt_lower(r, c, n)
        r, c = np.divmod(self._extra, n)
        # a new matrix either way: its values get replaced, the base's stay a pattern
        self._spm = (self._spm_base + self._cvxopt_lower(r, c, n)
                     if len(self._extra) else 1.0 * self._spm_base)
        colptr, rowind, _ = self._spm.CCS
        self._upper = (np.array(colptr, np.int64).ravel(), np.array(rowind, np.int64).ravel())
        self._upper_keys = _csr_keys(*self._upper, n)
        # base and extra keys are disjoint (extras are the keys outside the base): the
        # base's upper entries are the analysed ones that are not extra, in key order
        up = c >= r
        is_extra = np.zeros(len(self._upper_keys), bool)
        is_extra[np.searchsorted(self._upper_keys, self._extra[up])] = True
        self._base_pos = np.flatnonzero(~is_extra)
        # simplicial LDL' as scikit-sparse's default: the same Newton path (an indefinite
        # Hessian gives a direction that newton() checks for descent); supernodal LL'
        # (raises on a non-positive pivot, so more projected Hessians) moved some frames'
        # forces by up to 7 % at slip events
        _cvx_cholmod.options["supernodal"] = {"simplicial": 0, "auto": 1}.get(self.mode, 2)
        return _cvx_cholmod.symbolic(self._spm, uplo="L")

    def _cvxopt_values(self, A) -> np.ndarray | None:
        """A's values on the analysed upper triangle (explicit zeros where A has no
        entry: CHOLMOD's numeric step assumes that pattern), or None when an entry of
        A lies outside it. A :class:`SplitMatrix`'s base goes by the positions found at
        the analysis, its extra (and a plain matrix) by key."""
        n = A.shape[0]
        vals = np.zeros(len(self._upper_keys))
        if isinstance(A, SplitMatrix):
            vals[self._base_pos] = A.base.data[self._base_up]
            rest = A.extra
        else:
            rest = A
        if rest is not None and rest.nnz:
            rest = rest.tocoo()
            up = rest.col >= rest.row
            keys = rest.row[up].astype(np.int64) * n + rest.col[up]
            pos = np.minimum(np.searchsorted(self._upper_keys, keys), len(vals) - 1)
            if not np.array_equal(self._upper_keys[pos], keys):
                return None
            np.add.at(vals, pos, rest.data[up])
        return vals

    def _solve_cvxopt(self, A, b: np.ndarray) -> np.ndarray:
        vals = self._cvxopt_values(A)
        if vals is None:  # an entry outside the analysed pattern
            A = A.tocsr() if isinstance(A, SplitMatrix) else A
            self._ensure_analysis(A, None)
            vals = self._cvxopt_values(A)
        self._spm.V = _cvxopt.matrix(vals)
        t0 = time.perf_counter()
        try:
            _cvx_cholmod.numeric(self._spm, self._factor)
        except ArithmeticError as e:  # the column of the failed (zero or, LL', negative) pivot
            self._last = None  # the factor is overwritten in place
            self.time_factor += time.perf_counter() - t0
            raise NotPositiveDefinite(f"not positive definite (pivot of column {e})") from None
        self.n_factorizations += 1
        t1 = time.perf_counter()
        factor = self._factor

        def solve(b):
            x = _cvxopt.matrix(np.asarray(b, float).reshape(-1, 1))
            _cvx_cholmod.solve(factor, x)
            return np.array(x).ravel()
        self._last = solve
        x = solve(b)
        self.time_factor += t1 - t0
        self.time_solve += time.perf_counter() - t1
        return x

    def solve(self, A, b: np.ndarray, extra: sp.spmatrix | None = None) -> np.ndarray:
        """Solve A x = b for symmetric positive definite A (CSR, both triangles, or a
        :class:`SplitMatrix`, whose base must keep its pattern from call to call).

        ``extra``: for a CSR A, the contribution to A whose pattern changes between
        calls (its pattern is merged into the analysed one when new entries appear); a
        :class:`SplitMatrix` carries its own.
        Raises :class:`NotPositiveDefinite` where the factorisation fails: cholespy and
        supernodal CHOLMOD on any non-positive pivot, simplicial CHOLMOD (LDL') on a
        zero pivot only (an indefinite A then gives a solution: callers check descent).
        """
        if isinstance(A, SplitMatrix):
            if self.backend == "cvxopt":
                if self._base is not None and len(self._base) != A.base.nnz:
                    self._base = None  # another base pattern: analyse anew
                self._ensure_analysis(A.base, A.extra if A.extra is not None
                                      else sp.coo_matrix(A.shape))
                return self._solve_cvxopt(A, b)
            A, extra = A.tocsr(), A.extra
        A = A.tocsr()
        A.sort_indices()
        if self.backend == "cvxopt":
            self._ensure_analysis(A, extra)
            return self._solve_cvxopt(A, b)
        if self.backend == "cholmod":
            self._ensure_analysis(A, extra)
            t0 = time.perf_counter()
            # CSR of a symmetric matrix is the CSC of the same matrix
            Ac = sp.csc_matrix((A.data, A.indices, A.indptr), shape=A.shape)
            try:
                self._factor.cholesky_inplace(Ac)
            except CholmodNotPositiveDefiniteError as e:
                self._last = None  # the factor is overwritten in place
                self.time_factor += time.perf_counter() - t0
                raise NotPositiveDefinite(str(e)) from None
            self.n_factorizations += 1
            t1 = time.perf_counter()
            factor = self._factor
            self._last = lambda b: np.asarray(factor(b)).ravel()
            x = self._last(b)
            self.time_factor += t1 - t0
            self.time_solve += time.perf_counter() - t1
            return x
        if self.backend == "cholespy":
            t0 = time.perf_counter()
            n = A.shape[0]
            try:
                s = _cholespy.CholeskySolverD(n, A.indptr.astype(np.int32),
                                              A.indices.astype(np.int32),
                                              np.ascontiguousarray(A.data),
                                              _cholespy.MatrixType.CSR)
            except ValueError as e:  # "Matrix is not positive definite!"
                self.time_factor += time.perf_counter() - t0
                raise NotPositiveDefinite(str(e)) from None
            def solve(b):
                x = np.zeros(n)
                s.solve(np.ascontiguousarray(b, dtype=float), x)
                return x
            self._last = solve
            x = solve(b)
            self.n_factorizations += 1
            self.time_factor += time.perf_counter() - t0
            return x
        t0 = time.perf_counter()
        try:
            import scipy.sparse.linalg as spla  # the last resort only: 0.1 s of import

            lu = spla.splu(A.tocsc())
        except RuntimeError as e:  # exactly singular
            raise np.linalg.LinAlgError(str(e)) from None
        self._last = lu.solve
        x = lu.solve(b)
        self.n_factorizations += 1
        self.time_factor += time.perf_counter() - t0
        return x

    def resolve(self, b: np.ndarray) -> np.ndarray | None:
        """Solve with the last factorisation (of an earlier matrix: a chord step), or
        None before the first."""
        if self._last is None:
            return None
        t0 = time.perf_counter()
        try:
            x = self._last(b)
        except (ArithmeticError, ValueError, RuntimeError):
            return None
        self.n_resolves += 1
        self.time_solve += time.perf_counter() - t0
        return x


# ----------------------------------------------------------------------------------
# The discrete problem
# ----------------------------------------------------------------------------------
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

    def __init__(self, points, blocks: list[ElementBlock], fixed_nodes=(), driven_nodes=(),
                 contact: ContactModel | None = None, driver_stiffness: float = 1e5,
                 external_force: np.ndarray | None = None, psd="auto",
                 quad_degree: int | None = None, linear_solver: str = "auto"):
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
        self.f_ext = np.zeros((N, 2)) if external_force is None else np.asarray(external_force, float)
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
        self.stats = {"assembly_s": 0.0, "contact_s": 0.0, "solve_s": 0.0, "ccd_s": 0.0,
                      "line_search_s": 0.0}
        # per model (scene): backtracking that found no decrease, non-descent Newton
        # directions replaced by scaled gradient descent, the largest relative
        # residual of a converged solve, and chord steps refused (a Hessian assembled
        # and factorised instead)
        self.counters = {"line_search_failures": 0, "gradient_fallbacks": 0,
                         "residual_max_rel": 0.0, "chord_refused": 0}
        self._fixed_dofs = np.flatnonzero(np.repeat(fixed, 2))
        self.force_scale = 0.0  # N/mm, set by evaluate() (see residual_norm)

    # -- state mapping -------------------------------------------------------------
    def U(self, q: np.ndarray) -> np.ndarray:
        """Nodal displacements (N, 2) of the reduced vector q."""
        U = self.U_presc.copy()
        U.reshape(-1)[self._unknown] = q[self._unknown_dof]
        return U

    def q_from_U(self, U: np.ndarray) -> np.ndarray:
        q = np.zeros(self.n)
        m = self.dof_map >= 0
        q[self.dof_map[m]] = U[m]
        return q

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
            C = sp.coo_matrix((np.concatenate(extra_v), (np.concatenate(extra_r),
                                                          np.concatenate(extra_c))),
                              shape=(self.n, self.n))
        return E, g, SplitMatrix(self.elastic.pattern.matrix(Hdata), C)

    # -- reactions -----------------------------------------------------------------
    def contact_force(self, q: np.ndarray, nodes: np.ndarray, friction_only: bool = False) -> np.ndarray:
        """Total contact force (barrier + friction, N/mm) acting on the given nodes
        (bool mask or ids), ``-sum d(B + D)/dx`` over them."""
        if self.contact is None:
            return np.zeros(2)
        U = self.U(q)
        if friction_only:
            gc = self.contact.friction_gradient(U, self.U_step_start) \
                if self.U_step_start is not None else np.zeros(len(self.coll_full))
        else:
            gc = self.contact.evaluate(U, self.U_step_start, order=1)[1]
        g = np.zeros(2 * self.N)
        g[self.coll_full] += gc
        return -g.reshape(-1, 2)[nodes].sum(axis=0)

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
        r = float(np.linalg.norm(g[:self.n_free_dofs]))
        return r / max(self.force_scale, floor)


# ----------------------------------------------------------------------------------
# Newton
# ----------------------------------------------------------------------------------
@dataclass
class NewtonOptions:
    """Newton's stopping rule: converged when the step is below ``tol_dx`` (mm,
    infinity norm) *and* the free-DOF residual below ``tol_residual`` (relative to the
    support and load forces, :meth:`Model.residual_norm`; ``residual_floor`` N/mm
    is the force scale of an unloaded model)."""

    max_iterations: int = 40
    tol_dx: float = 1e-5  # mm, infinity norm of the Newton direction
    tol_residual: float = 1e-3  # |g_free| / |reactions + loads| (config fea.residual_tol)
    residual_floor: float = 1e-12  # N/mm
    armijo: float = 1e-4
    min_alpha: float = 1e-10
    # chord steps: after a full step below chord_dx (mm), the next direction reuses the
    # last factorisation; kept when it is at most chord_contraction times that step (the
    # Hessian has hardly changed), else a new factorisation is made (0: never). 0.1 mm
    # saved a fifth of the factorisations, but its solves, ending on slower chord steps,
    # left a steel scene's equilibrium error above equilibrium_tol (1.04e-3)
    chord_dx: float = 1e-2
    chord_contraction: float = 0.5


@dataclass
class NewtonResult:
    """``residual``: :meth:`Model.residual_norm` at the last assembled state (before
    the final step of size < tol_dx, which in Newton's quadratic regime reduces it
    further; no assembly is spent to measure it again); ``note``: why a converged
    solve is unusual (e.g. the line search stalled at round-off)."""

    q: np.ndarray
    converged: bool
    iterations: int
    cause: str = ""
    energy: float = np.nan
    history: list = field(default_factory=list)
    residual: float = np.nan
    note: str = ""


def newton(model: Model, q0: np.ndarray, opts: NewtonOptions | None = None,
           relag=None, relags: int = 0, relag_dx: float = 0.0) -> NewtonResult:
    """Minimise the model's potential from q0 (must be valid and intersection-free).

    ``relag(q)`` changes the potential (friction re-lagged at q) ``relags`` times
    during the solve: the first once a full Newton step of at most ``relag_dx`` (mm)
    has been taken (0: at convergence), the others at convergence, where the solve
    then goes on; a re-lag that the next step already satisfies ends them. One
    solve instead of a solve per re-lag saves the convergence check of each.

    Converged: Newton step below ``opts.tol_dx`` and residual below
    ``opts.tol_residual`` (both). A backtracking line search that finds no
    decrease is counted (``model.counters["line_search_failures"]``) and ends the
    solve: converged only if the residual criterion holds there (energy round-off
    near the minimum), else not converged, with the step and residual in ``cause``.
    A non-descent direction is replaced by scaled gradient descent and counted
    (``model.counters["gradient_fallbacks"]``).
    """
    opts = opts or NewtonOptions()
    cnt = model.counters
    q = q0.copy()
    E, g, H = model.evaluate(q, 2)
    if not np.isfinite(E):
        return NewtonResult(q, False, 0, "initial state has an inverted element", E)
    hist = []
    last_step = np.inf  # |dx| of the last full Newton step taken
    relags = relags if relag is not None else 0
    since_relag = None  # Newton steps since the last re-lag

    def chord_next() -> bool:
        return last_step < opts.chord_dx

    def assemble(q):
        # a chord step needs no Hessian (it is assembled if the chord is refused)
        return model.evaluate(q, 1 if chord_next() else 2)

    def do_relag(q):
        nonlocal relags, since_relag, last_step
        relag(q)
        relags -= 1
        since_relag = 0
        # re-lagging near the solution hardly changes the Hessian: a chord step may
        # follow, if it is below chord_contraction * chord_dx
        last_step = opts.chord_dx * (1 - 1e-12)
        return assemble(q)

    for it in range(1, opts.max_iterations + 1):
        if not (np.all(np.isfinite(g)) and (H is None or H.all_finite())):
            return NewtonResult(q, False, it, "non-finite gradient or Hessian", E, hist)
        t0 = time.perf_counter()
        d = None
        if chord_next():  # near the solution: try the last factorisation
            d = model.linsolve.resolve(-g)
            if d is not None and not (np.all(np.isfinite(d)) and float(g @ d) < 0 and np.abs(d).max()
                                      <= opts.chord_contraction * last_step):
                d = None
        if d is None and H is None:  # the chord was refused: the Hessian after all
            cnt["chord_refused"] += 1
            t1 = time.perf_counter()
            _, _, H = model.evaluate(q, 2)
            t0 += time.perf_counter() - t1  # counted as assembly and contact, not solve
            if not H.all_finite():
                return NewtonResult(q, False, it, "non-finite Hessian", E, hist)
        if d is None and model.psd is not True:
            try:
                d = model.linsolve.solve(H, -g)
                if not np.all(np.isfinite(d)) or float(g @ d) >= 0:
                    d = None
            except np.linalg.LinAlgError:
                d = None
        if d is None:  # indefinite: project the material tangents and retry
            model.stats["n_projected"] = model.stats.get("n_projected", 0) + 1
            if model.psd is not True:
                _, _, H = model.evaluate(q, 2, psd=True)
            try:
                d = model.linsolve.solve(H, -g)
            except np.linalg.LinAlgError as e:
                return NewtonResult(q, False, it, f"linear solve failed: {e}", E, hist)
        model.stats["solve_s"] += time.perf_counter() - t0
        if not np.all(np.isfinite(d)):
            return NewtonResult(q, False, it, "linear solve returned NaN", E, hist)
        gd = float(g @ d)
        if gd >= 0:  # not a descent direction (should not happen with PSD Hessians)
            cnt["gradient_fallbacks"] += 1
            if H is None:
                _, _, H = model.evaluate(q, 2)
            d = -g / np.maximum(H.diagonal(), 1e-12)
            gd = float(g @ d)
        dmax = float(np.abs(d).max()) if len(d) else 0.0
        res = model.residual_norm(g, opts.residual_floor)  # g of this state: no assembly
        hist.append([E, float(np.abs(g).max()) if len(g) else 0.0, dmax,
                     int(np.abs(d).argmax()) if len(d) else -1, 1.0, 1.0, res])
        if dmax < opts.tol_dx and res <= opts.tol_residual:
            # take the (tiny) last Newton step too: the residual becomes O(|d|^2)
            q_try = q + d
            ok = model.contact is None or model.contact.max_step(model.U(q), model.U(q_try)) >= 1.0
            if ok:
                E_try = model.energy(q_try)
                if np.isfinite(E_try) and E_try <= E + 1e-12 * max(1.0, abs(E)):
                    q, E = q_try, E_try
            # re-lag at the solution and go on, unless the last re-lag needed no step
            if relags > 0 and since_relag != 0:
                E, g, H = do_relag(q)
                continue
            cnt["residual_max_rel"] = max(cnt["residual_max_rel"], res)
            return NewtonResult(q, True, it, "", E, hist, res)
        # continuous collision detection bounds the step
        alpha = 1.0
        if model.contact is not None:
            t0 = time.perf_counter()
            alpha = min(1.0, model.contact.max_step(model.U(q), model.U(q + d)))
            model.stats["ccd_s"] += time.perf_counter() - t0
            if alpha <= 0:
                return NewtonResult(q, False, it, "CCD allows no step", E, hist)
            hist[-1][4] = alpha
        t0 = time.perf_counter()
        slack = 1e-12 * max(1.0, abs(E))
        while True:
            q_try = q + alpha * d
            E_try = model.energy(q_try)
            if np.isfinite(E_try) and E_try <= E + opts.armijo * alpha * gd + slack:
                break
            alpha *= 0.5
            if alpha < opts.min_alpha:
                model.stats["line_search_s"] += time.perf_counter() - t0
                cnt["line_search_failures"] += 1
                if dmax < 100 * opts.tol_dx and res <= opts.tol_residual:
                    # balanced forces, energy differences below round-off
                    cnt["residual_max_rel"] = max(cnt["residual_max_rel"], res)
                    return NewtonResult(q, True, it - 1, "", E, hist, res,
                                        note=f"line search stalled at |dx| = {dmax:.2e} mm "
                                             f"with the residual {res:.2e} within tolerance")
                return NewtonResult(q, False, it, f"line search failed (no decrease) at "
                                    f"|dx| = {dmax:.2e} mm, residual {res:.2e} (tolerance "
                                    f"{opts.tol_residual:.0e})", E, hist, res)
        model.stats["line_search_s"] += time.perf_counter() - t0
        hist[-1][5] = alpha
        last_step = dmax if alpha == 1.0 else np.inf
        q = q_try
        if since_relag is not None:
            since_relag += 1
        if relags > 0 and since_relag is None and alpha == 1.0 and dmax <= relag_dx:
            E, g, H = do_relag(q)
        else:
            E, g, H = assemble(q)
    # hist rows: [E, |g|, |d|, argmax, ccd alpha, alpha, residual]
    res_last = model.residual_norm(g, opts.residual_floor)
    dmax_last = hist[-1][2] if hist else np.nan
    return NewtonResult(q, False, opts.max_iterations,
                        f"no convergence in {opts.max_iterations} iterations "
                        f"(last |dx| = {dmax_last:.2e} mm, residual {res_last:.2e})", E, hist,
                        res_last)


# ----------------------------------------------------------------------------------
# Load stepping
# ----------------------------------------------------------------------------------
@dataclass
class StepOptions:
    initial_step: float = 0.05  # fraction of the load path
    max_step: float = 0.05
    min_step: float = 1e-4
    grow: float = 2.0
    easy_iterations: int = 6  # grow the step when Newton took at most this many
    max_retries: int = 12  # step cuts in a row before giving up
    friction_lag_iterations: int = 0  # friction re-lags within each step's solve
    # mm: the first re-lag once Newton's step is this small (0: at convergence). 1e-3 saves
    # ~13 % of the factorisations but moved a steel scene's force by 6 % at a slip event
    friction_relag_dx: float = 0.0
    predictor: bool = True
    max_driver_lag: float | None = 1e-3  # mm; a larger lag means the object is blocked


def march(model: Model, q: np.ndarray, targets, frames: np.ndarray,
          step_opts: StepOptions | None = None, newton_opts: NewtonOptions | None = None,
          on_frame=None, friction: bool = True):
    """Advance the load factor s from its current 0 to each value in ``frames``.

    ``targets(s)`` gives the driver target (2,) at load factor s (also sets
    ``model.load = s`` for external forces). ``on_frame(k, s, q, info)`` is called
    at every frame with the Newton iterations and wall time since the previous one
    and ``residual_rel``, the residual of the solve that reached the frame
    (:meth:`Model.residual_norm`).
    Raises :class:`SimulationError` naming the step and the cause on failure.
    Returns the final q.
    """
    so = step_opts or StepOptions()
    no = newton_opts or NewtonOptions()
    s = 0.0
    ds = so.initial_step
    step = 0
    q_prev, s_prev = None, None
    iters_frame = 0
    residual = np.nan
    t_frame = time.perf_counter()
    for k, s_f in enumerate(frames):
        while s < s_f - 1e-12:
            s_new = min(s + ds, s_f)
            if s_f - s_new < 0.25 * ds:  # avoid a sliver step before the frame
                s_new = s_f
            retries = 0
            while True:
                step += 1
                model.load = s_new
                model.t_target = np.asarray(targets(s_new), float)
                U_start = model.U(q)
                model.U_step_start = U_start
                if model.contact is not None:
                    model.contact.update_friction(U_start if friction else None)
                q_init = q
                if so.predictor and q_prev is not None and s > s_prev:
                    q_init = _predict(model, q, q_prev, (s_new - s) / (s - s_prev))
                relag = None
                if friction and model.contact is not None and model.contact.params.mu > 0:
                    relag = lambda q_: model.contact.update_friction(model.U(q_))  # noqa: E731
                res = newton(model, q_init, no, relag, so.friction_lag_iterations,
                             so.friction_relag_dx)
                iters = res.iterations
                iters_frame += iters
                if res.converged and model.has_driver and so.max_driver_lag is not None:
                    lag = float(np.abs(model.t(res.q) - model.t_target).max())
                    if lag > so.max_driver_lag:
                        raise SimulationError(
                            f"load step {step} (load factor {s:.5f} -> {s_new:.5f}): the "
                            f"driven object lags its prescribed position by {lag:.3g} mm; it "
                            f"is blocked (e.g. pressed against the clamped base)",
                            step=step, load=s_new, cause="object blocked")
                if res.converged:
                    break
                retries += 1
                if retries > so.max_retries or (s_new - s) / 2 < so.min_step:
                    raise SimulationError(
                        f"load step {step} (load factor {s:.5f} -> {s_new:.5f}) failed: "
                        f"{res.cause}", step=step, load=s_new, cause=res.cause)
                ds = (s_new - s) / 2
                s_new = s + ds
            q_prev, s_prev = q, s
            q, s = res.q, s_new
            residual = res.residual
            if iters <= so.easy_iterations:
                ds = min(so.max_step, ds * so.grow)
        if on_frame is not None:
            on_frame(k, s, q, {"newton_iterations": iters_frame,
                               "wall_time_s": time.perf_counter() - t_frame, "steps": step,
                               "residual_rel": residual})
        iters_frame = 0
        t_frame = time.perf_counter()
    return q


def _predict(model: Model, q, q_prev, ratio):
    """Linear extrapolation of the previous increment, cut to a valid, collision-free
    fraction (falls back to q)."""
    d = (q - q_prev) * ratio
    alpha = 1.0
    if model.contact is not None:
        alpha = min(1.0, model.contact.max_step(model.U(q), model.U(q + d)))
    for _ in range(4):
        q_try = q + alpha * d
        if np.isfinite(model.energy(q_try)):
            return q_try
        alpha *= 0.5
    return q

