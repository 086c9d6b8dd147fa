"""Sparse symmetric linear solves for Newton: four backends behind one interface.

:class:`LinearSolver` factorises the Hessian by sparse Cholesky (CHOLMOD from
scikit-sparse or from cvxopt's wheels, or cholespy) and reuses the symbolic analysis
while the pattern stays inside the analysed one; SuperLU (scipy) is the fallback that
is always there. ``resolve`` reuses the last factorisation (Newton's chord steps).
:class:`SplitMatrix` holds the Hessian as a fixed-pattern elastic part plus a
varying contact part.
"""

from __future__ import annotations

import time

import numpy as np
import scipy.sparse as sp

from ..errors import NotPositiveDefinite

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


class SplitMatrix:
    """A symmetric matrix held as ``base + extra``: ``base`` CSR on a pattern fixed for
    the model (elasticity), ``extra`` COO whose pattern varies (contact, driver spring).

    :class:`LinearSolver`'s cvxopt path scatters both into its analysed pattern, so
    the sum is formed only where something asks for it (:meth:`tocsr`).
    """

    def __init__(self, base: sp.csr_matrix, extra: sp.coo_matrix | None = None, margin=None):
        self.base = base
        self.extra = extra
        # () -> (rows, cols) of entries the extra part is likely to get soon (contact
        # pairs about to form), added to the analysed pattern when it is analysed anew
        self.margin = margin
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
        return bool(
            np.isfinite(self.base.data).all()
            and (self.extra is None or np.isfinite(self.extra.data).all())
        )


def _csr_keys(indptr: np.ndarray, indices: np.ndarray, n: int) -> np.ndarray:
    """row * n + col of each entry of a CSR pattern (sorted when its indices are)."""
    rows = np.repeat(np.arange(n, dtype=np.int64), np.diff(indptr))
    return rows * n + indices


def available_backends() -> list[str]:
    """The linear solver backends that import here, in the order "auto" prefers them
    (SuperLU, always there, last)."""
    return [
        b
        for b, ok in (
            ("cholmod", HAVE_CHOLMOD),
            ("cvxopt", HAVE_CVXOPT),
            ("cholespy", HAVE_CHOLESPY),
            ("splu", True),
        )
        if ok
    ]


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
    which raises on any non-positive pivot, or "hybrid", the default: supernodal LL'
    (a third less time than simplicial LDL' on a steel scene's Hessians with the
    wheel's OpenBLAS, one thread) and, where it meets a non-positive pivot, simplicial
    LDL' of the same matrix (analysed then, kept until the pattern changes), so that
    an indefinite Hessian is solved as by "simplicial": the supernodal mode alone
    projects it instead, which moved some frames' forces by up to 7 % at slip
    events), "cholespy" (a fresh analysis and factorisation each call), "splu" (scipy
    SuperLU), or "auto" (the first one available in that order). scikit-sparse takes
    "hybrid" as "simplicial".
    """

    def __init__(self, backend: str = "auto", mode: str = "hybrid"):
        # CHOLMOD: "hybrid", "simplicial", "supernodal" or "auto" (timed once)
        self.mode = mode
        if backend == "auto":
            backend = available_backends()[0]
        if backend not in ("cholmod", "cvxopt", "cholespy", "splu"):
            raise ValueError(
                f"unknown linear solver {backend!r}: use auto, cholmod, cvxopt, cholespy or splu"
            )
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
        self._factor_ldl = None  # cvxopt "hybrid": the simplicial analysis, once needed
        self.n_ldl_fallbacks = 0  # "hybrid": factorisations redone as LDL'
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

    def _ensure_analysis(self, A: sp.csr_matrix, extra: sp.spmatrix | None, margin=None) -> None:
        """Analyse the union of the base pattern and every extra pattern seen so far;
        re-analyse only when an extra entry falls outside it, then with the entries of
        ``margin()`` ((rows, cols), see :class:`SplitMatrix`) too.

        ``extra``: the part of A whose pattern varies (contact); A minus extra is the
        fixed base pattern, taken from the first call. Without ``extra`` all of A is
        checked against the analysed pattern.
        """
        n = A.shape[0]
        if self._base is None or self._base_n != n:
            self._base = self._keys(A)  # sorted: CSR with sorted indices
            self._base_csr = sp.csr_matrix(
                (np.ones(len(self._base)), A.indices.copy(), A.indptr.copy()), shape=A.shape
            )
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
            if margin is not None:
                r, c = margin()
                keys = r.astype(np.int64) * n + c
                new = np.concatenate(
                    [new, self._missing(self._missing(keys, self._extra), self._base)]
                )
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
            mode = "simplicial" if self.mode == "hybrid" else self.mode
            self._factor = _cholmod_analyze(Pc, mode=mode)
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
        self._spm = (
            self._spm_base + self._cvxopt_lower(r, c, n)
            if len(self._extra)
            else 1.0 * self._spm_base
        )
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
        self._factor_ldl = None
        return self._cvxopt_symbolic({"simplicial": 0, "auto": 1}.get(self.mode, 2))

    def _cvxopt_symbolic(self, supernodal: int):
        """cvxopt's CHOLMOD analysis of ``_spm`` (``supernodal``: 0 simplicial, 1 auto,
        2 supernodal; a global option of cvxopt, restored after)."""
        saved = _cvx_cholmod.options.get("supernodal")
        _cvx_cholmod.options["supernodal"] = supernodal
        try:
            return _cvx_cholmod.symbolic(self._spm, uplo="L")
        finally:
            if saved is None:
                del _cvx_cholmod.options["supernodal"]
            else:
                _cvx_cholmod.options["supernodal"] = saved

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
            margin = A.margin if isinstance(A, SplitMatrix) else None
            A = A.tocsr() if isinstance(A, SplitMatrix) else A
            self._ensure_analysis(A, None, margin)
            vals = self._cvxopt_values(A)
        self._spm.V = _cvxopt.matrix(vals)
        t0 = time.perf_counter()
        factor = self._factor
        try:
            try:
                _cvx_cholmod.numeric(self._spm, factor)
            except ArithmeticError:
                if self.mode != "hybrid":
                    raise
                # not positive definite: LDL', which solves it unless a pivot is zero
                self._last = None
                if self._factor_ldl is None:
                    t1 = time.perf_counter()
                    self._factor_ldl = self._cvxopt_symbolic(0)
                    self.time_analyse += time.perf_counter() - t1
                    t0 += time.perf_counter() - t1
                factor = self._factor_ldl
                self.n_ldl_fallbacks += 1
                _cvx_cholmod.numeric(self._spm, factor)
        except ArithmeticError as e:  # the column of the failed (zero or, LL', negative) pivot
            self._last = None  # the factor is overwritten in place
            self.time_factor += time.perf_counter() - t0
            raise NotPositiveDefinite(f"not positive definite (pivot of column {e})") from None
        self.n_factorizations += 1
        t1 = time.perf_counter()

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
                self._ensure_analysis(
                    A.base, A.extra if A.extra is not None else sp.coo_matrix(A.shape), A.margin
                )
                return self._solve_cvxopt(A, b)
            A, extra, margin = A.tocsr(), A.extra, A.margin
        else:
            margin = None
        A = A.tocsr()
        A.sort_indices()
        if self.backend == "cvxopt":
            self._ensure_analysis(A, extra, margin)
            return self._solve_cvxopt(A, b)
        if self.backend == "cholmod":
            self._ensure_analysis(A, extra, margin)
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
                s = _cholespy.CholeskySolverD(
                    n,
                    A.indptr.astype(np.int32),
                    A.indices.astype(np.int32),
                    np.ascontiguousarray(A.data),
                    _cholespy.MatrixType.CSR,
                )
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
