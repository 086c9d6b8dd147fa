"""Constitutive law: consistency of energy, stress and tangent; small-strain limit."""

import numpy as np
import pytest

from finray.fea.material import (
    NeoHookean,
    gent_modulus_from_shore_a,
    lame,
    project_tangent_psd,
    von_mises,
)


@pytest.fixture
def mat():
    return NeoHookean.from_E_nu(12.0, 0.45)


def random_F(n, scale=0.3, seed=0):
    rng = np.random.default_rng(seed)
    return np.eye(2) + scale * rng.standard_normal((n, 2, 2))


def test_pk1_and_tangent_match_finite_differences(mat):
    F = random_F(20)
    F = F[np.linalg.det(F) > 0.3]
    W, P, A = mat.evaluate(F)
    h = 1e-6
    for i in range(2):
        for j in range(2):
            dF = np.zeros((2, 2))
            dF[i, j] = h
            dW = (mat.energy(F + dF) - mat.energy(F - dF)) / (2 * h)
            np.testing.assert_allclose(P[:, i, j], dW, rtol=1e-7, atol=1e-7)
            dP = (mat.evaluate(F + dF, 1)[1] - mat.evaluate(F - dF, 1)[1]) / (2 * h)
            np.testing.assert_allclose(A[:, :, :, i, j], dP, rtol=1e-6, atol=1e-6)


def test_small_strain_limit_is_plane_strain_linear_elasticity(mat):
    _, P, A = mat.evaluate(np.eye(2)[None])
    np.testing.assert_allclose(P, 0.0, atol=1e-14)
    mu, lam = lame(12.0, 0.45)
    C = np.zeros((2, 2, 2, 2))
    d = np.eye(2)
    for i, j, k, l in np.ndindex(2, 2, 2, 2):
        C[i, j, k, l] = lam * d[i, j] * d[k, l] + mu * (d[i, k] * d[j, l] + d[i, l] * d[j, k])
    # on symmetric (strain) arguments the tangent acts as the elasticity tensor
    eps = np.array([[1e-3, 2e-4], [2e-4, -5e-4]])
    np.testing.assert_allclose(
        np.einsum("ijkl,kl->ij", A[0], eps), np.einsum("ijkl,kl->ij", C, eps), rtol=1e-12
    )
    # plane strain: uniaxial stress in x needs sigma_zz = nu (sxx + syy)
    sig, szz = mat.cauchy(np.eye(2)[None] + np.array([[[1e-6, 0], [0, 0]]]))
    assert szz[0] == pytest.approx(mat.nu * (sig[0, 0, 0] + sig[0, 1, 1]), rel=1e-5)


def test_energy_is_objective_and_inversion_is_infinite(mat):
    F = random_F(5, 0.2, seed=3)
    th = 0.7
    R = np.array([[np.cos(th), -np.sin(th)], [np.sin(th), np.cos(th)]])
    np.testing.assert_allclose(mat.energy(R @ F), mat.energy(F), rtol=1e-12)
    assert np.isinf(mat.energy(np.diag([1.0, -0.5])[None]))[0]


def test_cauchy_stress_is_symmetric_and_von_mises_of_pure_shear(mat):
    F = random_F(10, 0.2, seed=1)
    sig, szz = mat.cauchy(F)
    np.testing.assert_allclose(sig, np.swapaxes(sig, 1, 2), atol=1e-12)
    s = np.zeros((1, 2, 2))
    s[0, 0, 1] = s[0, 1, 0] = 2.0
    assert von_mises(s, np.zeros(1))[0] == pytest.approx(np.sqrt(3) * 2.0)


def test_psd_projection(mat):
    F = np.array([[[0.6, 0.0], [0.0, 1.0]], [[1.0, 0.1], [0.0, 1.0]]])  # strong compression
    _, _, A = mat.evaluate(F)
    Ap = project_tangent_psd(A)
    for a, ap in zip(A.reshape(-1, 4, 4), Ap.reshape(-1, 4, 4)):
        w = np.linalg.eigvalsh(0.5 * (a + a.T))
        wp = np.linalg.eigvalsh(ap)
        assert wp.min() >= -1e-10
        if w.min() >= 0:  # already PSD: unchanged
            np.testing.assert_allclose(ap, a, atol=1e-12)
    assert np.linalg.eigvalsh(A.reshape(-1, 4, 4)[0]).min() < 0  # the test exercises a fix


def test_config_materials_have_sources_and_give_the_laws():
    """The default config's ``materials:`` is the one source of the constants."""
    from finray.config import default_config_path, load_config
    from finray.fea.scene import material_law

    cfg = load_config(default_config_path())
    mats = cfg["materials"]
    assert {"steel", "ninjaflex", "neoprene"} <= set(mats)
    for name, m in mats.items():
        assert m.get("source"), f"material {name} has no source"
    nf, neo = material_law(cfg, "ninjaflex"), material_law(cfg, "neoprene")
    assert nf.E == pytest.approx(mats["ninjaflex"]["youngs_modulus_MPa"])
    assert nf.nu == pytest.approx(mats["ninjaflex"]["poisson_ratio"])
    assert neo.E < nf.E
    with pytest.raises(ValueError, match="material steel is rigid"):
        material_law(cfg, "steel")
    # neoprene's modulus is Gent's relation at Shore A 60, as its source says
    assert "Shore A 60" in mats["neoprene"]["source"]
    assert gent_modulus_from_shore_a(60) == pytest.approx(
        mats["neoprene"]["youngs_modulus_MPa"], rel=0.01
    )
