"""Kalman-filter core of FILTR (seed §3.2.1, Eq 3-3 and 3-4; gyro transition Eq 4-38).

The filter state is ``x = (δθ, b, s)``: ``δθ`` the body attitude-error angles *of the
current time* (the state elements ``att.roll/pitch/yaw`` are reinterpreted as these, with
the convention ``C_true = (I − [δθ×]) C`` of :mod:`gcs_core.models.base`), ``b`` the gyro
drift biases when they random-walk (``rrw > 0``), and ``s`` every static solve-for
parameter (gyro scale/misalignment, biases when ``rrw = 0``, sensor parameters). The
dynamic part ``d = (δθ, b)`` has ``d`` = 3 or 6 elements. Between times the filter
propagates (Eq 3-4)::

    x_k = Φ_k x_{k−1} + w_k,   P_k⁻ = Φ_k P_{k−1} Φ_kᵀ + Q_k                     (Eq 3-4)
    Φ_θθ = C_k C_{k−1}ᵀ,   Φ_θp = C_k (E_k − E_{k−1}) = W_k Δ_k   (Eq 4-38, attitude.py)

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
round-off (``tests/test_kalman.py``) at several times its speed
(``benchmarks/kalman_vs_filterpy.py``).

References
----------
Lefferts, Markley & Shuster, "Kalman filtering for spacecraft attitude estimation",
J. Guidance 5(5), 1982 (multiplicative EKF, Farrenkopf noise). Bierman, *Factorization
Methods for Discrete Sequential Estimation*, Academic Press 1977, §V (Joseph form, why).
Kailath, Sayed & Hassibi, *Linear Estimation*, Prentice Hall 2000, §4.1 (innovations
from the Cholesky factor of the covariance of stacked observations).
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from scipy.linalg import lapack

__all__ = ["LinearBlock", "BlockSolution", "solve_block", "referred_transitions",
           "group_partition"]


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


def solve_block(y0: np.ndarray, P0: np.ndarray, blk: LinearBlock, *, edit_k: float | None = 5.0,
                group_rows: int = 48, keep_epochs: bool = False) -> BlockSolution:
    """Filter one block (Eq 3-3, 3-4) group by group, with k-σ innovation gating.

    Parameters
    ----------
    y0 : (n,) prior mean at the block start; P0 : (n, n) its covariance.
    blk : the block's rows and process noise (:class:`LinearBlock`).
    edit_k : a frame whose normalized innovation ``|ν_i|/sqrt(S_ii)`` exceeds ``edit_k`` in
        any component is flagged and skipped (None: no gate). The gate uses the innovation
        given every earlier accepted frame, exactly as a frame-by-frame filter would.
    group_rows : scalar rows per lifted group (speed only; the answer does not depend on it).
    keep_epochs : also return the posterior at every epoch (for the smoother).
    """
    n, d = blk.n, blk.d
    G, F = blk.t.size, blk.frame_start.size
    m_max = int(blk.frame_m.max()) if F else 1
    nu = np.full((F, m_max), np.nan)
    S_out = np.full((F, m_max, m_max), np.nan)
    nis = np.full(F, np.nan)
    knorm = np.full(F, np.nan)
    gated = np.zeros(F, bool)
    y_ep = np.empty((G, n)) if keep_epochs else None
    P_ep = np.empty((G, n, n)) if keep_epochs else None
    frame_of_row = np.repeat(np.arange(F), blk.frame_m)
    bounds = group_partition(blk.row_epoch, G, group_rows)
    row_bounds = np.searchsorted(blk.row_epoch, bounds)
    frame_bounds = np.searchsorted(blk.frame_epoch, bounds)
    y, P = np.array(y0, float), np.array(P0, float)
    zero_d = np.zeros((d, d))
    for g in range(bounds.size - 1):
        e0, e1 = bounds[g], bounds[g + 1]
        base = blk.Pi[e0 - 1] if e0 > 0 else zero_d
        grp = _Group(blk, e0, e1, row_bounds[g], row_bounds[g + 1], frame_bounds[g],
                     frame_bounds[g + 1], frame_of_row, blk.Pi[e0:e1] - base)
        y, P = grp.run(y, P, edit_k, (nu, S_out, nis, knorm, gated), y_ep, P_ep)
    return BlockSolution(y, P, nu, S_out, nis, knorm, gated, y_ep, P_ep)


class _Group:
    """One lifted group of consecutive epochs (module docstring)."""

    def __init__(self, blk: LinearBlock, e0, e1, r0, r1, f0, f1, frame_of_row, Pig):
        self.blk, self.e0, self.e1, self.f0, self.f1 = blk, e0, e1, f0, f1
        self.A = blk.A[r0:r1]
        self.r = blk.r[r0:r1]
        self.sig = blk.sigma[r0:r1]
        self.rep = blk.row_epoch[r0:r1] - e0
        self.rframe = frame_of_row[r0:r1] - f0
        self.Hth = blk.Hth[r0:r1] if blk.Hth is not None and blk.sig_e2 > 0 else None
        self.m = blk.frame_m[f0:f1]
        self.fep = blk.frame_epoch[f0:f1] - e0
        self.Pig = Pig                                      # (Ge, d, d) noise since group start
        self.d = blk.d
        self.m_values = np.unique(self.m)

    def run(self, y0, P0, edit_k, out, y_ep, P_ep):
        nf = self.f1 - self.f0
        active = np.ones(nf, bool)
        while True:
            rows = active[self.rframe]
            sol = self._solve(y0, P0, rows)
            if sol is None:
                break
            diag = self._frame_diagnostics(sol, active)
            if edit_k is None:
                break
            bad = np.nonzero(diag["zmax"] > edit_k)[0]
            if bad.size == 0:
                break
            first = diag["frames"][bad[0]]                 # earliest gated frame in the group
            self._store(out, diag, bad[:1])
            out[4][self.f0 + first] = True
            active[first] = False
        if sol is None:                                     # nothing to update with: propagate only
            n = P0.shape[0]
            Pend = P0.copy()
            Pend[:self.d, :self.d] += self.Pig[-1]
            if y_ep is not None:
                y_ep[self.e0:self.e1] = y0
                P_ep[self.e0:self.e1] = P0
                P_ep[self.e0:self.e1, :self.d, :self.d] += self.Pig
            return y0.copy(), Pend
        self._store(out, diag, np.arange(diag["frames"].size), with_gain=sol)
        y_end = y0 + sol["W"] @ sol["e"]                    # x = x⁻ + K (z − H x⁻), all rows
        P_end = _group_end_covariance(P0, sol, self.Pig, self.d)
        if y_ep is not None:
            self._epochs(y0, P0, sol, y_ep, P_ep)
        return y_end, P_end

    # -- one solve over the active rows ------------------------------------------------
    def _solve(self, y0, P0, rows):
        if not np.any(rows):
            return None
        A, rep = self.A[rows], self.rep[rows]
        d = self.d
        # B = cov(y, z) = (P0 + Π_{k_s}) A_sᵀ
        B = P0 @ A.T
        if d:
            B[:d] += np.einsum("mij,mj->im", self.Pig[rep], A[:, :d])
        # S = A B for k_r ≥ k_s, mirrored, + R (= I after whitening)
        S = A @ B
        S = np.where(rep[:, None] >= rep[None, :], S, S.T)
        S.flat[::S.shape[0] + 1] += 1.0
        Hth = None
        if self.Hth is not None:
            Hth = self.Hth[rows]
            same = rep[:, None] == rep[None, :]
            # read-out noise: a white attitude error shared by the rows of one epoch
            S += self.blk.sig_e2 * np.where(same, Hth @ Hth.T, 0.0)
        L, Li = _cholesky_and_inverse(S)
        # e = L⁻¹ (z − A y⁻): whitened sequential innovations
        e = Li @ (self.r[rows] - A @ y0)
        # W = B L⁻ᵀ = cov(y, e)
        W = B @ Li.T
        return {"rows": rows, "A": A, "rep": rep, "L": L, "Li": Li, "e": e, "W": W,
                "Hth": Hth, "sig": self.sig[rows], "sig_e2": self.blk.sig_e2}

    def _frame_diagnostics(self, sol, active):
        """Innovation, S and NIS of every active frame from the frame blocks of L."""
        frames = np.nonzero(active)[0]
        m = self.m[frames]
        start = np.cumsum(m) - m                           # first row in the active rows
        out = {"frames": frames, "zmax": np.zeros(frames.size), "nu": {}, "S": {}, "nis": {},
               "idx": {}}
        for mm in self.m_values:
            sel = np.nonzero(m == mm)[0]
            if sel.size == 0:
                continue
            idx = start[sel][:, None] + np.arange(mm)
            blocks = (idx[:, :, None], idx[:, None, :])
            Lff = sol["L"][blocks]
            ef = sol["e"][idx]
            nu_w = np.einsum("fij,fj->fi", Lff, ef)        # ν_f = L_ff e_f
            S_w = Lff @ np.swapaxes(Lff, 1, 2)              # S_f = L_ff L_ffᵀ
            s = sol["sig"][idx]
            out["zmax"][sel] = np.max(np.abs(nu_w) / np.sqrt(np.einsum("fii->fi", S_w)), axis=1)
            out["nu"][mm] = (sel, nu_w * s)
            out["S"][mm] = S_w * s[:, :, None] * s[:, None, :]
            out["nis"][mm] = np.sum(ef ** 2, axis=1)       # NIS = νᵀ S⁻¹ ν = |e_f|²
            out["idx"][mm] = (sel, idx, blocks, s)
        return out

    def _store(self, out, diag, which, with_gain=None):
        nu, S, nis, knorm, _ = out
        which_set = np.zeros(diag["frames"].size, bool)
        which_set[which] = True
        for mm, (sel, vals) in diag["nu"].items():
            keep = which_set[sel]
            fr = self.f0 + diag["frames"][sel[keep]]
            nu[fr, :mm] = vals[keep]
            S[fr, :mm, :mm] = diag["S"][mm][keep]
            nis[fr] = diag["nis"][mm][keep]
            if with_gain is not None:
                _, idx, blocks, s = diag["idx"][mm]
                # K_f = W_f L_ff⁻¹ ((L⁻¹)_ff = (L_ff)⁻¹), in telemetry units: K_f diag(1/σ)
                Wf = np.swapaxes(with_gain["W"][:, idx], 0, 1)          # (Fm, n, mm)
                Kf = Wf @ with_gain["Li"][blocks] / s[:, None, :]
                if self.d and self.blk.Psi_d is not None:
                    ep = self.e0 + self.fep[diag["frames"][sel]]
                    Kf[:, :self.d] = self.blk.Psi_d[ep] @ Kf             # to current-time coords
                knorm[fr] = np.sqrt(np.sum(Kf[keep] ** 2, axis=(1, 2)))

    def _epochs(self, y0, P0, sol, y_ep, P_ep):
        """Posterior at every epoch of the group (rows up to that epoch)."""
        rep, W, e = sol["rep"], sol["W"], sol["e"]
        Ge = self.e1 - self.e0
        last = np.searchsorted(rep, np.arange(Ge), side="right") - 1
        has = last >= 0
        ycum = np.cumsum(W * e[None, :], axis=1)            # Σ_{s≤r} K_s ν_s
        y_ep[self.e0:self.e1] = y0
        y_ep[self.e0:self.e1][has] += ycum[:, last[has]].T
        WW = np.cumsum(np.einsum("is,js->sij", W, W), axis=0)
        Pk = np.broadcast_to(P0, (Ge,) + P0.shape).copy()
        Pk[:, :self.d, :self.d] += self.Pig                 # P0 + Π_k
        Pk[has] -= WW[last[has]]                            # − cov(y, e_{≤k}) cov(...)ᵀ
        P_ep[self.e0:self.e1] = 0.5 * (Pk + np.swapaxes(Pk, 1, 2))


def _group_end_covariance(P0, sol, Pig, d):
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
    A, W = sol["A"], sol["W"]
    n = P0.shape[0]
    # K = W L⁻¹ = B S⁻¹  (the group gain, n × M)
    K = W @ sol["Li"]
    IKA = np.eye(n) - K @ A
    # P = (I − K A) P0 (I − K A)ᵀ
    P = IKA @ P0 @ IKA.T
    # + K R Kᵀ  (R = I for whitened rows)
    P += K @ K.T
    if sol["Hth"] is not None:
        # + σ_e² Σ_epoch (K_e H_θ,e)(K_e H_θ,e)ᵀ   (read-out noise shared within an epoch)
        rep = sol["rep"]
        starts = np.nonzero(np.r_[True, np.diff(rep) != 0])[0]
        KH = np.add.reduceat(K.T[:, :, None] * sol["Hth"][:, None, :], starts, axis=0)
        P += sol["sig_e2"] * np.einsum("eia,eja->ij", KH, KH)
    if d:
        rep = sol["rep"]
        Ge = Pig.shape[0]
        # Σ_{s: k_s ≥ j} K_s A_s,d by a reverse cumulative sum over rows
        O = K.T[:, :, None] * A[:, None, :d]                 # (M, n, d)
        rev = np.concatenate([np.cumsum(O[::-1], axis=0)[::-1], np.zeros((1, n, d))])
        first = np.searchsorted(rep, np.arange(Ge), side="left")
        T = -rev[first]
        T[:, np.arange(d), np.arange(d)] += 1.0              # T_j = E_d − Σ K_s A_s,d
        dPi = np.diff(Pig, axis=0, prepend=np.zeros((1, d, d)))
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
