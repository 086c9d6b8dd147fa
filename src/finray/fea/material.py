"""Hyperelastic material laws for 2D plane strain (units: mm, N, MPa).

Stresses and moduli are in MPa (= N/mm^2); the strain-energy density ``W`` is in
MPa (= N mm / mm^3), so that integrating it over the cross-section (mm^2) gives an
energy per unit out-of-plane thickness (N mm / mm = N).

Plane strain: the 3D deformation gradient is ``diag(F, 1)`` with ``F`` the 2x2
in-plane one, so ``I1 = tr(F^T F) + 1`` and ``J = det F``.

Compressible neo-Hookean (Ogden / Simo-Pister form, e.g. Bonet & Wood, *Nonlinear
Continuum Mechanics for FEA*, eq. 6.27)::

    W = mu/2 (I1 - 3) - mu ln J + lam/2 (ln J)^2
    P = mu (F - F^-T) + lam ln J F^-T
    dP/dF = mu I + (mu - lam ln J) F^-T (x) F^-1 (swap) + lam F^-T (x) F^-T

which reduces to linear elasticity with Lame constants ``mu, lam`` at small strain.

The constants (Young's modulus, Poisson's ratio, rigid or not) and their sources are
the config's ``materials:`` section (``config/config.yaml``); :func:`finray.fea.scene.material_law`
builds the law of a configured material.
"""

from __future__ import annotations

from dataclasses import dataclass

import numba as nb
import numpy as np


def gent_modulus_from_shore_a(shore_a: float) -> float:
    """Young's modulus (MPa) from Shore A hardness, Gent (1958)."""
    s = float(shore_a)
    return 0.0981 * (56.0 + 7.62336 * s) / (0.137505 * (254.0 - 2.54 * s))


def lame(E: float, nu: float) -> tuple[float, float]:
    """(mu, lambda) in MPa from Young's modulus (MPa) and Poisson's ratio."""
    mu = E / (2.0 * (1.0 + nu))
    lam = E * nu / ((1.0 + nu) * (1.0 - 2.0 * nu))
    return mu, lam


@dataclass(frozen=True)
class NeoHookean:
    """Compressible neo-Hookean law in plane strain; ``mu``, ``lam`` in MPa."""

    mu: float
    lam: float
    name: str = "neo_hookean"

    @classmethod
    def from_E_nu(cls, E: float, nu: float, name: str = "neo_hookean") -> "NeoHookean":
        mu, lam = lame(E, nu)
        return cls(mu, lam, name)

    @property
    def E(self) -> float:
        return self.mu * (3 * self.lam + 2 * self.mu) / (self.lam + self.mu)

    @property
    def nu(self) -> float:
        return self.lam / (2 * (self.lam + self.mu))

    # -- kinematics helpers -------------------------------------------------------
    @staticmethod
    def _det_inv(F: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        a, b, c, d = F[..., 0, 0], F[..., 0, 1], F[..., 1, 0], F[..., 1, 1]
        J = a * d - b * c
        inv = np.empty_like(F)
        inv[..., 0, 0] = d
        inv[..., 0, 1] = -b
        inv[..., 1, 0] = -c
        inv[..., 1, 1] = a
        with np.errstate(divide="ignore", invalid="ignore"):
            inv /= J[..., None, None]
        return J, inv

    # -- energy, stress, tangent --------------------------------------------------
    def energy(self, F: np.ndarray) -> np.ndarray:
        """Strain-energy density W (MPa) of (..., 2, 2) gradients; +inf where J <= 0."""
        J, _ = self._det_inv(F)
        I1 = np.einsum("...ij,...ij->...", F, F) + 1.0
        with np.errstate(divide="ignore", invalid="ignore"):
            lnJ = np.log(np.where(J > 0, J, 1.0))
        W = 0.5 * self.mu * (I1 - 3.0) - self.mu * lnJ + 0.5 * self.lam * lnJ**2
        return np.where(J > 0, W, np.inf)

    def evaluate(self, F: np.ndarray, order: int = 2):
        """(W, P, A) with A = dP/dF as (..., 2, 2, 2, 2) [i, J, k, L] (order >= 2).

        W is +inf where J <= 0 (then P and A are not meaningful).
        """
        J, Finv = self._det_inv(F)
        ok = J > 0
        lnJ = np.log(np.where(ok, J, 1.0))
        I1 = np.einsum("...ij,...ij->...", F, F) + 1.0
        W = 0.5 * self.mu * (I1 - 3.0) - self.mu * lnJ + 0.5 * self.lam * lnJ**2
        W = np.where(ok, W, np.inf)
        if order < 1:
            return W, None, None
        FinvT = np.swapaxes(Finv, -1, -2)
        P = self.mu * (F - FinvT) + (self.lam * lnJ)[..., None, None] * FinvT
        if order < 2:
            return W, P, None
        eye = np.eye(2)
        c1 = (self.mu - self.lam * lnJ)[..., None, None, None, None]
        # A_iJkL = mu d_ik d_JL + (mu - lam lnJ) Finv_Jk Finv_Li + lam Finv_Ji Finv_Lk
        A = (
            self.mu * np.einsum("ik,JL->iJkL", eye, eye)
            + c1 * np.einsum("...Jk,...Li->...iJkL", Finv, Finv)
            + self.lam * np.einsum("...Ji,...Lk->...iJkL", Finv, Finv)
        )
        return W, P, A

    def cauchy(self, F: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """In-plane Cauchy stress (..., 2, 2) and the out-of-plane sigma_zz (MPa)."""
        a, b, c, d = F[..., 0, 0], F[..., 0, 1], F[..., 1, 0], F[..., 1, 1]
        J = a * d - b * c
        lnJ = np.log(J)
        # sigma = P F^T / J = (mu (F F^T - I) + lam ln J I) / J; with F33 = 1,
        # sigma_zz = lam ln J / J
        sig = np.empty(F.shape)
        sig[..., 0, 0] = (self.mu * (a * a + b * b - 1.0) + self.lam * lnJ) / J
        sig[..., 1, 1] = (self.mu * (c * c + d * d - 1.0) + self.lam * lnJ) / J
        sig[..., 0, 1] = sig[..., 1, 0] = self.mu * (a * c + b * d) / J
        return sig, self.lam * lnJ / J


def von_mises(sig: np.ndarray, szz: np.ndarray) -> np.ndarray:
    """Von Mises stress (MPa) of a plane state with out-of-plane normal stress szz."""
    sxx, syy, sxy = sig[..., 0, 0], sig[..., 1, 1], sig[..., 0, 1]
    return np.sqrt(0.5 * ((sxx - syy) ** 2 + (syy - szz) ** 2 + (szz - sxx) ** 2) + 3.0 * sxy**2)


@nb.njit(cache=True)
def _project_psd_inplace(M: np.ndarray, eps: float) -> int:
    """Clamp eigenvalues of each symmetric 4x4 M[n] at eps (in place); returns count.

    A Cholesky attempt first: only matrices that fail it are eigen-decomposed.
    """
    count = 0
    L = np.empty((4, 4))
    for n in range(M.shape[0]):
        for i in range(4):
            for j in range(i + 1, 4):
                v = 0.5 * (M[n, i, j] + M[n, j, i])
                M[n, i, j] = v
                M[n, j, i] = v
        ok = True
        for j in range(4):
            s = M[n, j, j]
            for k in range(j):
                s -= L[j, k] * L[j, k]
            if s <= eps:
                ok = False
                break
            L[j, j] = np.sqrt(s)
            for i in range(j + 1, 4):
                t = M[n, i, j]
                for k in range(j):
                    t -= L[i, k] * L[j, k]
                L[i, j] = t / L[j, j]
        if ok:
            continue
        count += 1
        w, V = np.linalg.eigh(M[n].copy())
        for i in range(4):
            if w[i] < eps:
                w[i] = eps
        for i in range(4):
            for j in range(4):
                s = 0.0
                for k in range(4):
                    s += V[i, k] * w[k] * V[j, k]
                M[n, i, j] = s
    return count


def project_tangent_psd(A: np.ndarray, eps: float = 0.0) -> np.ndarray:
    """Clamp the eigenvalues of the 4x4 material tangents (..., 2, 2, 2, 2) at ``eps``.

    A PSD material tangent gives PSD element stiffness matrices (K = B^T A B), the
    standard fix (e.g. Teran et al. 2005) for an indefinite Hessian of a
    hyperelastic energy in Newton's method. Returns a projected copy.
    """
    shp = A.shape
    M = np.ascontiguousarray(A.reshape(-1, 4, 4), dtype=float).copy()
    _project_psd_inplace(M, float(eps))
    return M.reshape(shp)
