"""Newton's stopping rule: converged only with a small step *and* balanced forces;
stalled line searches and gradient fallbacks are counted and explained."""

import numpy as np
import pytest

from finray.fea.assembly import ElementBlock
from finray.fea.material import NeoHookean
from finray.fea.newton import NewtonOptions, newton
from finray.fea.problem import Model
from helpers import edge_load, rectangle_mesh

MAT = NeoHookean.from_E_nu(12.0, 0.45)


def strip(load=1.0):
    """10 x 2 mm strip clamped at x = 0, pulled down at x = 10 (N/mm)."""
    mesh = rectangle_mesh(np.linspace(0, 10, 11), np.linspace(0, 2, 3), order=2)
    X = mesh.points
    be = mesh.boundary_edges
    mid = 0.5 * (X[be[:, 0]] + X[be[:, 1]])
    tip = be[np.abs(mid[:, 0] - 10) < 1e-12]
    model = Model(
        X,
        [ElementBlock(mesh.triangles, MAT)],
        fixed_nodes=np.flatnonzero(np.abs(X[:, 0]) < 1e-12),
        external_force=edge_load(mesh, tip, [0.0, -0.05]),
    )
    model.load = load
    return model


@pytest.fixture(scope="module")
def solution():
    model = strip()
    res = newton(model, np.zeros(model.n), NewtonOptions(tol_dx=1e-12, tol_residual=1e-12))
    assert res.converged and res.residual <= 1e-12
    return res.q


def perturbed(model, q, size_mm=4e-5):
    """q moved by ``size_mm`` (infinity norm): Newton's step back is between tol_dx and
    100 tol_dx, where the old rule called a stalled line search converged."""
    d = np.random.default_rng(0).standard_normal(len(q))
    return q + size_mm * d / np.abs(d).max()


def no_decrease(model, q0):
    """Make every trial point's energy infinite (no trial point can decrease it): the
    line search evaluates its first trial with derivatives, later ones by energy."""
    evaluate = model.evaluate
    model.energy = lambda q: np.inf
    model.evaluate = lambda q, order=2, psd=None: (
        evaluate(q, order, psd) if np.array_equal(q, q0) else (np.inf, None, None)
    )


def test_stalled_line_search_is_not_converged(solution):
    model = strip()
    q0 = perturbed(model, solution)
    no_decrease(model, q0)
    opts = NewtonOptions(tol_residual=1e-6)
    res = newton(model, q0, opts)
    dx = res.history[0][2]
    assert opts.tol_dx < dx < 100 * opts.tol_dx  # the old rule would say "converged"
    assert res.residual > opts.tol_residual
    assert not res.converged
    assert "line search failed (no decrease)" in res.cause and "residual" in res.cause
    assert model.counters["line_search_failures"] == 1


def test_stalled_line_search_with_balanced_forces_converges_with_a_note(solution):
    model = strip()
    q0 = perturbed(model, solution)
    no_decrease(model, q0)
    res = newton(model, q0, NewtonOptions(tol_residual=1.0))
    assert res.converged and "line search stalled" in res.note
    assert model.counters["line_search_failures"] == 1


def test_small_step_alone_is_not_convergence():
    """With a huge step tolerance only the residual criterion can stop Newton."""
    model = strip()
    opts = NewtonOptions(tol_dx=1e3, tol_residual=1e-8)
    res = newton(model, np.zeros(model.n), opts)
    assert res.converged and res.iterations > 1
    assert res.residual <= opts.tol_residual
    # reported: the last assembled state; the returned one (after the final tiny
    # step) is at least as balanced
    assert model.residual_norm(model.evaluate(res.q, 1)[1]) <= opts.tol_residual
    assert {
        k: model.counters[k]
        for k in ("line_search_failures", "gradient_fallbacks", "residual_max_rel")
    } == {"line_search_failures": 0, "gradient_fallbacks": 0, "residual_max_rel": res.residual}


def test_chord_steps_assemble_no_hessian_in_vain(solution):
    """A Hessian is assembled only where it is factorised, or at a line search's first
    trial that was then cut back (evaluated for the next iteration in case it is
    taken): chord iterations evaluate the gradient alone (order 1), a refused chord
    assembles it then. The solution is the one without chord steps, to Newton's
    tolerance."""
    found = {}
    for chord_dx in (0.0, 1e-2):
        model = strip()
        orders = []
        evaluate = model.evaluate
        model.evaluate = lambda q, order=2, psd=None: (
            orders.append(order) or evaluate(q, order, psd)
        )
        opts = NewtonOptions(tol_dx=1e-9, tol_residual=1e-9, chord_dx=chord_dx)
        res = newton(model, perturbed(model, solution, 0.05), opts)
        assert res.converged
        found[chord_dx] = res.q
        cut_back = sum(row[5] < row[4] for row in res.history)  # alpha < CCD's alpha
        assert (
            model.linsolve.n_factorizations
            <= orders.count(2)
            <= model.linsolve.n_factorizations + cut_back
        )
        if chord_dx:
            assert model.linsolve.n_resolves > 0 and orders.count(1) > 0
        else:
            assert model.linsolve.n_resolves == 0 and 1 not in orders
    np.testing.assert_allclose(found[1e-2], found[0.0], atol=1e-8)


def test_residual_is_relative_to_the_support_forces(solution):
    model = strip()
    g = model.evaluate(solution, 1)[1]
    # at the solution the clamp's reactions add to the applied load in the scale
    assert model.force_scale > np.linalg.norm(model.f_ext)
    g0 = model.evaluate(np.zeros(model.n), 1)[1]
    # unloaded start: the free nodes carry the whole load, no reaction yet
    assert model.residual_norm(g0) == pytest.approx(1.0, rel=1e-12)
    assert model.residual_norm(g) < 1e-10


def test_gradient_fallback_is_counted():
    model = strip()
    ascent = lambda A, b, extra=None: -b  # noqa: E731 - solves to +g: never a descent
    model.linsolve.solve = ascent
    newton(model, np.zeros(model.n), NewtonOptions(max_iterations=3))
    assert model.counters["gradient_fallbacks"] == 3


# -- the cvxopt backend (CHOLMOD from wheels) ----------------------------------------
def _spd(n=60, seed=0):
    import scipy.sparse as sp

    L = sp.random(n, n, density=0.05, random_state=seed)
    return (L @ L.T + 2.0 * sp.eye(n)).tocsr()


def test_cvxopt_backend_solves_spd_with_a_growing_pattern():
    """Solutions to 1e-10 with the analysis reused, extended by new (contact) entries
    and by an entry outside both the analysed pattern and ``extra``."""
    import scipy.sparse as sp
    from finray.fea import linear as S

    assert S.LinearSolver("auto").backend == ("cholmod" if S.HAVE_CHOLMOD else "cvxopt")
    A = _spd()
    n = A.shape[0]
    b = np.random.default_rng(1).normal(size=n)
    ls = S.LinearSolver("cvxopt")
    E = sp.csr_matrix(([0.5, 0.5, 1.0, 1.0], ([3, 40, 3, 40], [40, 3, 3, 40])), shape=(n, n))
    F = sp.csr_matrix(([0.3, 0.3, 1.0, 1.0], ([5, 50, 5, 50], [50, 5, 5, 50])), shape=(n, n))
    for M, extra in ((A, None), (2.0 * A, None), (A + E, E), (A + E + F, E)):
        x = ls.solve(M, b, extra)
        assert np.abs(M @ x - b).max() < 1e-10 * np.abs(b).max()
    assert ls.n_analyses == 3  # first, the new extra, the entry outside both
    assert ls.n_factorizations == 4


def test_cvxopt_backend_raises_not_positive_definite():
    """Supernodal LL' raises NotPositiveDefinite on an indefinite matrix; simplicial LDL'
    (as scikit-sparse's) solves it and raises on a zero pivot only, and so does the
    default "hybrid" (LL', LDL' where LL' fails), with the simplicial solution; all
    recover on the next SPD matrix (the Newton solver projects the Hessian on a raise
    and checks a direction for descent)."""
    import scipy.sparse as sp
    from finray.fea import linear as S

    A = _spd()
    n = A.shape[0]
    b = np.ones(n)
    indefinite = (A - 50.0 * sp.eye(n)).tocsr()
    ll = S.LinearSolver("cvxopt", mode="supernodal")
    with pytest.raises(S.NotPositiveDefinite, match="not positive definite"):
        ll.solve(indefinite, b)
    ldl = S.LinearSolver("cvxopt", mode="simplicial")
    x = ldl.solve(indefinite, b)
    assert np.abs(indefinite @ x - b).max() < 1e-10
    hybrid = S.LinearSolver("cvxopt")
    assert hybrid.mode == "hybrid"
    np.testing.assert_allclose(hybrid.solve(indefinite, b), x, rtol=0, atol=1e-10)
    assert hybrid.n_ldl_fallbacks == 1
    np.testing.assert_allclose(hybrid.resolve(b), x, rtol=0, atol=1e-10)  # with the LDL'
    d = np.ones(n)
    d[0] = 0.0
    for mode in ("simplicial", "hybrid"):
        with pytest.raises(S.NotPositiveDefinite, match="column 0"):
            S.LinearSolver("cvxopt", mode=mode).solve(sp.diags(d, format="csr"), b)
    for ls in (ll, ldl, hybrid):
        x = ls.solve(A, b)
        assert np.abs(A @ x - b).max() < 1e-10
    assert hybrid.n_ldl_fallbacks == 1  # SPD: LL'
    assert hybrid._last is not None and hybrid.resolve(b) is not None


def test_unknown_linear_solver_is_one_line():
    from finray.fea import linear as S

    with pytest.raises(ValueError, match="unknown linear solver 'mkl'"):
        S.LinearSolver("mkl")


def test_resolve_reuses_the_last_factorisation():
    """Every backend's resolve solves with the matrix it factorised last (None before any);
    a chord step is that solve for a new right-hand side."""
    import scipy.sparse as sp

    from finray.fea import linear as S

    backends = S.available_backends()
    n = 40
    A = sp.diags([-np.ones(n - 1), 2.5 * np.ones(n), -np.ones(n - 1)], [-1, 0, 1], format="csr")
    b1, b2 = np.arange(1.0, n + 1), np.cos(np.arange(n))
    for name in backends:
        ls = S.LinearSolver(name)
        assert ls.resolve(b1) is None
        x1 = ls.solve(A, b1)
        x2 = ls.resolve(b2)
        np.testing.assert_allclose(A @ x1, b1, atol=1e-10)
        np.testing.assert_allclose(A @ x2, b2, atol=1e-10)
        assert ls.n_factorizations == 1 and ls.n_resolves == 1


def test_cvxopt_pattern_is_the_union_of_base_and_contact_entries():
    """The analysed pattern (built as a cvxopt sum of the base and the extra entries) is
    the upper triangle of their union, sorted; a new contact entry re-analyses once."""
    import scipy.sparse as sp

    from finray.fea import linear as S

    n = 30
    base = sp.diags([-np.ones(n - 1), 3.0 * np.ones(n), -np.ones(n - 1)], [-1, 0, 1], format="csr")
    extra = sp.csr_matrix((np.full(4, -0.5), ([2, 17, 17, 2], [17, 2, 17, 2])), shape=(n, n))
    ls = S.LinearSolver("cvxopt")
    b = np.ones(n)
    ls.solve(base, b, extra=None)
    x = ls.solve(base + extra, b, extra=extra)
    np.testing.assert_allclose((base + extra) @ x, b, atol=1e-10)
    U = sp.triu(abs(base) + abs(extra), format="csr")  # the union's upper triangle
    U.sort_indices()
    assert np.array_equal(ls._upper[0], U.indptr) and np.array_equal(ls._upper[1], U.indices)
    assert ls.n_analyses == 2
    ls.solve(base + extra, b, extra=extra)
    assert ls.n_analyses == 2  # inside the analysed pattern: no new analysis


def test_tangent_predictor_is_newtons_first_step_without_a_factorisation(solution):
    """From the equilibrium at load 1, the load step's "tangent" prediction for load 1.02
    is Newton's first step there (solved with the factorisation of the Hessian at the
    equilibrium, which it reuses: no new one), to a state of lower potential than the
    unpredicted start."""
    from finray.fea.stepping import _predict_tangent

    model = strip()
    _, _, H = model.evaluate(solution, 2)
    model.linsolve.solve(H, np.ones(model.n))  # the last factorisation: H at the solution
    n_fact = model.linsolve.n_factorizations
    model.load = 1.02
    q_pred = _predict_tangent(model, solution, 0.02)
    assert model.linsolve.n_factorizations == n_fact and model.counters["predictor_solves"] == 1
    g_new = model.evaluate(solution, 1)[1]
    np.testing.assert_allclose(
        q_pred, solution + np.linalg.solve(H.tocsr().toarray(), -g_new), rtol=0, atol=1e-10
    )
    assert model.energy(q_pred) < model.energy(solution)  # a start nearer the minimum


def test_unknown_predictor_is_one_line():
    from finray.fea.stepping import StepOptions, march

    model = strip()
    with pytest.raises(ValueError, match="unknown predictor True"):
        march(
            model,
            np.zeros(model.n),
            lambda s: np.zeros(2),
            np.array([1.0]),
            StepOptions(predictor=True),
        )
