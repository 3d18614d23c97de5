"""Second-order (Newton) terms of the batch cost in the sensors' own parameters.

The batch (Eq 3-1) steps with the Gauss–Newton matrix ``Hᵀ R⁻¹ H``: it drops the term
``−Σ rᵀ R⁻¹ ∂²h`` of the cost's Hessian, ``½ ∇²χ² = Hᵀ R⁻¹ H − Σ_i (r_i/σ_i²) ∇²h_i``.
That is harmless where the model is nearly linear in its parameters, but a product of
parameters breaks it: the fine Sun sensor's ``A3 sin(k tan α)`` (Eq 4-23) with ``A3 ≈ 0``
gives ``k`` no Gauss–Newton curvature of its own, while the data still bend the cost
along ``A3·k``. Gauss–Newton then zig-zags down that valley, converging linearly. A
model that knows such pairs gives their second partials (``Prediction.d2_par``); this
module contracts them with the weighted residuals, block by block::

    K_ab = −Σ_frames Σ_components (r/σ²) ∂²h/∂a∂b          (one number per pair)

and :func:`newton_matrix` adds ``K`` to the Gauss–Newton matrix when the fit is near the
noise floor (where the residuals are noise, ``K`` is small against ``Hᵀ R⁻¹ H`` except
along such valleys) and the sum stays positive definite. The covariance (Eq 3-2) keeps
the Gauss–Newton matrix: the expected information, not the observed one.

References
----------
Nocedal & Wright, *Numerical Optimization*, 2nd ed., Springer 2006, §10.3 (the Hessian
of a least-squares cost and its Gauss–Newton part); Dennis & Schnabel, *Numerical
Methods for Unconstrained Optimization*, SIAM 1996, §10.2 (large-residual and
hybrid methods).
"""

from __future__ import annotations

import numpy as np

from gcs_core.models import common

#: the Newton term is used only when χ² per measurement is below this (the model
#: describes the data; far from it the residuals are systematic and K is meaningless)
NEAR_NOISE_CHI2_PER_MEASUREMENT = 2.0


def block_curvature(
    d2_par, par, r: np.ndarray, used: np.ndarray, sigma: np.ndarray
) -> tuple[tuple[int, int, float], ...]:
    """``((i, j, K_ij), ...)`` of one block: ``K_ij = −Σ (r_c/σ_c²) ∂²h_c/∂a∂b`` over used
    frames, for the pairs of ``d2_par`` (``(a, b)`` -> ``(component c, values)``,
    ``Prediction.d2_par``) whose two parameters are both columns of the block (``par``:
    (local name, block column) pairs). (n, m) ``r``."""
    if not d2_par:
        return ()
    where = dict(par)
    pairs = [(a, b) for a, b in d2_par if a in where and b in where]
    if not pairs:
        return ()
    n = r.shape[0]
    every = bool(np.all(used))
    idx = None if every else np.flatnonzero(used)
    rw = {}
    out = []
    for a, b in pairs:
        c, v = common.component_values(d2_par[(a, b)], n)
        if c not in rw:
            rc = r[:, c] if every else r[idx, c]
            rw[c] = np.ascontiguousarray(rc) / sigma[c] ** 2
        val = -float(rw[c] @ (v if every else v[idx]))
        if val != 0.0 and np.isfinite(val):
            out.append((where[a], where[b], val))
    return tuple(out)


def add_block(K: np.ndarray, cols: np.ndarray, curv) -> None:
    """Add one block's ``curv`` (:func:`block_curvature`) into the symmetric ``K``."""
    for i, j, v in curv:
        ci, cj = cols[i], cols[j]
        K[ci, cj] += v
        if ci != cj:
            K[cj, ci] += v


def near_floor(chi2: float, m: int) -> bool:
    """χ² per measurement below :data:`NEAR_NOISE_CHI2_PER_MEASUREMENT` (the model
    describes the data; its residuals are mostly noise)."""
    return chi2 <= NEAR_NOISE_CHI2_PER_MEASUREMENT * max(m, 1)


def newton_matrix(N_gn: np.ndarray, K: np.ndarray, chi2: float, m: int) -> np.ndarray | None:
    """``N_gn + K`` when it is usable for a step (near the noise floor, positive definite),
    else None (step with Gauss–Newton)."""
    if not np.any(K) or not near_floor(chi2, m):
        return None
    N = N_gn + K
    return N if positive_definite(N, np.sqrt(np.diag(N_gn))) else None


def positive_definite(N: np.ndarray, scale: np.ndarray | None = None) -> bool:
    """Whether ``N`` (equilibrated by ``scale`` when given) has a Cholesky factor."""
    try:
        np.linalg.cholesky(N if scale is None else N / np.outer(scale, scale))
    except np.linalg.LinAlgError:
        return False
    return True
