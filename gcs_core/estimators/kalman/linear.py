"""Linear Kalman-filter core of FILTR (seed §3.2.1, Eq 3-3 and 3-4).

The state is split into a dynamic part ``d`` (the attitude error δθ and random-walking
gyro biases in the MEKF of :mod:`gcs_core.estimators.kalman.mekf`) and a static part ``s`` (Φ = I,
Q = 0). Between times the filter propagates (Eq 3-4)::

    x_k = Φ_k x_{k−1} + w_k,   P_k⁻ = Φ_k P_{k−1} Φ_kᵀ + Q_k                     (Eq 3-4)

and at a frame with measurement rows ``H`` (noise ``R``, diagonal) it updates (Eq 3-3)::

    S = H P⁻ Hᵀ + R,   K = P⁻ Hᵀ S⁻¹,   x = x⁻ + K (z − H x⁻)                    (Eq 3-3)
    P = (I − K H) P⁻ (I − K H)ᵀ + K R Kᵀ                                         (Joseph)

Block-start coordinates
-----------------------
Within a block (a few hundred seconds, re-linearized at its start ``t_a``), the transition
from ``t_a`` to ``t`` is ``Ψ(t) = [[Ψ_dd, Ψ_ds], [0, I]]`` (static rows are identity) and
``y = Ψ(t)⁻¹ x`` does not move: ``y(t) = y(t_a) + ζ(t)``, ``ζ`` a random walk whose
covariance ``Π(t) = Σ Ψ_dd⁻¹ Q Ψ_dd⁻ᵀ`` lives in the dynamic block. A frame measures
``z = H Ψ(t) y + v = A y + v``. The filter is therefore run on ``y`` with ``Φ = I``.

The lifted (grouped) update
---------------------------
A pure-numpy filter pays ~1 µs per small array operation, so a frame-by-frame loop
cannot beat a generic implementation. The core instead processes a *group* of
consecutive frames (a few dozen scalar rows) at once, exactly: with all rows whitened
(``R = I``), ``B_s = (P_0 + Π_{k_s}) A_sᵀ`` is ``cov(y, z_s)`` and the joint innovation
covariance is ``S_rs = A_r B_s`` for ``k_r ≥ k_s`` (then symmetric). With ``S = L Lᵀ``
(Cholesky) the whitened innovations ``e = L⁻¹ (z − A y_0)`` are the sequential filter's
innovations frame after frame: the frame block ``L_ff`` of the factor gives its
innovation ``ν_f = L_ff e_f`` and covariance ``S_f = L_ff L_ffᵀ`` (conditioned on every
earlier row), ``NIS_f = |e_f|²``, and ``W = B L⁻ᵀ`` gives the gain ``K_f = W_f L_ff⁻¹``.
The state after the group is ``y_0 + W e``; its covariance is taken in Joseph form for
the group gain ``K = W L⁻¹`` (a sum of positive semi-definite terms, see
:func:`_group_end_covariance`). Results equal the textbook frame-by-frame filter to
round-off (``tests/unit/test_kalman.py``).

Two engines, one answer
-----------------------
:func:`solve_block` runs the compiled frame-by-frame kernel of
:mod:`gcs_core.estimators.kalman.kernels` (numba; the same Eq 3-3, 3-4 and Joseph update, one
frame at a time, O(n² m) per frame) when numba imports, and the lifted-group numpy core
above otherwise (:data:`ENGINE`, chosen once from :data:`gcs_core.compiled.COMPILED`). Both give
the same state, covariance, per-frame diagnostics and gate decisions to round-off
(``tests/unit/test_kalman.py``); the kernel is the faster (``benchmarks/kalman_vs_filterpy.py``).

References
----------
Bierman, *Factorization Methods for Discrete Sequential Estimation*, Academic Press 1977,
§V (Joseph form, why).
Kailath, Sayed & Hassibi, *Linear Estimation*, Prentice Hall 2000, §4.1 (innovations
from the Cholesky factor of the covariance of stacked observations).
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from scipy.linalg import lapack

from gcs_core.compiled import COMPILED
from gcs_core.estimators.kalman import kernels

__all__ = ["LinearBlock", "BlockSolution", "solve_block", "referred_transitions", "group_partition", "ENGINE"]

#: engine of :func:`solve_block`: "compiled" (numba kernel) when numba imports, else "numpy".
ENGINE = "compiled" if COMPILED else "numpy"


@dataclass(frozen=True)
class LinearBlock:
    """One block of the linearized problem in block-start coordinates ``y`` (module docstring).

    Epoch 0 is the block start, where the incoming ``y_0, P_0`` hold; the rows of a frame
    are contiguous and frames are ordered by epoch.

    Attributes
    ----------
    t : (G,) epoch times [s].
    Pi : (G, d, d) process noise accumulated from the block start, referred to it (``Π``).
    Psi_d : (G, d, n) dynamic rows of ``Ψ`` (``x_d = Psi_d y``), or None when d = 0.
    A : (M, n) measurement rows ``H Ψ`` divided by their noise sigma.
    r : (M,) measured minus nominal prediction, divided by the noise sigma.
    sigma : (M,) noise 1-sigma of each row, telemetry units.
    row_epoch : (M,) epoch of each row (non-decreasing).
    frame_start, frame_m, frame_epoch : (F,) first row, number of rows and epoch per frame.
    Hth : (M, 3) whitened ``∂z/∂δθ`` for the gyro read-out noise, or None.
    sig_e2 : variance σ_e² [rad²] of the white attitude read-out noise (0: none).
    """

    t: np.ndarray
    Pi: np.ndarray
    Psi_d: np.ndarray | None
    A: np.ndarray
    r: np.ndarray
    sigma: np.ndarray
    row_epoch: np.ndarray
    frame_start: np.ndarray
    frame_m: np.ndarray
    frame_epoch: np.ndarray
    Hth: np.ndarray | None = None
    sig_e2: float = 0.0

    @property
    def n(self) -> int:
        return int(self.A.shape[1])

    @property
    def d(self) -> int:
        return int(self.Pi.shape[1])


@dataclass(frozen=True)
class BlockSolution:
    """What :func:`solve_block` returns.

    Attributes
    ----------
    y, P : (n,), (n, n) posterior at the last epoch (block-start coordinates).
    nu : (F, m_max) innovation of each frame, telemetry units (NaN-padded).
    S : (F, m_max, m_max) its covariance ``H P⁻ Hᵀ + R``.
    nis : (F,) normalized innovation squared ``νᵀ S⁻¹ ν``.
    k_norm : (F,) Frobenius norm of the frame's gain ``K`` (current-time coordinates,
        state units per telemetry unit; a spike finder, its units are mixed).
    gated : (F,) frames refused by the k-σ innovation gate (flagged, not used).
    y_epoch, P_epoch : (G, n), (G, n, n) posterior at every epoch, or None.
    """

    y: np.ndarray
    P: np.ndarray
    nu: np.ndarray
    S: np.ndarray
    nis: np.ndarray
    k_norm: np.ndarray
    gated: np.ndarray
    y_epoch: np.ndarray | None = None
    P_epoch: np.ndarray | None = None


def group_partition(row_epoch: np.ndarray, n_epochs: int, group_rows: int) -> np.ndarray:
    """(n_groups + 1,) epoch boundaries: an epoch joins the group in which its first row
    falls, counting ``group_rows`` rows per group (a group may overrun by one epoch)."""
    counts = np.bincount(row_epoch, minlength=n_epochs)
    before = np.cumsum(counts) - counts
    gid = before // max(int(group_rows), 1)
    cut = np.nonzero(np.diff(gid))[0] + 1
    return np.concatenate([[0], cut, [n_epochs]]).astype(int)


def solve_block(
    y0: np.ndarray,
    P0: np.ndarray,
    blk: LinearBlock,
    *,
    edit_k: float | None | np.ndarray = 5.0,
    group_rows: int = 48,
    keep_epochs: bool = False,
    engine: str | None = None,
) -> BlockSolution:
    """Filter one block (Eq 3-3, 3-4) frame by frame, with k-σ innovation gating.

    Parameters
    ----------
    y0 : (n,) prior mean at the block start; P0 : (n, n) its covariance.
    blk : the block's rows and process noise (:class:`LinearBlock`).
    edit_k : a frame whose normalized innovation ``|ν_i|/sqrt(S_ii)`` exceeds ``edit_k`` in
        any component is flagged and skipped (None: no gate); an (F,) array gives each
        frame its own gate (``inf``: none), e.g. per sensor. The gate uses the innovation
        given every earlier accepted frame, exactly as a frame-by-frame filter would.
    group_rows : scalar rows per lifted group of the numpy engine (speed only; the answer
        does not depend on it).
    keep_epochs : also return the posterior at every epoch (for the smoother).
    engine : "compiled" (frame-by-frame numba kernel) or "numpy" (lifted groups); None:
        :data:`ENGINE`. Both give the same answer to round-off.
    """
    engine = ENGINE if engine is None else engine
    F = blk.frame_start.size
    if edit_k is None:
        gates = np.full(F, np.inf)
    else:
        gates = np.broadcast_to(np.asarray(edit_k, float), (F,)).copy()
    if engine == "compiled":
        return BlockSolution(*kernels.run_block(y0, P0, blk, gates, keep_epochs))
    if engine != "numpy":
        raise ValueError(f"unknown Kalman engine {engine!r} (compiled, numpy)")
    n, d = blk.n, blk.d
    G, F = blk.t.size, blk.frame_start.size
    mx = int(blk.frame_m.max()) if F else 1
    raw = _Raw(F, n, mx)
    gated = np.zeros(F, bool)
    y_ep = np.empty((G, n)) if keep_epochs else None
    P_ep = np.empty((G, n, n)) if keep_epochs else None
    frame_of_row = np.repeat(np.arange(F), blk.frame_m)
    bounds = group_partition(blk.row_epoch, G, group_rows)
    row_b = np.searchsorted(blk.row_epoch, bounds)
    frame_b = np.searchsorted(blk.frame_epoch, bounds)
    y, P = np.array(y0, float), np.array(P0, float)
    zero_d = np.zeros((d, d))
    dPi = np.diff(blk.Pi, axis=0, prepend=zero_d[None])  # ΔΠ_k, noise entering at epoch k
    for g in range(bounds.size - 1):
        e0, e1 = bounds[g], bounds[g + 1]
        base = blk.Pi[e0 - 1] if e0 > 0 else zero_d
        grp = _Group(
            blk,
            e0,
            e1,
            slice(row_b[g], row_b[g + 1]),
            slice(frame_b[g], frame_b[g + 1]),
            frame_of_row,
            blk.Pi[e0:e1] - base,
            dPi[e0:e1],
        )
        y, P = grp.run(y, P, gates, raw, gated, y_ep, P_ep)
    nu, S, nis, knorm = raw.finish(blk, gated)
    return BlockSolution(y, P, nu, S, nis, knorm, gated, y_ep, P_ep)


class _Raw:
    """Per-frame pieces gathered in the groups; the diagnostics are formed once per block.

    ``L_ff`` and ``(L⁻¹)_ff`` are padded with identity, ``e_f`` and ``W_f`` with zeros, so
    frames with fewer rows than ``m_max`` need no special case.
    """

    def __init__(self, F: int, n: int, mx: int):
        self.F, self.n, self.mx = F, n, mx
        self.parts: list = []

    def put(self, fr, mm, Lff, ef, Liff, Wf):
        self.parts.append((fr, mm, Lff, ef, Liff, Wf))

    def _assemble(self):
        F, n, mx = self.F, self.n, self.mx
        L = np.broadcast_to(np.eye(mx), (F, mx, mx)).copy()
        Li = L.copy()
        e = np.zeros((F, mx))
        W = np.zeros((F, n, mx))
        for mm in {p[1] for p in self.parts}:
            parts = [p for p in self.parts if p[1] == mm]
            fr = np.concatenate([p[0] for p in parts])
            # a group re-run after a gated frame gathers later frames again: keep the last
            last = fr.size - 1 - np.unique(fr[::-1], return_index=True)[1]
            fr = fr[last]
            L[fr, :mm, :mm] = np.concatenate([p[2] for p in parts])[last]
            e[fr, :mm] = np.concatenate([p[3] for p in parts])[last]
            Li[fr, :mm, :mm] = np.concatenate([p[4] for p in parts])[last]
            W[fr, :, :mm] = np.swapaxes(np.concatenate([p[5] for p in parts], axis=1), 0, 1)[last]
        return L, Li, e, W

    def finish(self, blk: LinearBlock, gated: np.ndarray):
        F, mx = self.F, self.mx
        L, Li, e, W = self._assemble()
        pad = np.arange(mx)[None, :] >= blk.frame_m[:, None]  # (F, mx)
        rows = np.minimum(blk.frame_start[:, None] + np.arange(mx), max(blk.sigma.size - 1, 0))
        sig = np.where(pad, 1.0, blk.sigma[rows]) if F else np.ones((0, mx))
        nu = (L @ e[:, :, None])[:, :, 0] * sig  # ν_f = L_ff e_f
        S = L @ np.swapaxes(L, 1, 2) * sig[:, :, None] * sig[:, None, :]  # S_f = L_ff L_ffᵀ
        nis = np.sum(e**2, axis=1)  # NIS = νᵀ S⁻¹ ν = |e_f|²
        # K_f = W_f (L⁻¹)_ff in telemetry units (÷σ), rows of δθ, b in current-time coordinates
        K = W @ Li / sig[:, None, :]
        if blk.d and blk.Psi_d is not None:
            K[:, : blk.d] = blk.Psi_d[blk.frame_epoch] @ K
        knorm = np.sqrt(np.einsum("fij,fij->f", K, K))
        knorm[gated] = np.nan
        nu[pad] = np.nan
        S[pad[:, :, None] | pad[:, None, :]] = np.nan
        return nu, S, nis, knorm


class _Pattern:
    """Index arrays of one row/frame layout of a group (cached: layouts repeat)."""

    def __init__(self, rep: np.ndarray, m: np.ndarray, Ge: int):
        M = rep.size
        self.lower = rep[:, None] >= rep[None, :]  # S_rs = A_r B_s holds for k_r ≥ k_s
        self.same = rep[:, None] == rep[None, :]
        self.after = (rep[:, None] >= np.arange(Ge)[None, :]).astype(float)  # row at/after epoch j
        self.last = np.searchsorted(rep, np.arange(Ge), side="right") - 1
        self.has = self.last >= 0
        self.eye = np.eye(M)
        self.starts = np.nonzero(np.r_[True, np.diff(rep) != 0])[0]
        start = np.cumsum(m) - m
        self.classes = []
        for mm in np.unique(m):
            sel = np.nonzero(m == mm)[0]
            idx = start[sel][:, None] + np.arange(mm)
            self.classes.append((int(mm), sel, idx, idx[:, :, None] * M + idx[:, None, :]))


_PATTERNS: dict = {}


def _pattern(rep, m, Ge) -> _Pattern:
    key = (Ge, rep.tobytes(), m.tobytes())
    pat = _PATTERNS.get(key)
    if pat is None:
        if len(_PATTERNS) > 512:
            _PATTERNS.clear()
        pat = _PATTERNS[key] = _Pattern(rep, m, Ge)
    return pat


class _Group:
    """One lifted group of consecutive epochs (module docstring)."""

    def __init__(self, blk: LinearBlock, e0, e1, rows: slice, frames: slice, frame_of_row, Pig, dPi):
        self.blk, self.e0, self.e1, self.f0 = blk, e0, e1, frames.start
        self.A, self.r, self.rep = blk.A[rows], blk.r[rows], blk.row_epoch[rows] - e0
        self.rframe = frame_of_row[rows] - frames.start
        self.Hth = blk.Hth[rows] if blk.Hth is not None and blk.sig_e2 > 0 else None
        self.m = blk.frame_m[frames]
        self.Pig = Pig  # (Ge, d, d) noise since group start
        self.dPi = dPi  # (Ge, d, d) noise entering per epoch
        self.d = blk.d

    def run(self, y0, P0, edit_k, raw: _Raw, gated, y_ep, P_ep):
        local = np.arange(self.m.size)  # frames taking part
        rows: slice | np.ndarray = slice(None)
        Ge = self.e1 - self.e0
        while local.size:
            pat = _pattern(self.rep[rows], self.m[local], Ge)
            sol = self._solve(y0, P0, rows, pat)
            first = self._gather(sol, pat, local, raw, edit_k)
            if first is None:
                break
            gated[self.f0 + first] = True  # earliest gated frame: skip it, redo
            local = local[local != first]
            rows = np.isin(self.rframe, local)
        if not local.size:  # no rows left: propagate only
            P_end = P0.copy()
            P_end[: self.d, : self.d] += self.Pig[-1]
            if y_ep is not None:
                y_ep[self.e0 : self.e1] = y0
                P_ep[self.e0 : self.e1] = P0
                P_ep[self.e0 : self.e1, : self.d, : self.d] += self.Pig
            return y0.copy(), P_end
        y_end = y0 + sol["W"] @ sol["e"]  # x = x⁻ + K (z − H x⁻), all rows
        P_end = _group_end_covariance(P0, sol, self.dPi, self.d, pat)
        if y_ep is not None:
            self._epochs(y0, P0, sol, pat, y_ep, P_ep)
        return y_end, P_end

    # -- one solve over the active rows ------------------------------------------------
    def _solve(self, y0, P0, rows, pat: _Pattern):
        A = self.A[rows]
        d = self.d
        # B = cov(y, z) = (P0 + Π_{k_s}) A_sᵀ,  Π_{k_s} A_sᵀ = Σ_{j ≤ k_s} ΔΠ_j A_s,dᵀ
        B = P0 @ A.T
        Z = None
        if d:
            Ge = self.dPi.shape[0]
            Z = (pat.after[:, :, None] * A[:, None, :d]).reshape(A.shape[0], Ge * d)
            B[:d] += self.dPi.transpose(1, 0, 2).reshape(d, Ge * d) @ Z.T
        # S = A B for k_r ≥ k_s, mirrored, + R (= I after whitening)
        S = A @ B
        S = np.where(pat.lower, S, S.T)
        S += pat.eye
        Hth = None
        if self.Hth is not None:
            Hth = self.Hth[rows]
            # read-out noise: a white attitude error shared by the rows of one epoch
            S += self.blk.sig_e2 * np.where(pat.same, Hth @ Hth.T, 0.0)
        L, Li = _cholesky_and_inverse(S)
        # e = L⁻¹ (z − A y⁻): whitened sequential innovations
        e = Li @ (self.r[rows] - A @ y0)
        # W = B L⁻ᵀ = cov(y, e)
        W = B @ Li.T
        return {"A": A, "L": L, "Li": Li, "e": e, "W": W, "Hth": Hth, "Z": Z, "sig_e2": self.blk.sig_e2}

    def _gather(self, sol, pat: _Pattern, local, raw: _Raw, edit_k):
        """Keep each frame's blocks of L, L⁻¹, e, W; return the first gated frame or None."""
        first = None
        L, Li, e, W = sol["L"], sol["Li"], sol["e"], sol["W"]
        for mm, sel, idx, blocks in pat.classes:
            Lff, ef = L.take(blocks), e[idx]
            fr = self.f0 + local[sel]
            # |ν_i|/sqrt(S_ii) ≤ sqrt(NIS_f) (Cauchy–Schwarz): test components only if needed
            k_f = edit_k[fr]
            if np.any(np.einsum("fi,fi->f", ef, ef) > k_f**2):
                nu_w = (Lff @ ef[:, :, None])[:, :, 0]  # ν_f = L_ff e_f (whitened rows)
                z = np.abs(nu_w) / np.sqrt(np.sum(Lff * Lff, axis=2))  # |ν_i| / sqrt(S_ii)
                bad = np.nonzero(np.max(z, axis=1) > k_f)[0]
                if bad.size and (first is None or local[sel[bad[0]]] < first):
                    first = int(local[sel[bad[0]]])
            raw.put(fr, mm, Lff, ef, Li.take(blocks), W.take(idx, axis=1))
        return first

    def _epochs(self, y0, P0, sol, pat: _Pattern, y_ep, P_ep):
        """Posterior at every epoch of the group (rows up to that epoch)."""
        W, e = sol["W"], sol["e"]
        last, has = pat.last, pat.has
        ycum = np.cumsum(W * e[None, :], axis=1)  # Σ_{s≤r} K_s ν_s
        ys = y_ep[self.e0 : self.e1]
        ys[:] = y0
        ys[has] += ycum[:, last[has]].T
        WW = np.cumsum(W.T[:, :, None] * W.T[:, None, :], axis=0)
        Pk = np.broadcast_to(P0, (self.e1 - self.e0,) + P0.shape).copy()
        Pk[:, : self.d, : self.d] += self.Pig  # P0 + Π_k
        Pk[has] -= WW[last[has]]  # − cov(y, e_{≤k}) cov(y, e_{≤k})ᵀ
        P_ep[self.e0 : self.e1] = 0.5 * (Pk + np.swapaxes(Pk, 1, 2))


def _group_end_covariance(P0, sol, dPi, d, pat: _Pattern):
    """Joseph form of the group update, a sum of positive semi-definite terms.

    The error of ``ŷ = y_0 + K (z − A y_0)`` after the group is
    ``(I − K A) ε_0 + Σ_j T_j Δζ_j − K v`` with ``T_j = E_d − Σ_{s: k_s ≥ j} K_s A_s,d``
    (the process-noise increment ``Δζ_j`` of epoch j reaches every later row), so::

        P = (I − K A) P_0 (I − K A)ᵀ + Σ_j T_j ΔΠ_j T_jᵀ + K R Kᵀ

    Why Joseph: the short form ``P_0 − K S Kᵀ`` subtracts two nearly equal matrices when
    the data are much better than the prior (arc-seconds against a degree) and round-off
    can leave it indefinite; the Joseph form stays positive semi-definite for any gain,
    and an error in ``K`` enters ``P`` only at second order (Bierman 1977, §V).
    """
    A = sol["A"]
    n = P0.shape[0]
    # K = W L⁻¹ = B S⁻¹  (the group gain, n × M)
    K = sol["W"] @ sol["Li"]
    IKA = -(K @ A)
    IKA[range(n), range(n)] += 1.0  # I − K A
    # P = (I − K A) P0 (I − K A)ᵀ + K R Kᵀ   (R = I for whitened rows)
    P = IKA @ P0 @ IKA.T + K @ K.T
    if sol["Hth"] is not None:
        # + σ_e² Σ_epoch (K_e H_θ,e)(K_e H_θ,e)ᵀ   (read-out noise shared within an epoch)
        KH = np.add.reduceat(K.T[:, :, None] * sol["Hth"][:, None, :], pat.starts, axis=0)
        P += sol["sig_e2"] * np.einsum("eia,eja->ij", KH, KH)
    if d:
        Ge = dPi.shape[0]
        # Σ_{s: k_s ≥ j} K_s A_s,d = K Z_j, Z_j the rows of A_d at or after epoch j
        T = (K @ sol["Z"]).reshape(n, Ge, d).transpose(1, 0, 2)
        np.negative(T, out=T)
        T[:, :d, :] += np.eye(d)  # T_j = E_d − Σ K_s A_s,d
        TQ = (T @ dPi).transpose(1, 0, 2).reshape(n, -1)
        # + Σ_j T_j ΔΠ_j T_jᵀ
        P += TQ @ T.transpose(1, 0, 2).reshape(n, -1).T
    # symmetrize deliberately: the products above leave ~1e-16 relative asymmetry, which
    # the recursion would otherwise accumulate until a Cholesky factorization fails
    return 0.5 * (P + P.T)


def _cholesky_and_inverse(S: np.ndarray):
    """Lower Cholesky factor of ``S`` and its inverse (LAPACK potrf + trtri).

    The direct LAPACK calls cost a few µs for the group sizes used here, where the
    general-purpose wrappers cost ten times more; with ``L⁻¹`` every later solve is a
    matrix product.
    """
    L, info = lapack.dpotrf(S, lower=1, clean=1)
    if info != 0:
        raise np.linalg.LinAlgError(f"innovation covariance not positive definite (pivot {info})")
    Li, info = lapack.dtrtri(L, lower=1)
    if info != 0:
        raise np.linalg.LinAlgError("singular Cholesky factor")
    return L, Li


def referred_transitions(Phi_dd: np.ndarray, Phi_ds: np.ndarray, Q: np.ndarray):
    """Block-start transitions of a structured linear system (module docstring).

    For steps k = 1..K with ``x_k = [[Φ_dd, Φ_ds], [0, I]] x_{k−1} + w_k``,
    ``cov(w_k) = Q_k`` (dynamic block only), returns ``Ψ_k = Φ_k ⋯ Φ_1`` as
    ``(Psi_dd (K, d, d), Psi_ds (K, d, s))`` and the referred process noise
    ``Π_k = Σ_{j≤k} Ψ_dd,j⁻¹ Q_j Ψ_dd,j⁻ᵀ`` (K, d, d). The products are formed by a
    parallel prefix (``ceil(log2 K)`` vectorized passes), composition being associative.
    """
    Pdd = np.array(Phi_dd, float)
    Pds = np.array(Phi_ds, float)
    K = Pdd.shape[0]
    step = 1
    while step < K:
        # (later ∘ earlier): dd = L_dd E_dd, ds = L_dd E_ds + L_ds
        new_ds = Pdd[step:] @ Pds[:-step] + Pds[step:]
        Pdd[step:] = Pdd[step:] @ Pdd[:-step]
        Pds[step:] = new_ds
        step *= 2
    inv = np.linalg.inv(Pdd)
    dPi = inv @ np.asarray(Q, float) @ np.swapaxes(inv, 1, 2)
    return Pdd, Pds, np.cumsum(0.5 * (dPi + np.swapaxes(dPi, 1, 2)), axis=0)
