"""Element assembly: patch test, derivatives, cantilever against beam theory."""

import numpy as np
import pytest
from shapely.geometry import Polygon

from finray.fea.assembly import ElasticAssembler, ElementBlock
from finray.fea.material import NeoHookean
from finray.fea.newton import NewtonOptions, newton
from finray.fea.problem import Model
from finray.geometry.mesh import triangulate_polygon
from helpers import edge_load, plane_strain_modulus, q_from_U, rectangle_mesh

MAT = NeoHookean.from_E_nu(12.0, 0.45)
F0 = np.array([[1.12, 0.21], [-0.07, 0.93]])  # finite homogeneous deformation


def irregular_mesh(order):
    poly = Polygon(
        [(0, 0), (7, -1), (9, 4), (4, 8), (-1, 5)], holes=[[(3, 2), (3, 4), (5, 3.5), (5, 2.2)]]
    )
    mesh, _ = triangulate_polygon(poly, 1.0, 25.0, order=order)
    return mesh


def free_all_map(n_nodes):
    return np.arange(2 * n_nodes).reshape(n_nodes, 2), 2 * n_nodes


@pytest.mark.parametrize("order", [1, 2])
def test_patch_homogeneous_deformation(order):
    mesh = irregular_mesh(order)
    X = mesh.points
    U = X @ (F0 - np.eye(2)).T
    dof_map, n = free_all_map(len(X))
    asm = ElasticAssembler(X, [ElementBlock(mesh.triangles, MAT)], dof_map, n)
    E, g, _ = asm.evaluate(U, 1)
    area = asm.areas.sum()
    assert E == pytest.approx(float(MAT.energy(F0[None])[0]) * area, rel=1e-13)
    bnodes = np.unique(mesh.boundary_edges[mesh.boundary_edges >= 0])
    inner = np.setdiff1d(np.arange(len(X)), bnodes)
    scale = np.abs(MAT.evaluate(F0[None], 1)[1]).max()
    assert np.abs(g.reshape(-1, 2)[inner]).max() < 1e-13 * scale
    # the boundary forces are the tractions P N of the homogeneous state: they sum to 0
    assert np.abs(g.reshape(-1, 2).sum(axis=0)).max() < 1e-12 * scale
    # recovered nodal stress is the exact homogeneous Cauchy stress
    sig, szz = MAT.cauchy(F0[None])
    st = asm.nodal_stress(U)
    np.testing.assert_allclose(st["sxx"], sig[0, 0, 0], rtol=1e-12)
    np.testing.assert_allclose(st["sxy"], sig[0, 0, 1], rtol=1e-12)
    np.testing.assert_allclose(st["szz"], szz[0], rtol=1e-12)

    # Newton with the boundary prescribed recovers the homogeneous field exactly
    model = Model(X, [ElementBlock(mesh.triangles, MAT)], fixed_nodes=bnodes)
    model.U_presc[bnodes] = U[bnodes]
    rng = np.random.default_rng(0)
    q0 = q_from_U(model, U + 0.02 * rng.standard_normal(U.shape))
    res = newton(model, q0, NewtonOptions(tol_dx=1e-13))
    assert res.converged
    assert np.abs(model.U(res.q) - U).max() < 1e-12


def test_fused_kernel_matches_numpy_reference():
    mesh = irregular_mesh(2)
    X = mesh.points
    dof_map, n = free_all_map(len(X))
    asm = ElasticAssembler(X, [ElementBlock(mesh.triangles, MAT)], dof_map, n)
    U = 0.05 * np.random.default_rng(1).standard_normal(X.shape)
    for psd in (False, True):
        E1, g1, h1 = asm.evaluate(U, 2, psd)
        E2, g2, h2 = asm.evaluate_numpy(U, 2, psd)
        assert E1 == pytest.approx(E2, rel=1e-13)
        np.testing.assert_allclose(g1, g2, atol=1e-12 * np.abs(g2).max())
        np.testing.assert_allclose(h1, h2, atol=1e-12 * np.abs(h2).max())


@pytest.mark.parametrize("order", [1, 2])
def test_elastic_gradient_and_hessian_vs_finite_differences(order):
    mesh = irregular_mesh(order)
    X = mesh.points
    dof_map, n = free_all_map(len(X))
    asm = ElasticAssembler(X, [ElementBlock(mesh.triangles, MAT)], dof_map, n)
    rng = np.random.default_rng(2)
    U = X @ (F0 - np.eye(2)).T + 0.05 * rng.standard_normal(X.shape)
    E, g, hd = asm.evaluate(U, 2, psd=False)
    H = asm.pattern.matrix(hd)
    h = 1e-6
    for _ in range(3):
        v = rng.standard_normal(U.shape)
        Ep = asm.energy(U + h * v)
        Em = asm.energy(U - h * v)
        assert (Ep - Em) / (2 * h) == pytest.approx(g @ v.ravel(), rel=1e-6)
        gp = asm.evaluate(U + h * v, 1)[1]
        gm = asm.evaluate(U - h * v, 1)[1]
        np.testing.assert_allclose(
            (gp - gm) / (2 * h), H @ v.ravel(), rtol=1e-6, atol=1e-6 * np.abs(H @ v.ravel()).max()
        )


def test_cantilever_tip_deflection_matches_beam_theory():
    """40 x 1.5 mm strip clamped at x = 0, end shear P: delta = P L^3 / (3 E' I)."""
    L, h, P = 40.0, 1.5, 1e-5  # P in N per mm of thickness
    mesh = rectangle_mesh(np.linspace(0, L, 81), np.linspace(0, h, 4), order=2)
    X = mesh.points
    clamp = np.where(np.abs(X[:, 0]) < 1e-12)[0]
    be = mesh.boundary_edges
    mid = 0.5 * (X[be[:, 0]] + X[be[:, 1]])
    tip_edges = be[np.abs(mid[:, 0] - L) < 1e-12]
    model = Model(
        X,
        [ElementBlock(mesh.triangles, MAT)],
        fixed_nodes=clamp,
        external_force=edge_load(mesh, tip_edges, [0.0, -P / h]),
    )
    model.load = 1.0
    res = newton(model, np.zeros(model.n))
    assert res.converged
    U = model.U(res.q)
    tip = np.where((np.abs(X[:, 0] - L) < 1e-12) & (np.abs(X[:, 1] - h / 2) < 1e-12))[0]
    delta = -U[tip, 1][0]
    theory = P * L**3 / (3 * plane_strain_modulus(MAT) * h**3 / 12)
    assert delta == pytest.approx(theory, rel=0.02)
