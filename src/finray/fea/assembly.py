"""Vectorised total-Lagrangian assembly of hyperelastic triangles (mm, N, MPa).

Elements: 6-node quadratic triangles (corners 0, 1, 2 counter-clockwise, then the
mid-side nodes of edges (0,1), (1,2), (2,0)) with a 3-point Gauss rule (exact for
the stiffness of straight-sided P2 in linear elasticity), or 3-node linear
triangles with 1 point. The rule can be raised (``quad_degree=4``: 6 points).

The unknowns are a *reduced* DOF vector: every node DOF maps through ``dof_map``
(shape (N, 2)) to a reduced index, or to -1 when it is prescribed (clamped base,
rigidly driven nodes handled elsewhere). Several node DOFs may map to the same
reduced index (nodes slaved to a rigid translation).

Energy is per unit out-of-plane thickness (N mm / mm = N), gradients are nodal
forces per unit thickness (N/mm), Hessians are in N/mm^2.

The sparse pattern of the Hessian and the scatter index from element entries to
the CSR data array are computed once in :class:`ElasticAssembler`; each
evaluation only fills a new data array (``np.bincount``).
"""

from __future__ import annotations

from dataclasses import dataclass

import numba as nb
import numpy as np
import scipy.sparse as sp

from .material import NeoHookean, project_tangent_psd


# ----------------------------------------------------------------------------------
# Reference elements
# ----------------------------------------------------------------------------------
def gauss_rule(degree: int) -> tuple[np.ndarray, np.ndarray]:
    """Barycentric points (q, 3) and weights (q,) summing to 1 (times the area)."""
    if degree <= 1:
        return np.array([[1 / 3, 1 / 3, 1 / 3]]), np.array([1.0])
    if degree == 2:
        a, b = 2 / 3, 1 / 6
        return np.array([[a, b, b], [b, a, b], [b, b, a]]), np.full(3, 1 / 3)
    if degree <= 4:  # Strang-Fix / Dunavant 6-point, degree 4
        a1, b1, w1 = 0.816847572980459, 0.091576213509771, 0.109951743655322
        a2, b2, w2 = 0.108103018168070, 0.445948490915965, 0.223381589678011
        pts = [[a1, b1, b1], [b1, a1, b1], [b1, b1, a1], [a2, b2, b2], [b2, a2, b2], [b2, b2, a2]]
        return np.array(pts), np.array([w1] * 3 + [w2] * 3)
    raise ValueError(f"no Gauss rule of degree {degree}")


def shape_functions(nodes_per_element: int, L: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Shape functions N (q, n) and derivatives dN/d(xi, eta) (q, n, 2) at barycentric L.

    Reference coordinates: xi = L1, eta = L2, L0 = 1 - xi - eta.
    """
    L0, L1, L2 = L[:, 0], L[:, 1], L[:, 2]
    q = len(L)
    if nodes_per_element == 3:
        N = np.column_stack([L0, L1, L2])
        dN = np.broadcast_to(np.array([[-1.0, -1.0], [1.0, 0.0], [0.0, 1.0]]), (q, 3, 2)).copy()
        return N, dN
    if nodes_per_element == 6:
        N = np.column_stack(
            [
                L0 * (2 * L0 - 1),
                L1 * (2 * L1 - 1),
                L2 * (2 * L2 - 1),
                4 * L0 * L1,
                4 * L1 * L2,
                4 * L2 * L0,
            ]
        )
        # dL/dxi = (-1, 1, 0), dL/deta = (-1, 0, 1)
        dN = np.empty((q, 6, 2))
        g0 = 4 * L0 - 1
        dN[:, 0, 0] = -g0
        dN[:, 0, 1] = -g0
        dN[:, 1, 0] = 4 * L1 - 1
        dN[:, 1, 1] = 0.0
        dN[:, 2, 0] = 0.0
        dN[:, 2, 1] = 4 * L2 - 1
        dN[:, 3, 0] = 4 * (L0 - L1)
        dN[:, 3, 1] = -4 * L1
        dN[:, 4, 0] = 4 * L2
        dN[:, 4, 1] = 4 * L1
        dN[:, 5, 0] = -4 * L2
        dN[:, 5, 1] = 4 * (L0 - L2)
        return N, dN
    raise ValueError(f"unsupported element with {nodes_per_element} nodes")


#: Barycentric coordinates of the element nodes (for nodal stress recovery).
NODE_BARY = {
    3: np.eye(3),
    6: np.array(
        [[1, 0, 0], [0, 1, 0], [0, 0, 1], [0.5, 0.5, 0], [0, 0.5, 0.5], [0.5, 0, 0.5]], dtype=float
    ),
}


def reference_gradients(points: np.ndarray, tri: np.ndarray, dN: np.ndarray):
    """Physical shape gradients dN/dX (M, q, n, 2) and Jacobian determinants (M, q)."""
    X = points[tri]  # (M, n, 2)
    Jm = np.einsum("mnI,qna->mqIa", X, dN)  # dX_I / dxi_a
    det = Jm[..., 0, 0] * Jm[..., 1, 1] - Jm[..., 0, 1] * Jm[..., 1, 0]
    inv = np.empty_like(Jm)
    inv[..., 0, 0] = Jm[..., 1, 1]
    inv[..., 0, 1] = -Jm[..., 0, 1]
    inv[..., 1, 0] = -Jm[..., 1, 0]
    inv[..., 1, 1] = Jm[..., 0, 0]
    inv /= det[..., None, None]
    G = np.einsum("qna,mqaI->mqnI", dN, inv)  # dN/dX = dN/dxi . dxi/dX
    return G, det


# ----------------------------------------------------------------------------------
# Element kernels (numba, serial)
# ----------------------------------------------------------------------------------
@nb.njit(cache=True)
def _element_hessians(G, wdet, A, out):
    """out[m, 2a+i, 2b+k] = sum_q w G[a, J] A[i, J, k, L] G[b, L]."""
    M, q, n, _ = G.shape
    for m in range(M):
        for a in range(2 * n):
            for b in range(2 * n):
                out[m, a, b] = 0.0
        for p in range(q):
            w = wdet[m, p]
            for a in range(n):
                ga0 = G[m, p, a, 0]
                ga1 = G[m, p, a, 1]
                for i in range(2):
                    for k in range(2):
                        # c_L = sum_J G[a, J] A[i, J, k, L]
                        c0 = ga0 * A[m, p, i, 0, k, 0] + ga1 * A[m, p, i, 1, k, 0]
                        c1 = ga0 * A[m, p, i, 0, k, 1] + ga1 * A[m, p, i, 1, k, 1]
                        for b in range(n):
                            out[m, 2 * a + i, 2 * b + k] += w * (
                                c0 * G[m, p, b, 0] + c1 * G[m, p, b, 1]
                            )
    return out


@nb.njit(cache=True)
def _element_forces(G, wdet, P, out):
    """out[m, 2a+i] = sum_q w P[i, J] G[a, J]."""
    M, q, n, _ = G.shape
    for m in range(M):
        for a in range(2 * n):
            out[m, a] = 0.0
        for p in range(q):
            w = wdet[m, p]
            for a in range(n):
                for i in range(2):
                    out[m, 2 * a + i] += w * (
                        P[m, p, i, 0] * G[m, p, a, 0] + P[m, p, i, 1] * G[m, p, a, 1]
                    )
    return out


@nb.njit(cache=True)
def _nh_fused(tri, U, G, wdet, mu_e, lam_e, order, psd, pos, data, g_full):
    """Fused compressible neo-Hookean element loop (plane strain).

    Computes the energy (returned), adds nodal forces into g_full (2N,) when
    order >= 1 and element stiffness entries into the CSR data array through the
    scatter positions pos (M, 2n, 2n; -1 = dropped) when order >= 2. The material
    tangents are projected to PSD per Gauss point when ``psd``. Returns +inf if an
    element is inverted (J <= 0).
    """
    M, q, n, _ = G.shape
    E = 0.0
    A = np.empty((4, 4))
    L = np.empty((4, 4))
    c = np.empty((n, 2, 2, 2))  # c[a, i, k, L] = sum_J G[a, J] A[iJ, kL]
    for m in range(M):
        mu = mu_e[m]
        lam = lam_e[m]
        for p in range(q):
            w = wdet[m, p]
            f00 = 1.0
            f01 = 0.0
            f10 = 0.0
            f11 = 1.0
            for a in range(n):
                node = tri[m, a]
                ux = U[node, 0]
                uy = U[node, 1]
                g0 = G[m, p, a, 0]
                g1 = G[m, p, a, 1]
                f00 += ux * g0
                f01 += ux * g1
                f10 += uy * g0
                f11 += uy * g1
            J = f00 * f11 - f01 * f10
            if J <= 0.0:
                return np.inf
            lnJ = np.log(J)
            E += w * (
                0.5 * mu * (f00 * f00 + f01 * f01 + f10 * f10 + f11 * f11 - 2.0)
                - mu * lnJ
                + 0.5 * lam * lnJ * lnJ
            )
            if order < 1:
                continue
            # Finv[J, k]
            i00 = f11 / J
            i01 = -f01 / J
            i10 = -f10 / J
            i11 = f00 / J
            # P = mu (F - Finv^T) + lam lnJ Finv^T
            cl = lam * lnJ
            P00 = mu * (f00 - i00) + cl * i00
            P01 = mu * (f01 - i10) + cl * i10
            P10 = mu * (f10 - i01) + cl * i01
            P11 = mu * (f11 - i11) + cl * i11
            for a in range(n):
                node = tri[m, a]
                g0 = G[m, p, a, 0]
                g1 = G[m, p, a, 1]
                g_full[2 * node] += w * (P00 * g0 + P01 * g1)
                g_full[2 * node + 1] += w * (P10 * g0 + P11 * g1)
            if order < 2:
                continue
            Fi = ((i00, i01), (i10, i11))
            c1 = mu - lam * lnJ
            for i in range(2):
                for Jj in range(2):
                    for k in range(2):
                        for Ll in range(2):
                            v = c1 * Fi[Jj][k] * Fi[Ll][i] + lam * Fi[Jj][i] * Fi[Ll][k]
                            if i == k and Jj == Ll:
                                v += mu
                            A[2 * i + Jj, 2 * k + Ll] = v
            if psd:
                ok = True
                for j in range(4):
                    sj = A[j, j]
                    for k in range(j):
                        sj -= L[j, k] * L[j, k]
                    if sj <= 0.0:
                        ok = False
                        break
                    L[j, j] = np.sqrt(sj)
                    for i in range(j + 1, 4):
                        t = A[i, j]
                        for k in range(j):
                            t -= L[i, k] * L[j, k]
                        L[i, j] = t / L[j, j]
                if not ok:
                    wv, V = np.linalg.eigh(A.copy())
                    for i in range(4):
                        if wv[i] < 0.0:
                            wv[i] = 0.0
                    for i in range(4):
                        for j in range(4):
                            t = 0.0
                            for k in range(4):
                                t += V[i, k] * wv[k] * V[j, k]
                            A[i, j] = t
            for a in range(n):
                g0 = G[m, p, a, 0]
                g1 = G[m, p, a, 1]
                for i in range(2):
                    for k in range(2):
                        c[a, i, k, 0] = g0 * A[2 * i, 2 * k] + g1 * A[2 * i + 1, 2 * k]
                        c[a, i, k, 1] = g0 * A[2 * i, 2 * k + 1] + g1 * A[2 * i + 1, 2 * k + 1]
            for a in range(n):
                for i in range(2):
                    r = 2 * a + i
                    for b in range(n):
                        h0 = G[m, p, b, 0]
                        h1 = G[m, p, b, 1]
                        for k in range(2):
                            pp = pos[m, r, 2 * b + k]
                            if pp >= 0:
                                data[pp] += w * (c[a, i, k, 0] * h0 + c[a, i, k, 1] * h1)
    return E


# ----------------------------------------------------------------------------------
# Sparse pattern with a fixed scatter index
# ----------------------------------------------------------------------------------
@dataclass
class ScatterPattern:
    """CSR pattern of a sum of dense element blocks and the scatter of their entries."""

    n: int
    indptr: np.ndarray
    indices: np.ndarray
    entry_pos: np.ndarray  # for each kept element entry, its position in data
    entry_mask: np.ndarray  # (M * k * k,) which element entries are kept

    @classmethod
    def from_element_dofs(cls, edofs: np.ndarray, n: int) -> "ScatterPattern":
        """``edofs`` (M, k) reduced DOF indices of each element (-1 = prescribed)."""
        M, k = edofs.shape
        r = np.repeat(edofs, k, axis=1).ravel()
        c = np.tile(edofs, (1, k)).ravel()
        mask = (r >= 0) & (c >= 0)
        key = r[mask].astype(np.int64) * n + c[mask]
        uniq, inv = np.unique(key, return_inverse=True)
        rows = uniq // n
        indices = (uniq % n).astype(np.int32)
        indptr = np.zeros(n + 1, dtype=np.int64)
        np.add.at(indptr, rows + 1, 1)
        indptr = np.cumsum(indptr)
        return cls(n, indptr.astype(np.int32), indices, inv.ravel(), mask)

    @property
    def nnz(self) -> int:
        return len(self.indices)

    def positions(self, M: int, k: int) -> np.ndarray:
        """(M, k, k) position of each element entry in the data array (-1: dropped)."""
        pos = -np.ones(M * k * k, np.int64)
        pos[self.entry_mask] = self.entry_pos
        return pos.reshape(M, k, k)

    def data(self, Ke: np.ndarray) -> np.ndarray:
        """CSR data array of the assembled element matrices Ke (M, k, k)."""
        vals = Ke.reshape(-1)[self.entry_mask]
        return np.bincount(self.entry_pos, weights=vals, minlength=self.nnz)

    def matrix(self, data: np.ndarray) -> sp.csr_matrix:
        return sp.csr_matrix((data, self.indices, self.indptr), shape=(self.n, self.n))


# ----------------------------------------------------------------------------------
# Elastic assembler
# ----------------------------------------------------------------------------------
@dataclass
class ElementBlock:
    """Triangles (global node ids) that share one material law."""

    triangles: np.ndarray
    material: NeoHookean


class ElasticAssembler:
    """Energy, gradient and Hessian of the elastic energy of one or more bodies.

    Parameters
    ----------
    points : (N, 2) reference coordinates (mm) of all nodes of the problem.
    blocks : element blocks (triangles in global node numbering + material).
    dof_map : (N, 2) reduced DOF index of each node DOF, -1 if prescribed.
    n_dofs : size of the reduced system.
    quad_degree : Gauss rule degree (default 2 for P2, 1 for P1).
    """

    def __init__(
        self,
        points: np.ndarray,
        blocks: list[ElementBlock],
        dof_map: np.ndarray,
        n_dofs: int,
        quad_degree: int | None = None,
    ):
        self.points = np.asarray(points, float)
        self.blocks = blocks
        self.dof_map = np.asarray(dof_map)
        self.n_dofs = int(n_dofs)
        self.n_nodes = len(points)
        npe = {b.triangles.shape[1] for b in blocks}
        if len(npe) != 1:
            raise ValueError("all blocks must use the same element order")
        self.npe = npe.pop()
        if quad_degree is None:
            quad_degree = 2 if self.npe == 6 else 1
        L, self.qw = gauss_rule(quad_degree)
        self.N, dN = shape_functions(self.npe, L)
        self.tri = np.vstack([b.triangles for b in blocks]).astype(np.int64)
        self.block_slices = []
        s = 0
        for b in blocks:
            self.block_slices.append(slice(s, s + len(b.triangles)))
            s += len(b.triangles)
        self.G, det = reference_gradients(self.points, self.tri, dN)
        self._G_nodes = None  # shape gradients at the element nodes (nodal_stress)
        if (det <= 0).any():
            raise ValueError("inverted or degenerate reference elements")
        self.wdet = det * self.qw[None, :] * 0.5  # reference triangle area = 1/2
        n = self.npe
        # full (node) DOFs of each element, ordering [n0x, n0y, n1x, ...]
        self.edof_full = (2 * self.tri[:, :, None] + np.arange(2)[None, None, :]).reshape(-1, 2 * n)
        self.edof_red = self.dof_map.reshape(-1)[self.edof_full]
        self.pattern = ScatterPattern.from_element_dofs(self.edof_red, self.n_dofs)
        self.areas = self.wdet.sum(axis=1)
        # fused numba path (neo-Hookean blocks)
        self.fused = all(isinstance(b.material, NeoHookean) for b in blocks)
        if self.fused:
            self._pos = self.pattern.positions(len(self.tri), 2 * n)
            self._mu = np.concatenate([np.full(len(b.triangles), b.material.mu) for b in blocks])
            self._lam = np.concatenate([np.full(len(b.triangles), b.material.lam) for b in blocks])

    # -- kinematics ----------------------------------------------------------------
    def deformation_gradient(self, U: np.ndarray) -> np.ndarray:
        """F (M, q, 2, 2) for nodal displacements U (N, 2)."""
        Ue = U[self.tri]  # (M, n, 2)
        F = np.einsum("mni,mqnJ->mqiJ", Ue, self.G)
        F[..., 0, 0] += 1.0
        F[..., 1, 1] += 1.0
        return F

    def is_valid(self, U: np.ndarray) -> bool:
        F = self.deformation_gradient(U)
        J = F[..., 0, 0] * F[..., 1, 1] - F[..., 0, 1] * F[..., 1, 0]
        return bool((J > 0).all())

    # -- evaluation ----------------------------------------------------------------
    def energy(self, U: np.ndarray) -> float:
        if self.fused:
            return self._evaluate_fused(U, 0, False)[0]
        F = self.deformation_gradient(U)
        tot = 0.0
        for b, s in zip(self.blocks, self.block_slices):
            W = b.material.energy(F[s])
            tot += float((W * self.wdet[s]).sum())
        return tot

    def evaluate(self, U: np.ndarray, order: int = 2, psd: bool = True):
        """Energy (N), full nodal gradient (2N,) and reduced Hessian CSR data.

        ``order`` 0: energy only; 1: + gradient; 2: + Hessian data (pattern fixed,
        see :attr:`pattern`). ``psd`` projects the material tangents to PSD.
        Returns (E, g_full, H_data); E is +inf if an element is inverted.
        """
        if self.fused:
            return self._evaluate_fused(U, order, psd)
        return self.evaluate_numpy(U, order, psd)

    def _evaluate_fused(self, U, order, psd):
        U = np.ascontiguousarray(U, dtype=float)
        g = np.zeros(2 * self.n_nodes)
        data = np.zeros(self.pattern.nnz if order >= 2 else 1)
        E = _nh_fused(
            self.tri, U, self.G, self.wdet, self._mu, self._lam, order, psd, self._pos, data, g
        )
        if not np.isfinite(E):
            return np.inf, None, None
        return E, (g if order >= 1 else None), (data if order >= 2 else None)

    def evaluate_numpy(self, U: np.ndarray, order: int = 2, psd: bool = True):
        """Reference (numpy) implementation of :meth:`evaluate` for any material law."""
        F = self.deformation_gradient(U)
        M, q = F.shape[:2]
        n = self.npe
        W = np.empty((M, q))
        P = np.empty((M, q, 2, 2)) if order >= 1 else None
        A = np.empty((M, q, 2, 2, 2, 2)) if order >= 2 else None
        for b, s in zip(self.blocks, self.block_slices):
            w_, p_, a_ = b.material.evaluate(F[s], order)
            W[s] = w_
            if order >= 1:
                P[s] = p_
            if order >= 2:
                A[s] = a_
        E = float((W * self.wdet).sum())
        if order < 1 or not np.isfinite(E):
            return E, None, None
        # element forces f[a, i] = sum_q w P_iJ G_aJ
        fe = np.empty((M, 2 * n))
        _element_forces(self.G, self.wdet, np.ascontiguousarray(P), fe)
        g = np.bincount(self.edof_full.ravel(), weights=fe.ravel(), minlength=2 * self.n_nodes)
        if order < 2:
            return E, g, None
        if psd:
            A = project_tangent_psd(A)
        Ke = self.element_hessians(A)
        return E, g, self.pattern.data(Ke)

    def element_hessians(self, A: np.ndarray) -> np.ndarray:
        """Element stiffness matrices (M, 2n, 2n) from material tangents A (M, q, 2,2,2,2)."""
        M = A.shape[0]
        out = np.empty((M, 2 * self.npe, 2 * self.npe))
        _element_hessians(self.G, self.wdet, np.ascontiguousarray(A), out)
        return out

    def reduce_gradient(self, g_full: np.ndarray) -> np.ndarray:
        """Sum a full nodal vector (2N,) into the reduced DOFs."""
        dm = self.dof_map.reshape(-1)
        keep = dm >= 0
        return np.bincount(dm[keep], weights=g_full[keep], minlength=self.n_dofs)

    # -- stress recovery -----------------------------------------------------------
    def nodal_stress(self, U: np.ndarray) -> dict[str, np.ndarray]:
        """Nodal Cauchy stress (MPa), averaged over the elements sharing each node.

        Returns sxx, syy, sxy, szz (plane strain) and von Mises, each (N,), NaN at
        nodes of no element.
        """
        from .material import von_mises

        G = self._G_nodes
        if G is None:  # shape gradients at the element nodes: fixed, computed once
            _, dN = shape_functions(self.npe, NODE_BARY[self.npe])
            G = self._G_nodes = reference_gradients(self.points, self.tri, dN)[0]  # (M, n, n, 2)
            ids = self.tri.ravel()
            cnt = np.bincount(ids, minlength=self.n_nodes)
            # the mean over the elements sharing each node, as one sparse product
            self._node_mean = sp.csr_matrix(
                (1.0 / cnt[ids], (ids, np.arange(len(ids)))), shape=(self.n_nodes, len(ids))
            )
            self._no_element = cnt == 0
        # optimize=True swaps the operands: 5x faster here (same c_einsum, one thread)
        F = np.einsum("mni,mqnJ->mqiJ", U[self.tri], G, optimize=True)
        F[..., 0, 0] += 1.0
        F[..., 1, 1] += 1.0
        vals = np.empty(F.shape[:2] + (4,))
        for b, s in zip(self.blocks, self.block_slices):
            sig, szz = b.material.cauchy(F[s])
            vals[s] = np.stack([sig[..., 0, 0], sig[..., 1, 1], sig[..., 0, 1], szz], axis=-1)
        out = self._node_mean @ vals.reshape(-1, 4)
        out[self._no_element] = np.nan
        sig = np.zeros((self.n_nodes, 2, 2))
        sig[:, 0, 0], sig[:, 1, 1] = out[:, 0], out[:, 1]
        sig[:, 0, 1] = sig[:, 1, 0] = out[:, 2]
        vm = von_mises(sig, out[:, 3])
        return {
            "sxx": out[:, 0],
            "syy": out[:, 1],
            "sxy": out[:, 2],
            "szz": out[:, 3],
            "von_mises": vm,
        }
