"""Compiled frame-by-frame Kalman pass of FILTR (seed §3.2.1, Eq 3-3 and 3-4), with numba.

:func:`filter_frames` runs one :class:`~gcs_core.estimators.kalman.linear.LinearBlock` frame after
frame, in the block-start coordinates ``y`` of :mod:`gcs_core.estimators.kalman.linear` (there
``Φ = I``: propagation only adds the process noise entering at each epoch)::

    P⁻ = P + ΔΠ_k                                                                (Eq 3-4)
    S = A P⁻ Aᵀ + I,   K = P⁻ Aᵀ S⁻¹,   y = y⁻ + K (r − A y⁻)                    (Eq 3-3)
    P = (I − K A) P⁻ (I − K A)ᵀ + K Kᵀ                                           (Joseph)

with whitened rows (``R = I``). ``I − K A`` is the identity minus a rank-m matrix, so the
Joseph product is formed as two rank-m corrections, ``N = P⁻ (I − K A)ᵀ = P⁻ − Bᵀ Kᵀ``
(``Bᵀ = P⁻ Aᵀ``) then ``P = N − K (A N) + K Kᵀ``: O(n² m) per frame instead of O(n³),
every inner loop an axpy over a contiguous row (vectorized without reassociating sums,
``fastmath=False``). Each frame keeps its innovation ν, covariance S, NIS and gain norm,
and the k-σ gate ``|ν_i| / sqrt(S_ii) > k`` skips the frame (flagged, not used).

The white attitude read-out noise (σ_e, rows ``H_θ``) is shared by the rows of one epoch,
so frames at the same epoch have correlated noise. It is carried exactly by three extra
states ``e`` (the read-out error of the epoch): the rows become ``[A, H_θ]``, and at each
epoch ``e`` is marginalized out (its rows and columns dropped) and re-introduced fresh,
``e ~ N(0, σ_e² I)``.

Engine selection is :data:`gcs_core.compiled.COMPILED`: when it holds,
:mod:`gcs_core.estimators.kalman.linear` runs this kernel, otherwise its pure-numpy lifted-group core
(same answer to round-off). Without numba the functions below are plain Python (correct,
slow: tests only).

References
----------
Bierman, *Factorization Methods for Discrete Sequential Estimation*, Academic Press 1977,
§V (Joseph form, why).
"""

from __future__ import annotations

import numpy as np

from gcs_core.compiled import jit

__all__ = ["filter_frames", "run_block"]

#: ``@numba.njit(cache=True, fastmath=False)``, or the identity without numba.
_jit = jit(fastmath=False)

#: states added for the read-out error of an epoch (a body rotation, 3 angles)
N_READOUT = 3


@_jit
def _cholesky(S, m, L):
    """Lower ``L`` with ``L Lᵀ = S[:m, :m]``; False if ``S`` is not positive definite."""
    for j in range(m):
        s = S[j, j]
        for k in range(j):
            s -= L[j, k] * L[j, k]
        if not s > 0.0:  # also catches NaN
            return False
        L[j, j] = np.sqrt(s)
        for i in range(j + 1, m):
            t = S[i, j]
            for k in range(j):
                t -= L[i, k] * L[j, k]
            L[i, j] = t / L[j, j]
    return True


@_jit
def _rows_times(Af, X, m, N, out):
    """``out[:m] = A X`` for the rows ``Af[:m]`` and an (N, N) ``X``, row by row (axpy)."""
    for a in range(m):
        for k in range(N):
            out[a, k] = 0.0
        for j in range(N):
            c = Af[a, j]
            for k in range(N):
                out[a, k] += c * X[j, k]


@_jit
def _innovation(Af, ya, r, s0, Bt, m, N, v, Sw):
    """Eq 3-3: ``ν = r − A y⁻`` into ``v``, ``S = A P⁻ Aᵀ + R`` into ``Sw`` (``R = I`` after
    whitening; lower triangle mirrored), from ``Bt = A P⁻``."""
    for a in range(m):
        t = r[s0 + a]
        for j in range(N):
            t -= Af[a, j] * ya[j]
        v[a] = t
        for b in range(a + 1):
            t = 0.0
            for j in range(N):
                t += Af[a, j] * Bt[b, j]
            Sw[a, b] = t
            Sw[b, a] = t
        Sw[a, a] += 1.0


@_jit
def _diagnose(f, m, v, L, Sw, sigma, s0, edit_k, e, nu, S, nis):
    """Frame ``f``'s diagnostics in telemetry units: ν, S = L Lᵀ, NIS = νᵀ S⁻¹ ν = |L⁻¹ ν|²
    (``e = L⁻¹ ν``); True if the k-σ gate ``|ν_i| / sqrt(S_ii) > k`` holds on a component."""
    q = 0.0
    bad = False
    for a in range(m):
        t = v[a]
        for b in range(a):
            t -= L[a, b] * e[b]
        e[a] = t / L[a, a]  # e = L⁻¹ ν
        q += e[a] * e[a]
        nu[f, a] = v[a] * sigma[s0 + a]
        for b in range(m):
            S[f, a, b] = Sw[a, b] * sigma[s0 + a] * sigma[s0 + b]
        if abs(v[a]) / np.sqrt(Sw[a, a]) > edit_k:  # k-σ gate on every component
            bad = True
    nis[f] = q
    return bad


@_jit
def _gain(Bt, L, m, N, Kt):
    """Eq 3-3 gain, transposed: ``Kᵀ = S⁻¹ A P⁻ = L⁻ᵀ L⁻¹ Bt`` (row operations)."""
    for a in range(m):
        for k in range(N):
            Kt[a, k] = Bt[a, k]
        for b in range(a):
            c = L[a, b]
            for k in range(N):
                Kt[a, k] -= c * Kt[b, k]
        c = 1.0 / L[a, a]
        for k in range(N):
            Kt[a, k] *= c
    for a in range(m - 1, -1, -1):
        for b in range(a + 1, m):
            c = L[b, a]
            for k in range(N):
                Kt[a, k] -= c * Kt[b, k]
        c = 1.0 / L[a, a]
        for k in range(N):
            Kt[a, k] *= c


@_jit
def _gain_norm(Kt, sigma, s0, Psi_d, ep, m, n):
    """|K| in telemetry units (÷σ), rows of δθ, b in current-time coordinates (Ψ_d K)."""
    q = 0.0
    dq = Psi_d.shape[1]
    for a in range(m):
        w = 1.0 / (sigma[s0 + a] * sigma[s0 + a])
        for i in range(dq):
            t = 0.0
            for j in range(n):
                t += Psi_d[ep, i, j] * Kt[a, j]
            q += t * t * w
        for i in range(dq, n):
            q += Kt[a, i] * Kt[a, i] * w
    return np.sqrt(q)


@_jit
def _joseph(Pa, Af, Bt, Kt, m, N, AN, Nm):
    """Joseph form (module docstring) as two rank-m corrections, in place on ``Pa``:
    ``N = P⁻ (I − K A)ᵀ = P⁻ − Bᵀ Kᵀ``, then ``P = (I − K A) N + K R Kᵀ = N + K (Kᵀ − A N)``
    (``R = I``), symmetrized."""
    for i in range(N):
        for k in range(N):
            Nm[i, k] = Pa[i, k]
        for a in range(m):
            c = Bt[a, i]
            for k in range(N):
                Nm[i, k] -= c * Kt[a, k]
    _rows_times(Af, Nm, m, N, AN)  # A N  (m, N)
    for a in range(m):
        for k in range(N):
            AN[a, k] = Kt[a, k] - AN[a, k]
    for i in range(N):
        for k in range(N):
            Pa[i, k] = Nm[i, k]
        for a in range(m):
            c = Kt[a, i]
            for k in range(N):
                Pa[i, k] += c * AN[a, k]
    # symmetrize deliberately: the products leave ~1e-16 relative asymmetry, which the
    # recursion would otherwise accumulate
    for i in range(N):
        for k in range(i + 1, N):
            t = 0.5 * (Pa[i, k] + Pa[k, i])
            Pa[i, k] = t
            Pa[k, i] = t


@_jit
def _frame(
    f, Pa, ya, Af, m, n, N, r, sigma, s0, Psi_d, ep, edit_k, Bt, Kt, AN, Nm, Sw, L, v, e, nu, S, nis, knorm, gated
):
    """Update with frame ``f`` (rows ``Af[:m]``, whitened; Eq 3-3, Joseph form); False if
    S is not PD."""
    _rows_times(Af, Pa, m, N, Bt)  # Bt = A P⁻  (m, N), i.e. (P⁻ Aᵀ)ᵀ
    _innovation(Af, ya, r, s0, Bt, m, N, v, Sw)
    if not _cholesky(Sw, m, L):
        return False
    if _diagnose(f, m, v, L, Sw, sigma, s0, edit_k, e, nu, S, nis):
        gated[f] = True
        knorm[f] = np.nan
        return True
    _gain(Bt, L, m, N, Kt)
    # y = y⁻ + K ν
    for a in range(m):
        c = v[a]
        for k in range(N):
            ya[k] += Kt[a, k] * c
    knorm[f] = _gain_norm(Kt, sigma, s0, Psi_d, ep, m, n)
    _joseph(Pa, Af, Bt, Kt, m, N, AN, Nm)
    return True


@_jit
def filter_frames(
    y,
    P,
    A,
    r,
    sigma,
    Hth,
    sig_e2,
    dPi,
    Psi_d,
    frame_start,
    frame_m,
    frame_epoch,
    edit_k,
    keep,
    nu,
    S,
    nis,
    knorm,
    gated,
    y_ep,
    P_ep,
):
    """Filter one block frame by frame (module docstring); returns −1, or the first frame
    whose innovation covariance is not positive definite.

    Parameters (all C-contiguous; arrays marked *out* are written)
    ----------
    y : (n,) in/out, prior mean at the block start, then the posterior at the last epoch.
    P : (n, n) in/out, its covariance.
    A : (M, n) whitened rows; r : (M,) whitened residuals; sigma : (M,) row noise sigma.
    Hth : (M, 3) whitened ``∂z/∂δθ`` for the read-out noise, or (0, 3); sig_e2 : σ_e².
    dPi : (G, d, d) process noise entering at each epoch (``ΔΠ_k``).
    Psi_d : (G, d, n) dynamic rows of Ψ for the gain norm, or (G, 0, n).
    frame_start, frame_m, frame_epoch : (F,) int64, frames ordered by epoch.
    edit_k : (F,) gate of each frame (inf: none); keep : record the posterior at every epoch.
    nu (F, m_max), S (F, m_max, m_max), nis (F,), knorm (F,), gated (F,) : *out*.
    y_ep (G, n), P_ep (G, n, n) : *out* when ``keep`` (else (0, n), (0, n, n)).
    """
    n = y.shape[0]
    G, d = dPi.shape[0], dPi.shape[1]
    F = frame_start.shape[0]
    mx = nu.shape[1]
    na = N_READOUT if (sig_e2 > 0.0 and Hth.shape[0] > 0) else 0
    N = n + na
    ya = np.zeros(N)
    Pa = np.zeros((N, N))
    for i in range(n):
        ya[i] = y[i]
        for k in range(n):
            Pa[i, k] = P[i, k]
    Af, Bt, Kt = np.zeros((mx, N)), np.zeros((mx, N)), np.zeros((mx, N))
    AN, Nm = np.zeros((mx, N)), np.zeros((N, N))
    Sw, L, v, e = np.zeros((mx, mx)), np.zeros((mx, mx)), np.zeros(mx), np.zeros(mx)
    f = 0
    for k in range(G):
        # P⁻ = P + ΔΠ_k  (Φ = I in block-start coordinates)
        for i in range(d):
            for j in range(d):
                Pa[i, j] += dPi[k, i, j]
        if na:
            # a fresh read-out error for this epoch: e ~ N(0, σ_e² I), uncorrelated
            for i in range(n, N):
                ya[i] = 0.0
                for j in range(N):
                    Pa[i, j] = 0.0
                    Pa[j, i] = 0.0
                Pa[i, i] = sig_e2
        while f < F and frame_epoch[f] == k:
            s0, m = frame_start[f], frame_m[f]
            for a in range(m):
                for j in range(n):
                    Af[a, j] = A[s0 + a, j]
                for j in range(na):
                    Af[a, n + j] = Hth[s0 + a, j]
            if not _frame(
                f,
                Pa,
                ya,
                Af,
                m,
                n,
                N,
                r,
                sigma,
                s0,
                Psi_d,
                k,
                edit_k[f],
                Bt,
                Kt,
                AN,
                Nm,
                Sw,
                L,
                v,
                e,
                nu,
                S,
                nis,
                knorm,
                gated,
            ):
                return f
            f += 1
        if keep:
            for i in range(n):
                y_ep[k, i] = ya[i]
                for j in range(n):
                    P_ep[k, i, j] = Pa[i, j]
    for i in range(n):
        y[i] = ya[i]
        for k in range(n):
            P[i, k] = Pa[i, k]
    return -1


def run_block(y0, P0, blk, edit_k, keep_epochs: bool):
    """Run :func:`filter_frames` on a ``LinearBlock``; returns the fields of a
    ``BlockSolution`` in order (``y, P, nu, S, nis, k_norm, gated, y_epoch, P_epoch``).

    ``edit_k``: the gate, None (none), one k, or (F,) per frame.
    Every argument is passed with one dtype and layout, so the kernel is compiled once.
    """
    f64 = lambda a: np.ascontiguousarray(a, dtype=np.float64)
    i64 = lambda a: np.ascontiguousarray(a, dtype=np.int64)
    A = f64(blk.A)
    n = A.shape[1]
    G, F = blk.t.size, blk.frame_start.size
    Pi = f64(blk.Pi)
    d = Pi.shape[1]
    mx = int(blk.frame_m.max()) if F else 1
    dPi = np.diff(Pi, axis=0, prepend=np.zeros((1, d, d)))  # ΔΠ_k, noise entering at epoch k
    readout = blk.Hth is not None and blk.sig_e2 > 0
    Hth = f64(blk.Hth) if readout else np.zeros((0, N_READOUT))
    Psi_d = f64(blk.Psi_d) if blk.Psi_d is not None and d else np.zeros((G, 0, n))
    y = np.array(y0, dtype=np.float64)
    P = np.array(P0, dtype=np.float64, order="C")
    nu = np.full((F, mx), np.nan)  # padding stays NaN
    S = np.full((F, mx, mx), np.nan)
    nis, knorm = np.empty(F), np.empty(F)
    gated = np.zeros(F, dtype=np.bool_)
    y_ep = np.empty((G if keep_epochs else 0, n))
    P_ep = np.empty((G if keep_epochs else 0, n, n))
    bad = filter_frames(
        y,
        P,
        A,
        f64(blk.r),
        f64(blk.sigma),
        Hth,
        float(blk.sig_e2 if readout else 0.0),
        dPi,
        Psi_d,
        i64(blk.frame_start),
        i64(blk.frame_m),
        i64(blk.frame_epoch),
        np.ascontiguousarray(np.broadcast_to(np.inf if edit_k is None else np.asarray(edit_k, np.float64), (F,))),
        bool(keep_epochs),
        nu,
        S,
        nis,
        knorm,
        gated,
        y_ep,
        P_ep,
    )
    if bad >= 0:
        raise np.linalg.LinAlgError(f"innovation covariance of frame {bad} not positive definite")
    return (y, P, nu, S, nis, knorm, gated, y_ep if keep_epochs else None, P_ep if keep_epochs else None)
