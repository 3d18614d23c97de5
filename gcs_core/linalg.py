"""Small linear-algebra helpers shared by the estimators and the diagnosis."""

from __future__ import annotations

import numpy as np

__all__ = ["sparse_basis"]


def sparse_basis(V: np.ndarray) -> np.ndarray:
    """Columns spanning the same subspace as ``V`` (n, k), in reduced row echelon form of
    ``Vᵀ`` with pivots on the largest remaining weights, each normalized to unit length."""
    B = V.T.copy()
    k = B.shape[0]
    used: list[int] = []
    for i in range(k):
        rest = np.abs(B[i:, :]).copy()
        rest[:, used] = 0.0
        r0, c0 = np.unravel_index(int(np.argmax(rest)), rest.shape)
        r, c = int(r0) + i, int(c0)
        B[[i, r]] = B[[r, i]]
        B[i] /= B[i, c]
        for j in range(k):
            if j != i:
                B[j] -= B[j, c] * B[i]
        used.append(c)
    B /= np.linalg.norm(B, axis=1, keepdims=True)
    return B.T
