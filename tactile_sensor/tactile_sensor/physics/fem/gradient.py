"""The element gradient operator: displacements to deformation gradients, stresses to nodal
forces and tangents to element matrices, as GEMMs on box elements."""

from __future__ import annotations

import numpy as np


class _GradientOperator:
    """u_e -> F at the quadrature points, and stress -> element forces, as two GEMMs.

    On the structured mesh every element is an axis-aligned box, so dN_a/dX_K at a quadrature
    point is the reference gradient scaled by 1/h_K: the gather over the 8 nodes becomes one
    (3 e x 8) @ (8 x 3 q) product instead of e*q tiny batched products. Any other mesh takes
    the general path.
    """

    def __init__(self, dndx: np.ndarray, w: np.ndarray, xe: np.ndarray) -> None:
        # xe: (3, 8, e) node coordinates per element
        self._dndx, self._w = dndx, w
        ne, nq = w.shape
        h = np.ptp(xe, axis=1).T                                      # (e, 3)
        ref = dndx[0] * h[0]                                          # (q, a, K)
        self._box = bool(np.allclose(dndx, ref[None] / h[:, None, None, :],
                                     rtol=1e-10, atol=0.0))
        # per-component GEMMs that read and write F's (e, q) slabs in place: the transposes
        # of one big GEMM cost more than the products (0.67 -> 0.39 ms and 0.56 -> 0.18 ms
        # per residual on the default mesh)
        self._ref_kq = np.ascontiguousarray(ref.transpose(1, 2, 0).reshape(8, 3 * nq))
        self._ref_qa = [np.ascontiguousarray(ref[:, :, k]) for k in range(3)]  # (q, a)
        hinv = 1.0 / h
        self._w_hinv = np.ascontiguousarray(w[None] * hinv.T[:, :, None])     # (K, e, q)
        # w / (h_K h_L) as (e, 1, 1, q, K, L), the stiffness's layout
        self._w_hh = (w[:, :, None, None] * hinv[:, None, :, None]
                      * hinv[:, None, None, :])[:, None, None]
        # pairs[(q, K, L), (a, b)] = ref[q, a, K] ref[q, b, L]
        self._pairs = np.einsum("qaK,qbL->qKLab", ref, ref).reshape(nq * 9, 64)
        self._hinv = hinv
        self._shape = (ne, nq)

    def deformation(self, ue: np.ndarray) -> np.ndarray:
        """F[i, K, e, q] from element dofs ue (e, 24) ordered (a, i)."""
        ne, nq = self._shape
        ue = ue.reshape(ne, 8, 3)
        if self._box:
            F = np.empty((3, 3, ne, nq), dtype=np.result_type(ue, self._ref_kq))
            for i in range(3):
                g = (ue[:, :, i] @ self._ref_kq).reshape(ne, 3, nq)      # (e, K, q)
                for k in range(3):
                    np.multiply(g[:, k], self._hinv[:, k, None], out=F[i, k])
        else:
            F = np.einsum("eai,eqaK->iKeq", ue, self._dndx, optimize=True)
        F[0, 0] += 1.0
        F[1, 1] += 1.0
        F[2, 2] += 1.0
        return F

    def divergence(self, P: np.ndarray) -> np.ndarray:
        """Element nodal forces fe[e, a, i] = sum_q w dN_a/dX_K P_iK."""
        ne = self._shape[0]
        if self._box:
            fe = np.empty((ne, 8, 3), dtype=np.result_type(P, self._w_hinv))
            for i in range(3):
                S = P[i] * self._w_hinv                                   # (K, e, q)
                acc = S[0] @ self._ref_qa[0]
                acc += S[1] @ self._ref_qa[1]
                acc += S[2] @ self._ref_qa[2]
                fe[:, :, i] = acc
            return fe
        return np.einsum("iKeq,eqaK->eai", P * self._w, self._dndx, optimize=True)

    def stiffness(self, A: np.ndarray) -> np.ndarray:
        """Element matrices ke[e, (a i), (b k)] = sum_q w dN_a/dX_K A_iKkL dN_b/dX_L.

        A has shape (i, K, k, L, e, q). On box elements the sum over q, K, L is one GEMM
        with a constant (72 x 64) matrix of reference-gradient products per (i, k) pair.
        """
        ne, nq = self._shape
        if not self._box:
            ke = np.einsum("eqaK,iKkLeq,eqbL->eaibk", self._dndx, A * self._w, self._dndx,
                           optimize=True)
            return ke.reshape(ne, 24, 24)
        # weights and scalings in one pass that also lays A out for the GEMM
        X = np.empty((ne, 3, 3, nq, 3, 3), dtype=A.dtype)
        w_hh, pairs = (self._w_hh, self._pairs) if A.dtype == np.float64 else \
            (self._w_hh.astype(A.dtype), self._pairs.astype(A.dtype))
        np.multiply(A.transpose(4, 0, 2, 5, 1, 3), w_hh, out=X)      # (e, i, k, q, K, L)
        ke = (X.reshape(ne * 9, nq * 9) @ pairs).reshape(ne, 3, 3, 8, 8)  # (e, i, k, a, b)
        return ke.transpose(0, 3, 1, 4, 2).reshape(ne, 24, 24)
