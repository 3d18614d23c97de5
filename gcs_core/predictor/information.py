"""Covariance-only accumulation for static states (seed Eq 3-2) and the consider budget.

For solve-for elements with a-priori information ``P̄⁻¹`` the predictor needs no
residuals, only the partials of every frame at the nominal state (seed §3.2.1: "only
Equations (3-2) and (3-4) are needed")::

    P(t) = (P̄⁻¹ + Σ_{t_k ≤ t} H_kᵀ R⁻¹ H_k)⁻¹                                    (Eq 3-2)

which is also the covariance a batch fit reports at its solution, so a prediction for
the frames of a real data set reproduces the calibration's σ.

Consider elements ``c`` (role "consider": not estimated, a-priori σ carried) bias the
solution through ``S = −P Hᵀ R⁻¹ H_c``; their covariance contribution is ``S P_c Sᵀ``
(consider analysis, Tapley, Schutz & Born 2004, §6.3). With uncorrelated consider
elements, element ``i``'s total variance splits into a budget, in the manner of the
GSFC error analyses::

    σ_i² = P_ii  +  Σ_j (S_ij σ_cj)²      (noise only + one term per error source)

Frames are binned by output time (data up to and including each output time), the
per-bin information ``Σ Hᵀ R⁻¹ H`` summed cumulatively, and the normal matrices of all
output times equilibrated to unit diagonal, checked positive definite by Cholesky and
solved against the identity together; a time whose matrix is singular (an element
without information or prior) falls back to an eigen-decomposition that reports the
elements involved as unobservable (σ = ∞).

References
----------
Tapley, B. D., Schutz, B. E., Born, G. H., *Statistical Orbit Determination*, Elsevier
2004, §4.3 and §6.3.
"""

from __future__ import annotations

from collections.abc import Mapping, Sequence

import numpy as np

#: relative eigenvalue below which a direction of the normal matrix carries no information
NULL_TOL = 1e-13


def weighted_rows(lin, t: np.ndarray, use: np.ndarray | None = None) -> tuple[np.ndarray, np.ndarray]:
    """Whitened partials ``R^-1/2 H`` of one sensor's used frames.

    Parameters
    ----------
    lin : a :class:`~gcs_core.problem.linearization.Linearization`; t : (N,) its frame times;
    use : (N,) frames to use besides the model's ``valid`` flag.

    Returns
    -------
    ``(t, X)``: (N_used,) frame times and (N_used, m, k) rows.
    """
    mask = np.asarray(lin.valid, bool) if use is None else (np.asarray(lin.valid, bool) & use)
    X = lin.H[mask] / np.asarray(lin.sigma, float)[None, :, None]
    return np.asarray(t)[mask], X


def binned_information(rows: Sequence[tuple[np.ndarray, np.ndarray]], times: np.ndarray, k: int) -> np.ndarray:
    """(T, k, k) cumulative ``Σ_{t_f ≤ τ_j} Xᵀ X`` at the output times ``τ_j``.

    ``rows`` holds ``(t, X)`` pairs of :func:`weighted_rows`; frames after the last
    output time are left out.
    """
    T = times.size
    A = np.zeros((T, k, k))
    for t, X in rows:
        if t.size == 0:
            continue
        b = np.searchsorted(times, t, side="left")  # first τ_j ≥ t
        order = np.argsort(b, kind="stable")
        b, X = b[order], X[order]
        bins, first = np.unique(b, return_index=True)
        last = np.append(first[1:], b.size)
        for j, i0, i1 in zip(bins, first, last):
            if j >= T:
                break
            Y = X[i0:i1].reshape(-1, k)
            A[j] += Y.T @ Y
    return np.cumsum(A, axis=0)


def _equilibrated_inverse(N: np.ndarray) -> np.ndarray:
    """Inverse of symmetric positive definite matrices (..., n, n) by equilibration.

    Scaled to unit diagonal, checked positive definite by a Cholesky factorization whose
    pivots must stay above ``sqrt(NULL_TOL)``, then solved against the identity.
    Raises ``LinAlgError`` otherwise.
    """
    d = np.sqrt(np.diagonal(N, axis1=-2, axis2=-1))
    if not np.all(d > 0):
        raise np.linalg.LinAlgError("zero diagonal")
    dd = d[..., :, None] * d[..., None, :]
    Ns = N / dd
    L = np.linalg.cholesky(Ns)
    if np.min(np.diagonal(L, axis1=-2, axis2=-1)) < np.sqrt(NULL_TOL):
        raise np.linalg.LinAlgError("ill-conditioned")
    P = np.linalg.solve(Ns, np.broadcast_to(np.eye(N.shape[-1]), Ns.shape)) / dd
    return 0.5 * (P + np.swapaxes(P, -1, -2))  # symmetrize: round-off only


def covariance(N: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Inverse of a symmetric positive semi-definite normal matrix, with its null space.

    The matrix is equilibrated to unit diagonal and factored by Cholesky. Where that
    fails (a combination without information) the eigen-decomposition is used and the
    elements touching the null space are flagged.

    Returns
    -------
    P : (n, n) covariance (rows/columns of flagged elements are zero).
    unobservable : (n,) bool, elements with no information in some direction.
    """
    n = N.shape[0]
    try:
        return _equilibrated_inverse(N), np.zeros(n, dtype=bool)
    except np.linalg.LinAlgError:
        pass
    d = np.sqrt(np.clip(np.diag(N), 0.0, None))
    unobs = ~(d > 0)
    ok = ~unobs
    P = np.zeros((n, n))
    if not np.any(ok):
        return P, unobs
    dk = d[ok]
    Ns = N[np.ix_(ok, ok)] / np.outer(dk, dk)
    w, V = np.linalg.eigh(Ns)
    keep = w > NULL_TOL * max(float(w[-1]), 1e-300)
    Ps = (V[:, keep] / w[keep]) @ V[:, keep].T
    touched = np.any(np.abs(V[:, ~keep]) > 1e-6, axis=1)
    idx = np.flatnonzero(ok)
    unobs[idx[touched]] = True
    Ps[touched, :] = 0.0
    Ps[:, touched] = 0.0
    Pk = Ps / np.outer(dk, dk)
    P[np.ix_(ok, ok)] = 0.5 * (Pk + Pk.T)
    return P, unobs


def static_history(
    A_cum: np.ndarray, n: int, prior_info: np.ndarray, sigma_c: np.ndarray, attitude_J: np.ndarray | None = None
) -> dict:
    """σ history of static states (Eq 3-2) with the consider budget at each output time.

    Parameters
    ----------
    A_cum : (T, k, k) cumulative information over solve-for (first n) and consider columns.
    prior_info : (n,) diagonal a-priori information (0 where σ0 is infinite).
    sigma_c : (k − n,) consider σ.
    attitude_J : (T, 3, n) partials of the attitude at each output time, or None.

    Returns
    -------
    dict with ``sigma`` and ``sigma_noise`` (T, n), ``attitude_sigma`` (T, 3),
    ``P`` and ``P_consider`` (n, n) at the last time, ``budget`` (c, n), ``unobservable``
    (n,) bool at the last time.
    """
    T = A_cum.shape[0]
    N = A_cum[:, :n, :n] + np.diag(prior_info)[None]
    try:  # all output times at once
        P = _equilibrated_inverse(N)
        unobs = np.zeros((T, n), dtype=bool)
    except np.linalg.LinAlgError:  # some time lacks information
        parts = [covariance(N[j]) for j in range(T)]
        P = np.stack([p for p, _ in parts])
        unobs = np.stack([u for _, u in parts])
    # consider: S = −P A_xc, contribution S P_c Sᵀ
    Sc = -(P @ A_cum[:, :n, n:]) * sigma_c[None, None, :]
    Ptot = P + Sc @ np.swapaxes(Sc, -1, -2)
    sig_noise = np.sqrt(np.clip(np.diagonal(P, axis1=1, axis2=2), 0.0, None))
    sig = np.sqrt(np.clip(np.diagonal(Ptot, axis1=1, axis2=2), 0.0, None))
    sig_noise[unobs] = np.inf
    sig[unobs] = np.inf
    att = np.full((T, 3), np.nan)
    if attitude_J is not None:
        v = np.einsum("tia,tab,tib->ti", attitude_J, Ptot, attitude_J)
        touches = np.einsum("tia,ta->ti", np.abs(attitude_J), unobs.astype(float)) > 0
        att = np.where(touches, np.inf, np.sqrt(np.clip(v, 0.0, None)))
    return {
        "sigma": sig,
        "sigma_noise": sig_noise,
        "attitude_sigma": att,
        "P": P[-1],
        "P_consider": Ptot[-1],
        "budget": np.abs(Sc[-1]).T,
        "unobservable": unobs[-1],
    }


def prior_information(sigma0: np.ndarray) -> np.ndarray:
    """(n,) ``1/σ0²``, zero where σ0 is infinite or not positive."""
    s = np.asarray(sigma0, dtype=float)
    with np.errstate(divide="ignore"):
        return np.where(np.isfinite(s) & (s > 0), 1.0 / np.where(s > 0, s, 1.0) ** 2, 0.0)


def final_information(rows: Sequence[tuple[np.ndarray, np.ndarray]], k: int, t_end: float) -> np.ndarray:
    """(k, k) ``Σ Xᵀ X`` over all frames up to ``t_end``."""
    A = np.zeros((k, k))
    for t, X in rows:
        Y = X[t <= t_end].reshape(-1, k)
        A += Y.T @ Y
    return A


def masks_in(plan, problem) -> Mapping[str, np.ndarray]:
    """Frames of ``problem`` inside the plan span and outside its gaps."""
    return {sd.name: plan.in_span(sd.t) & ~plan.in_gap(sd.t, sd.name) for sd in problem.sensors}
