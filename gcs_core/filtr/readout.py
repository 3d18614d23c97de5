"""The gyro's read-out (electronic) noise σ_e in the whole-span normal equations (ICD §5 ``electronic``).

A gyro whose integrated angle is read with a white error ``e_k ~ N(0, σ_e² I)`` at each
sample (Farrenkopf 1978; Markley & Crassidis 2014 §6.2) gives rates that carry
``(e_k − e_{k−1})/Δ``, so the attitude it carries from ``t_ref`` to ``t_k`` is off by

    δθ(t_k) = w(t_k) + e_k − e_ref

``w`` the random walk of the angle and rate noise (σ_v, σ_u: the knots of
:mod:`gcs_core.filtr.knots`), ``e_k − e_ref`` the read-out noise, which telescopes and does
not accumulate. ``e_ref`` is one constant rotation: the static roll/pitch/yaw take it up
(they are the gyro-carried trajectory's reference, which differs from the true attitude
at ``t_ref`` by ``e_ref``). What remains is a white body-frame attitude error ``ε_k = e_k``
of variance σ_e² per axis at every sample, shared by every row of every sensor at that
epoch. The measurement model of the rows ``i`` of epoch ``k`` is then::

    y_i = h_i(x, z) + D_i ε_k + v_i,   v ~ N(0, R),   D_i = ∂h_i/∂δθ   (body frame)

so the rows of one epoch are correlated: ``Cov(y_k) = R_k + σ_e² D_k D_kᵀ``. The knots
cannot carry ``e``: a knot correction ``α_j`` that were the whole error at its own epoch
would see increments ``α_{j+1} − α_j`` with ``2σ_e²`` more variance, correlated from one
interval to the next through the shared ``e_j`` (not a Markov process, which the
information-filter elimination needs). Keeping the wander (knots) and the read-out (per
epoch) apart is the exact decomposition of the simulator's and the model's error.

ε_k is eliminated per epoch in closed form (Woodbury), with the whitened rows
``[H̃ | Ũ | r̃] = R^-1/2 [H | U | r]`` and ``D̃ = R^-1/2 D``::

    (I + σ_e² D̃ D̃ᵀ)⁻¹ = I − D̃ M⁻¹ D̃ᵀ,      M_k = σ_e⁻² I + F_k,   F_k = Σ_i D̃_iᵀ D̃_i

    [H̃ Ũ r̃]ᵀ (I + σ_e² D̃ D̃ᵀ)⁻¹ [H̃ Ũ r̃] = Σ_i [.]ᵢᵀ[.]ᵢ − G_kᵀ M_k⁻¹ G_k,
    G_k = Σ_i D̃_iᵀ [H̃_i | Ũ_i | r̃_i] = [G_x | F_k C_k [I | Γ_j(t_k)] | G_r]

i.e. three pseudo-rows ``V_k = L_k⁻¹ G_k`` (``L_k L_kᵀ = M_k``) per epoch, subtracted
(a rank-3 downdate of the normal matrix, the gradient and χ²). Their knot part is
``L_k⁻¹ F_k C_k [I | Γ_j]``, the form of the knot rows with ``D → L_k⁻¹ F_k``, so the knot
blocks take them as they take the data (:func:`subtract_knot_rows`). The cost is that
of three rows per epoch over the epoch's columns; σ_e = 0 never builds this object (the
σ_e = 0 path is unchanged to the byte).

Linearization point. The gyro-carried attitude is computed from the gyro data, so it
carries ``e_k`` itself: the partials of a sensor whose signal is the attitude's small
variation about a fixed geometry (a Sun sensor's scale on a Sun-pointing spacecraft,
``∂n/∂A2 ∝ tan α``) are evaluated at ``α_true + e_k``, a regressor with errors. Linearized
at ``ε = 0`` the Gauss–Newton fixed point is the regression of the data on that noisy
attitude, biased toward zero slope (errors in variables: on a 4 h Sun-pointing mission with
σ_e three times the tracker noise the FSS ``A2``, ``A3`` came out 10–12σ off, the Kalman
filter's alike). So the passes keep ``ε̂_k`` per epoch (:class:`EpochErrors`), evaluate the
attitude at ``exp(−[ε̂_k×]) C_k`` and take the gradient in ε as ``Σ D̃ᵀ r̃ − ε̂_k/σ_e²``, the
cost with ``‖ε̂_k‖²/σ_e²``: Gauss–Newton on the joint problem in ``(x, z, ε)``, whose
minimum is the known-variance functional errors-in-variables estimate (Deming's), consistent
where the ``ε = 0`` form is not. After each accepted step ``ε̂`` moves to its conditional
optimum ``ε̂ + M⁻¹ g_ε`` at the new ``(x, z)``; the fit converges when that move is below
:data:`~gcs_core.filtr.smoothing_batch.EPS_TOL` σ_e as well. The reported residuals are at
``ε = 0`` (``r + D ε̂`` to first order): the marginal residuals, of variance
``σ² + σ_e² |D|²`` less the prediction's.

χ² becomes ``Σ_k r_kᵀ (R_k + σ_e² D_k D_kᵀ)⁻¹ r_k``, the generalized least-squares cost,
and the statics' and knots' covariance that of the correlated rows. Per row the marginal
variance is ``σ_i² + σ_e² |D_i|²`` (:func:`row_variance`): the normalized residuals, the
editing, the per-sensor χ² and leverage are formed against it (the rows of one epoch
are correlated, so the per-sensor sums are χ²-like with the right mean, not exactly
χ²-distributed). An epoch is a sample time shared by the sensors' data (the gyro's
sample times in the missions GCS reads); a sensor sampled between gyro samples would
carry the interpolated ``(1 − f) e_{k−1} + f e_k``, variance ``((1 − f)² + f²) σ_e²``,
which this form bounds from above.

References
----------
Farrenkopf, R. L., "Analytic steady-state accuracy solutions for two common spacecraft
attitude estimators", J. Guidance & Control 1(4), 1978. Markley, F. L. and Crassidis,
J. L., *Fundamentals of Spacecraft Attitude Determination and Control*, Springer 2014, §6
(gyro noise model). Golub & Van Loan, *Matrix Computations*, 4th ed., §2.1.4
(Sherman–Morrison–Woodbury). Fuller, W. A., *Measurement Error Models*, Wiley 1987, §1.3
(the functional model with known error variances).
"""

from __future__ import annotations

import numpy as np

from gcs_core.filtr import knots as kn


def row_variance(D: np.ndarray, sig_e2: float) -> np.ndarray:
    """(N, m) the read-out noise's share of each row's variance, ``σ_e² |D_i|²``
    (D (N, m, 3) the model's attitude partials, NaN rows give 0)."""
    D = np.nan_to_num(D)
    return sig_e2 * np.einsum("nma,nma->nm", D, D)


def subtract_knot_rows(sysk: kn.KnotSystem, Dp: np.ndarray, t: np.ndarray, V: np.ndarray, cols) -> None:
    """Subtract pseudo-rows from the knot blocks of ``sysk``: per epoch (E of them, times
    ``t`` in order) three rows whose knot part is ``Dp [I | Γ_j(t)]`` (Dp (E, 3, 3), the
    attitude already chained) and whose static part and residual are ``V`` (E, 3, p + 1)
    over ``cols`` (p,) and the last column (module docstring)."""
    if not t.size:
        return
    j = sysk.grid.index(t)
    U = kn.knot_rows(Dp, np.broadcast_to(np.eye(3), (t.size, 3, 3)), t, j, sysk.grid, sysk.R)  # (E, 3, d)
    knot = sysk._local(j.astype(np.int64))
    starts = np.flatnonzero(np.r_[True, knot[1:] != knot[:-1]])
    js = knot[starts]
    sysk.Dk[js] -= np.add.reduceat(np.einsum("nra,nrb->nab", U, U), starts, axis=0)
    HB = np.add.reduceat(np.einsum("nra,nrq->naq", U, V), starts, axis=0)  # (J, d, p + 1)
    cols = np.asarray(cols, int)
    if cols.size:
        Bk = sysk.Bk
        for q, c in enumerate(cols):
            Bk[js, :, c] -= HB[:, :, q]
    sysk.Bk[js, :, -1] -= HB[:, :, -1]


class EpochErrors:
    """The per-epoch read-out errors ``ε̂_k`` the whole-span fit linearizes about.

    T : (E,) the epochs (every sample time of the data); eps : (E, 3) the current
    linearization values [rad, body frame]; cond : (E, 3) their conditional optimum
    ``ε + M⁻¹ g_ε`` given the statics and knots of the last pass (:meth:`adopt` takes it).
    """

    def __init__(self, sensors):
        ts = [np.asarray(sd.t, float) for sd in sensors if sd.n]
        self.T = np.unique(np.concatenate(ts)) if ts else np.zeros(0)
        self.eps = np.zeros((self.T.size, 3))
        self.cond = self.eps.copy()
        self.stale = False  # ε̂ adopted after the last pass

    def index(self, t: np.ndarray) -> np.ndarray:
        """(n,) epoch of each time (every data time is one)."""
        return np.clip(np.searchsorted(self.T, t), 0, max(self.T.size - 1, 0))

    def at(self, t: np.ndarray) -> np.ndarray:
        """(n, 3) ε̂ at times ``t`` (0 at a time that is no epoch)."""
        if not self.T.size:
            return np.zeros((np.size(t), 3))
        i = self.index(t)
        return np.where((self.T[i] == t)[:, None], self.eps[i], 0.0)

    def moved(self, sig_e: float) -> float:
        """The largest change :meth:`adopt` would make, in σ_e (inf when ε̂ changed since the
        last pass: that pass's normal equations are not at ε̂)."""
        if self.stale:
            return float("inf")
        return float(np.max(np.abs(self.cond - self.eps))) / sig_e if self.T.size else 0.0

    def adopt(self) -> None:
        """Linearize the next passes about the last pass's conditional optimum."""
        if not self.stale:
            self.eps = self.cond.copy()
            self.stale = True


class ReadoutEpochs:
    """The per-epoch elimination of the read-out error over one streaming pass.

    A pass visits time windows, each sensor at most once per window
    (:func:`~gcs_core.problem.linearization.iter_blocks`); rows of one epoch never straddle
    windows. Per block :meth:`add` keeps the block's ``F`` and ``D̃ᵀ[H̃ | r̃]`` per frame
    (small: 3 × (k + 1) per frame); when a sensor comes round again (a new window) or at
    :meth:`finish`, the window's epochs are formed and subtracted from ``A`` (p, p),
    ``b`` (p,) (in place), the knot system (its ``passed`` calls held until then) and
    :attr:`chi2_removed`.
    """

    def __init__(
        self,
        sig_e2: float,
        A: np.ndarray,
        b: np.ndarray,
        knots: kn.KnotSystem | None,
        sensors,
        errors: EpochErrors | None = None,
    ):
        self.inv_e2 = 1.0 / float(sig_e2)
        self.errors = errors  # ε̂ the rows were evaluated at (None: ε = 0)
        self.A, self.b, self.knots = A, b, knots
        self.p = A.shape[0]
        self.order = {sd.name: i for i, sd in enumerate(sensors)}
        self.chi2_removed = 0.0
        self._last = -1
        self._parts: list[tuple] = []
        self._passed: list[tuple] = []

    def visit(self, sd) -> None:
        """A block of ``sd`` comes next: close the window when ``sd`` was in it already."""
        i = self.order[sd.name]
        if i <= self._last:
            self.flush()
        self._last = i

    def passed(self, sd, hi: int) -> None:
        """``KnotSystem.passed``, held until the window's epochs are in."""
        if self.knots is not None:
            self._passed.append((sd, hi))

    def add(self, t, D, w, C, Hm, rw, cols) -> None:
        """One block: times t (n,), attitude partials D (n, m, 3), row weights w (n, m),
        the chained attitude C (n, 3, 3) or None (no knots), weighted static rows Hm
        (n·m, k) over ``cols`` (k,), weighted residuals rw (n·m,)."""
        n, m = D.shape[:2]
        Dw = np.nan_to_num(D) * w[:, :, None]
        F = np.einsum("nma,nmb->nab", Dw, Dw)
        k = len(cols)
        X = np.empty((n, 3, k + 1))
        if k:
            X[:, :, :k] = np.einsum("nma,nmq->naq", Dw, Hm.reshape(n, m, k))
        X[:, :, k] = np.einsum("nma,nm->na", Dw, rw.reshape(n, m))
        FC = F @ C if C is not None else None
        self._parts.append((np.asarray(t, float), F, FC, X, np.asarray(cols, int)))

    def flush(self) -> None:
        """Form the held window's epochs and subtract their pseudo-rows."""
        parts, self._parts, self._last = self._parts, [], -1
        if parts:
            self._eliminate(parts)
        if self.knots is not None:
            for sd, hi in self._passed:
                self.knots.passed(sd, hi)
        self._passed = []

    def finish(self) -> float:
        """Close the last window; returns the χ² the read-out error took out."""
        self.flush()
        return self.chi2_removed

    def _eliminate(self, parts) -> None:
        T = np.unique(np.concatenate([p[0] for p in parts]))
        E, p = T.size, self.p
        F = np.zeros((E, 3, 3))
        G = np.zeros((E, p + 1, 3))  # D̃ᵀ[H̃ | r̃] per epoch, columns first (fancy-index adds)
        FC = np.zeros((E, 3, 3)) if self.knots is not None else None
        for t, Fb, FCb, X, cols in parts:
            idx = np.searchsorted(T, t)
            ext = np.append(cols, p)
            if idx.size > 1 and np.any(np.diff(idx) <= 0):  # repeated times: unbuffered adds
                np.add.at(F, idx, Fb)
                if FC is not None and FCb is not None:
                    np.add.at(FC, idx, FCb)
                np.add.at(G, (idx[:, None], ext[None, :]), np.swapaxes(X, 1, 2))
                continue
            F[idx] += Fb
            if FC is not None and FCb is not None:
                FC[idx] += FCb
            G[idx[:, None], ext[None, :], :] += np.swapaxes(X, 1, 2)
        keep = np.einsum("eaa->e", F) > 0  # epochs with attitude-sensitive rows
        if not np.all(keep):
            T, F, G = T[keep], F[keep], G[keep]
            FC = FC[keep] if FC is not None else None
        if not T.size:
            return
        M = F + self.inv_e2 * np.eye(3)
        L = np.linalg.cholesky(M)
        ro = self.errors
        if ro is not None:
            # rows evaluated at ε̂: the gradient in ε is Σ D̃ᵀ r̃ − ε̂/σ_e², and the prior's
            # ‖ε̂‖²/σ_e² is part of the cost
            k = ro.index(T)
            eps = ro.eps[k]
            G[:, p, :] -= self.inv_e2 * eps
            self.chi2_removed -= self.inv_e2 * float(np.sum(eps * eps))
        V = np.linalg.solve(L, np.swapaxes(G, 1, 2))  # (E, 3, p + 1): L⁻¹ G
        Vf = V.reshape(-1, p + 1)
        if ro is not None:
            # the conditional optimum given (x, z): ε̂ + M⁻¹ g_ε = ε̂ + L⁻ᵀ (L⁻¹ g_ε)
            ro.cond[k] = eps + np.linalg.solve(np.swapaxes(L, 1, 2), V[:, :, p : p + 1])[:, :, 0]
            ro.stale = False
        if p:
            self.A -= Vf[:, :p].T @ Vf[:, :p]
            self.b -= Vf[:, :p].T @ Vf[:, p]
        self.chi2_removed += float(Vf[:, p] @ Vf[:, p])
        if self.knots is not None and FC is not None:
            subtract_knot_rows(self.knots, np.linalg.solve(L, FC), T, V, np.arange(p))
