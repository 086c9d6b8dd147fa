"""Contact: derivatives of the total energy, 2D Hertz, Coulomb sliding."""

import numpy as np
import pytest

from finray.fea.assembly import ElementBlock
from finray.fea.contact import ContactModel, ContactParams, split_p2_edges
from finray.fea.material import NeoHookean
from finray.fea.newton import NewtonOptions
from finray.fea.problem import Model
from finray.fea.stepping import StepOptions, march
from helpers import (
    arc_polyline,
    circle_polyline,
    graded_coords,
    plane_strain_modulus,
    rectangle_mesh,
    segment_polyline,
)

MAT = NeoHookean.from_E_nu(12.0, 0.45)


def top_edges(mesh, y, xmin=-np.inf, xmax=np.inf):
    X = mesh.points
    be = mesh.boundary_edges
    mid = 0.5 * (X[be[:, 0]] + X[be[:, 1]])
    keep = (np.abs(mid[:, 1] - y) < 1e-9) & (mid[:, 0] > xmin) & (mid[:, 0] < xmax)
    return be[keep]


def block_and_rigid(
    mesh, rigid_pts, rigid_edges, contact_edges, params, fixed, driver_k=1e5, rigid_driven=True
):
    """Elastic block (nodes 0..N-1) + rigid polyline (driven, or static)."""
    N = len(mesh.points)
    pts = np.vstack([mesh.points, rigid_pts])
    segs = np.vstack([split_p2_edges(contact_edges), rigid_edges + N])
    body = np.r_[np.zeros(N, int), np.ones(len(rigid_pts), int)]
    cm = ContactModel(pts, segs, body, rigid_bodies=[1], params=params)
    rigid = np.arange(N, len(pts))
    model = Model(
        pts,
        [ElementBlock(mesh.triangles, MAT)],
        fixed_nodes=fixed,
        driven_nodes=rigid if rigid_driven else (),
        contact=cm,
        driver_stiffness=driver_k,
    )
    return model, cm


def test_total_energy_gradient_and_hessian_vs_finite_differences():
    """Elastic + barrier + lagged friction, exact (unprojected) Hessian."""
    mesh = rectangle_mesh(np.linspace(-2, 2, 9), np.linspace(-1.5, 0, 4), order=2)
    R, dhat = 2.0, 0.02
    cp, ce = circle_polyline([0.0, R + 0.012], R, 160)
    fixed = np.where(np.abs(mesh.points[:, 1] + 1.5) < 1e-9)[0]
    model, cm = block_and_rigid(
        mesh,
        cp,
        ce,
        top_edges(mesh, 0.0),
        ContactParams(dhat=dhat, kappa=0.5, mu=0.3, eps_v=1e-3),
        fixed,
        driver_k=1.0,
    )
    rng = np.random.default_rng(0)
    q_lag = np.zeros(model.n)
    q_lag[model.t_index] = [0.0, -0.005]  # the circle 7 um from the block: active pairs
    cm.update_friction(model.U(q_lag))
    model.U_step_start = model.U(q_lag)
    model.t_target = np.array([0.01, -0.006])
    # a state with slip (sliding and sticking pairs) and small elastic deformation
    q = q_lag.copy()
    q[: model.n_free_dofs] = 1e-4 * rng.standard_normal(model.n_free_dofs)
    q[model.t_index] = [0.004, -0.0055]
    assert cm.pairs(model.U(q))["d"].size > 5
    assert cm._tangential is not None and len(cm._tangential) > 5
    E, g, H = model.evaluate(q, 2, psd=False)
    h = 1e-7
    for _ in range(4):
        v = rng.standard_normal(model.n)
        v /= np.abs(v).max()
        fd = (model.energy(q + h * v) - model.energy(q - h * v)) / (2 * h)
        assert fd == pytest.approx(g @ v, rel=1e-5, abs=1e-9)
        gp = model.evaluate(q + h * v, 1, psd=False)[1]
        gm = model.evaluate(q - h * v, 1, psd=False)[1]
        Hv = H @ v
        np.testing.assert_allclose((gp - gm) / (2 * h), Hv, atol=2e-5 * np.abs(Hv).max())


def test_hertz_contact_half_width():
    """Frictionless rigid cylinder (R = 10 mm) on a 20 x 10 mm block, plane strain:
    a = sqrt(4 P R / (pi E*)), E* = E / (1 - nu^2) (rigid indenter)."""
    W, H, R, gap, delta = 10.0, 10.0, 10.0, 0.05, 0.2
    x = graded_coords(-W, W, 80, 0.95, "both")
    y = graded_coords(-H, 0.0, 40, 0.92, "b")
    mesh = rectangle_mesh(x, y, order=2)
    cp, ce = arc_polyline([0.0, R + gap], R, -np.pi / 2 - 0.5, -np.pi / 2 + 0.5, 400)
    fixed = np.where(np.abs(mesh.points[:, 1] + H) < 1e-9)[0]
    model, cm = block_and_rigid(
        mesh,
        cp,
        ce,
        top_edges(mesh, 0.0, -5, 5),
        ContactParams(dhat=0.01, kappa=1.0, mu=0.0),
        fixed,
    )
    q = march(
        model,
        np.zeros(model.n),
        lambda s: [0.0, -(gap + delta) * s],
        [1.0],
        StepOptions(initial_step=0.5, max_step=0.5),
        friction=False,
    )
    N = len(mesh.points)
    U = model.U(q)
    _, gc, _ = cm.evaluate(U, None, 1)
    gf = np.zeros(2 * len(model.points))
    gf[model.coll_full] += gc
    fy = gf.reshape(-1, 2)[:N, 1]  # force on the block: -grad, downwards -> gc_y > 0
    P = fy.sum()
    xs = (mesh.points + U[:N])[:, 0]
    a = 2.0 * np.sqrt((xs**2 * fy).sum() / P)  # Hertz: <x^2>_p = a^2 / 4
    a_hertz = np.sqrt(4 * P * R / (np.pi * plane_strain_modulus(MAT)))
    assert a_hertz > 0.5  # resolved by ~10 surface elements
    assert a == pytest.approx(a_hertz, rel=0.05)
    # the indenter force equals the support reaction
    Fobj = model.contact_force(q, np.arange(N, len(model.points)))
    Rbase = model.elastic_force(q, fixed)
    np.testing.assert_allclose(Fobj, Rbase, rtol=5e-3, atol=1e-6 * abs(P))


def test_block_dragged_under_normal_load_slips_at_mu_N():
    """Elastic block pressed on a rigid floor, then dragged: T = mu N once it slides."""
    mu = 0.15
    mesh = rectangle_mesh(np.linspace(0, 6, 13), np.linspace(0.01, 2.01, 5), order=2)
    fp, fe = segment_polyline([-5.0, 0.0], [20.0, 0.0], 100)
    X = mesh.points
    top = np.where(np.abs(X[:, 1] - 2.01) < 1e-9)[0]
    N = len(X)
    pts = np.vstack([X, fp])
    segs = np.vstack([split_p2_edges(top_edges(mesh, 0.01)), fe + N])
    body = np.r_[np.zeros(N, int), np.ones(len(fp), int)]
    cm = ContactModel(
        pts,
        segs,
        body,
        rigid_bodies=[1],
        params=ContactParams(dhat=0.01, kappa=1.0, mu=mu, eps_v=1e-4),
    )
    model = Model(pts, [ElementBlock(mesh.triangles, MAT)], driven_nodes=top, contact=cm)
    press, slide = 0.06, 1.0

    def path(s):  # press during the first 30 %, then slide
        if s <= 0.3:
            return [0.0, -press * s / 0.3]
        return [slide * (s - 0.3) / 0.7, -press]

    frames = [0.3, 0.65, 1.0]
    out = []
    floor = np.arange(N, len(pts))

    def on_frame(k, s, q, info):
        out.append(model.contact_force(q, floor))

    march(
        model,
        np.zeros(model.n),
        path,
        frames,
        StepOptions(initial_step=0.1, max_step=0.1, friction_lag_iterations=4),
        NewtonOptions(tol_dx=1e-7),
        on_frame=on_frame,
    )
    T, Nn = out[-1]
    assert Nn < -0.5  # the block pushes the floor down (force on the floor)
    assert abs(T) / abs(Nn) == pytest.approx(mu, rel=0.02)
    assert T > 0  # friction drags the floor along +x


def test_linear_solver_backends_agree():
    """CHOLMOD (scikit-sparse's or cvxopt's, reused analysis), cholespy and SuperLU give
    the same contact solution."""
    from finray.fea import linear as S

    backends = S.available_backends()
    mesh = rectangle_mesh(np.linspace(-3, 3, 13), np.linspace(-2, 0, 5), order=2)
    cp, ce = circle_polyline([0.0, 3.05], 3.0, 200)
    fixed = np.where(np.abs(mesh.points[:, 1] + 2) < 1e-9)[0]
    forces = []
    for b in backends:
        model, cm = block_and_rigid(
            mesh, cp, ce, top_edges(mesh, 0.0), ContactParams(dhat=0.01, kappa=1.0, mu=0.15), fixed
        )
        model.linsolve = S.LinearSolver(b)
        q = march(
            model,
            np.zeros(model.n),
            lambda s: [0.2 * s, -0.25 * s],
            [1.0],
            StepOptions(initial_step=0.5, max_step=0.5),
        )
        forces.append(model.contact_force(q, np.arange(len(mesh.points), len(model.points))))
    assert np.abs(forces[0][1]) > 0.1
    for f in forces[1:]:
        np.testing.assert_allclose(f, forces[0], rtol=1e-4)  # to the Newton tolerance


def test_contact_evaluation_is_bit_reproducible():
    """The same state gives bit-identical energy, gradient, Hessian and pairs every call
    (ipctk runs serially: its parallel sums depended on the thread schedule)."""
    mesh = rectangle_mesh(np.linspace(-4, 4, 161), np.linspace(-1, 0, 3), order=2)
    cp, ce = segment_polyline([-4.5, 0.008], [4.5, 0.008], 900)
    fixed = np.where(np.abs(mesh.points[:, 1] + 1.0) < 1e-9)[0]
    model, cm = block_and_rigid(
        mesh, cp, ce, top_edges(mesh, 0.0), ContactParams(dhat=0.02, kappa=0.5, mu=0.3), fixed
    )
    U0 = np.zeros_like(model.points)
    U = U0.copy()
    U[: len(mesh.points)] = 1e-3 * np.random.default_rng(1).standard_normal((len(mesh.points), 2))
    cm.update_friction(U0)
    runs = [cm.evaluate(U, U0) for _ in range(30)]
    E0, g0, H0 = runs[0]
    assert len(cm.pairs(U)["d"]) > 500 and cm._tangential is not None
    for E, g, H in runs[1:]:
        assert E == E0 and np.array_equal(g, g0)
        assert np.array_equal(H.indptr, H0.indptr) and np.array_equal(H.indices, H0.indices)
        assert np.array_equal(H.data, H0.data)
    p0 = cm.pairs(U)
    for _ in range(10):
        p = cm.pairs(U)
        assert all(np.array_equal(p[k], p0[k]) for k in p0)


def test_reused_broad_phase_candidates_find_every_pair():
    """Candidates found at rest are reused for a state in which every vertex moved by
    up to the margin: two segments 2 x 0.99 margin + 0.999 dhat apart, moved towards
    each other, touch within dhat and are found, as a fresh broad phase finds them."""
    dhat = 0.02
    m = ContactModel.CANDIDATE_MARGIN_MM
    h = dhat + 2 * 0.99 * m - 0.001 * dhat
    pts = np.array([[-1.0, 0.0], [1.0, 0.0], [-1.0, h], [1.0, h]])
    segs = np.array([[0, 1], [3, 2]])
    params = ContactParams(dhat=dhat, kappa=1.0, mu=0.0)
    cm = ContactModel(pts, segs, np.array([0, 0, 1, 1]), params=params)
    U0 = np.zeros((4, 2))
    assert cm.energy(U0) == 0.0  # apart at rest: no pair, candidates kept
    U = np.array([[0.0, 1.0], [0.0, 1.0], [0.0, -1.0], [0.0, -1.0]]) * 0.99 * m
    E = cm.energy(U)
    assert cm._cand[0] is not None and np.array_equal(cm._cand[1], cm.vertices(U0))  # reused
    fresh = ContactModel(pts, segs, np.array([0, 0, 1, 1]), params=params)
    assert E > 0 and E == pytest.approx(fresh.energy(U), rel=1e-12)
    assert cm.pairs(U)["d"].size == fresh.pairs(U)["d"].size > 0


def test_small_steps_skip_the_ccd_and_agree_with_it():
    """Two segments 0.01 mm apart (inside dhat): a step that moves each towards the other
    by less than SAFE_MOVE of the gap is whole without a CCD, as ipctk's CCD also finds;
    a larger step goes to the CCD (which cuts it where they would touch); without an
    evaluation at the step's start the CCD runs."""
    import ipctk

    gap = 0.01
    pts = np.array([[-1.0, 0.0], [1.0, 0.0], [-1.0, gap], [1.0, gap]])
    segs = np.array([[0, 1], [3, 2]])
    cm = ContactModel(pts, segs, np.array([0, 0, 1, 1]), params=ContactParams(dhat=0.02, mu=0.0))
    calls = []
    ccd = ipctk.compute_collision_free_stepsize
    U0 = np.zeros((4, 2))

    def towards(move):
        return np.array([[0.0, 1.0], [0.0, 1.0], [0.0, -1.0], [0.0, -1.0]]) * move

    def full(U1):
        return ccd(cm.mesh, cm.vertices(U0), cm.vertices(U1), 0.0, cm.broad_phase, cm.ccd)

    import finray.fea.contact as C

    try:
        C.ipctk.compute_collision_free_stepsize = lambda *a: calls.append(1) or ccd(*a)
        cm.energy(U0)
        small = towards(0.99 * ContactModel.SAFE_MOVE * gap)
        assert cm.max_step(U0, small) == 1.0 == full(small) and not calls
        near = towards(0.49 * gap)  # closes to 2 % of the gap: the CCD's, whole
        assert cm.max_step(U0, near) == 1.0 and len(calls) == 1
        large = towards(0.6 * gap)  # they would cross: cut
        alpha = cm.max_step(U0, large)
        assert len(calls) == 2 and 0.0 < alpha < 1.0 and alpha == full(large)
        cm.energy(towards(1e-4))  # the last evaluation is elsewhere
        assert cm.max_step(U0, small) == 1.0 and len(calls) == 3
    finally:
        C.ipctk.compute_collision_free_stepsize = ccd


def test_near_pairs_hold_the_contact_hessian_pattern():
    """The pattern the linear solver analyses ahead (pairs within dhat + the margin) holds
    every Hessian entry of the pairs within dhat, and pairs up to the margin beyond; an
    analysis with it needs no new one while the circle closes in."""
    import scipy.sparse as sp

    mesh = rectangle_mesh(np.linspace(-2, 2, 9), np.linspace(-1.5, 0, 4), order=2)
    R, dhat = 2.0, 0.02
    cp, ce = circle_polyline([0.0, R + 0.012], R, 160)
    fixed = np.where(np.abs(mesh.points[:, 1] + 1.5) < 1e-9)[0]
    model, cm = block_and_rigid(
        mesh, cp, ce, top_edges(mesh, 0.0), ContactParams(dhat=dhat, kappa=0.5, mu=0.0), fixed
    )
    n = model.n

    def keys(q):
        _, _, H = model.evaluate(q, 2)
        e = H.extra.tocoo()
        r, c = H.margin()
        return set(e.row.astype(np.int64) * n + e.col), set(r * n + c), H

    q = np.zeros(model.n)
    q[model.t_index] = [0.0, -0.005]  # 7 um gap: pairs within dhat
    within, ahead, H = keys(q)
    assert len(within) > 2 and within <= ahead
    far = np.zeros(model.n)
    far[model.t_index] = [0.0, 0.08]  # 92 um: no pair within dhat, all within the margin
    within_far, ahead_far, _ = keys(far)
    assert within_far <= {int(k) for k in model.t_index * n + model.t_index}  # driver only
    assert within <= ahead_far
    # analysed once at the far state, the closing contact fits its pattern
    _, _, H_far = model.evaluate(far, 2)
    model.linsolve.solve(H_far, np.ones(n))
    analyses = model.linsolve.n_analyses
    model.linsolve.solve(H, np.ones(n))
    assert model.linsolve.n_analyses == analyses
    assert isinstance(H.base, sp.csr_matrix)
