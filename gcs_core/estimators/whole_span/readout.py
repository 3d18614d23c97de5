"""The gyro's read-out (electronic) noise σ_e in the whole-span normal equations (ICD §5 ``electronic``).

A gyro whose integrated angle is read with a white error ``e_k ~ N(0, σ_e² I)`` at each
sample (Farrenkopf 1978; Markley & Crassidis 2014 §6.2) gives rates that carry
``(e_k − e_{k−1})/Δ``, so the attitude it carries from ``t_ref`` to ``t_k`` is off by

    δθ(t_k) = w(t_k) + e_k − e_ref

``w`` the random walk of the angle and rate noise (σ_v, σ_u: the knots of
:mod:`gcs_core.estimators.whole_span.knots`), ``e_k − e_ref`` the read-out noise, which telescopes and does
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

a rank-3 downdate per epoch of the normal matrix, the gradient and χ² (three negative
pseudo-rows ``L_k⁻¹ G_k``, ``L_k L_kᵀ = M_k``; formed as ``G_kᵀ (M_k⁻¹ G_k)`` with the 3 × 3
inverse, :func:`inverse_spd3`). Its knot part has the form of the knot rows with
``D → F_k`` on the left and ``M_k⁻¹ F_k`` on the right, so the knot blocks take it as they
take the data (:func:`.readout_knots.subtract_knot_rows`). The cost is that
of three rows per epoch over the epoch's columns; σ_e = 0 never builds this object (the
σ_e = 0 path is unchanged to the byte).

Linearization point. The gyro-carried attitude is computed from the gyro data, so it
carries ``e_k`` itself: the partials of a sensor whose signal is the attitude's small
variation about a fixed geometry (a Sun sensor's scale on a Sun-pointing spacecraft,
``∂n/∂A2 ∝ tan α``) are evaluated at ``α_true + e_k``, a regressor with errors. Linearized
at ``ε = 0`` the Gauss–Newton fixed point is the regression of the data on that noisy
attitude, biased toward zero slope (errors in variables: on a 4 h Sun-pointing mission with
σ_e three times the tracker noise the FSS ``A2``, ``A3`` came out 10–12σ off, the Kalman
filter's alike). So the passes keep ``ε̂_k`` per epoch (:class:`~.epoch_errors.EpochErrors`), evaluate the
attitude at ``exp(−[ε̂_k×]) C_k`` and take the gradient in ε as ``Σ D̃ᵀ r̃ − ε̂_k/σ_e²``, the
cost with ``‖ε̂_k‖²/σ_e²``: Gauss–Newton on the joint problem in ``(x, z, ε)``, whose
minimum is the known-variance functional errors-in-variables estimate (Deming's), consistent
where the ``ε = 0`` form is not. After each accepted step ``ε̂`` moves to its conditional
optimum ``ε̂ + M⁻¹ g_ε`` at the new ``(x, z)``; the fit converges when that move is below
:data:`~gcs_core.estimators.whole_span.fit.EPS_TOL` σ_e as well. The reported residuals are at
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

from dataclasses import dataclass

import numpy as np

from gcs_core.compiled import COMPILED
from gcs_core.estimators.whole_span import knots as kn
from gcs_core.estimators.whole_span.epoch_errors import EpochErrors, inverse_spd3
from gcs_core.estimators.whole_span.readout_kernels import (
    _epoch_solve,
    _frame_products_into,
    _row_readout,
    _scatter,
)
from gcs_core.estimators.whole_span.readout_knots import subtract_factored_knot_rows, subtract_knot_rows


def row_readout(D: np.ndarray, sig_e2: float, eps: np.ndarray | None) -> tuple[np.ndarray, np.ndarray | None]:
    """(N, m) each row's read-out variance ``σ_e² |D_i|²`` (:func:`row_variance`) and, given
    the frames' ε̂ (N, 3), ``D_i · ε̂`` (NaN partials count as 0)."""
    if COMPILED:
        D = np.ascontiguousarray(D, float)
        var = np.empty(D.shape[:2])
        De = np.empty(D.shape[:2]) if eps is not None else None
        e = np.ascontiguousarray(eps, float) if eps is not None else np.zeros((0, 3))
        _row_readout(D, e, sig_e2, var, De if De is not None else var[:0])
        return var, De
    D = np.nan_to_num(D)
    return row_variance(D, sig_e2, finite=True), (np.einsum("nma,na->nm", D, eps) if eps is not None else None)


def row_variance(D: np.ndarray, sig_e2: float, *, finite: bool = False) -> np.ndarray:
    """(N, m) the read-out noise's share of each row's variance, ``σ_e² |D_i|²``
    (D (N, m, 3) the model's attitude partials, NaN rows give 0; ``finite``: D has been
    through :func:`numpy.nan_to_num` already)."""
    if not finite:
        D = np.nan_to_num(D)
    return sig_e2 * np.einsum("nma,nma->nm", D, D)


@dataclass
class _Window:
    """One window's per-epoch sums (:meth:`ReadoutEpochs._add_into_window`): buffers over the
    epochs ``base, base + 1, …`` (global indices), of which ``[lo, hi)`` have rows."""

    base: int
    F: np.ndarray  # (S, 3, 3)
    G: np.ndarray  # (S, 3, p + 1)
    FC: np.ndarray | None  # (S, 3, 3), with knots
    lo: int
    hi: int
    tag: str = ""  # which of the two buffer sets it uses (ReadoutEpochs._cover)


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
        work: dict | None = None,
        record: bool = False,
    ):
        self.inv_e2 = 1.0 / float(sig_e2)
        self.errors = errors  # ε̂ the rows were evaluated at (None: ε = 0)
        # keep the epochs' sensitivities for the joint step's read-out part (EpochErrors.predicted)
        self.record = bool(record and errors is not None and knots is not None)
        if self.record and errors is not None:
            errors.record_start(A.shape[0])
        self.A, self.b, self.knots = A, b, knots
        self.p = A.shape[0]
        self.order = {sd.name: i for i, sd in enumerate(sensors)}
        self.chi2_removed = 0.0
        self._last = -1
        self._parts: list[tuple] = []
        self._win: _Window | None = None  # the window's epochs, added into (_add_into_window)
        self._passed: list[tuple] = []
        # the windows' (E, 3, p + 1) arrays, reused from window to window and, given the
        # caller's ``work``, from pass to pass (fresh pages cost more than the sums in them)
        self._work = work if work is not None else {}

    def _buffer(self, key: str, shape: tuple, zero: bool) -> np.ndarray:
        size = int(np.prod(shape))
        buf = self._work.get(key)
        if buf is None or buf.size < size:
            buf = self._work[key] = np.empty(size)
        out = buf[:size].reshape(shape)
        if zero:
            out.fill(0.0)
        return out

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

    def add(self, t, D, w, C, Hr, cols) -> None:
        """One block: times t (n,), attitude partials D (n, m, 3), row weights w (n, m),
        the chained attitude C (n, 3, 3) or None (no knots), ``Hr`` (n·m, k + 1) the
        weighted static rows over ``cols`` (k,) with the weighted residual last."""
        n, m = D.shape[:2]
        k = len(cols)
        Hr = np.ascontiguousarray(Hr)  # the kernels' loop along a row is unit-stride
        if COMPILED and self.errors is not None and self.errors.T.size:
            self._add_into_window(t, D, w, C, Hr, cols)
            return
        if COMPILED:  # one "epoch" per frame
            F, X = np.zeros((n, 3, 3)), np.zeros((n, 3, k + 1))
            FC = np.zeros((n, 3, 3)) if C is not None else None
            _frame_products_into(
                D,
                w,
                Hr,
                np.ascontiguousarray(C) if FC is not None else np.zeros((0, 3, 3)),
                np.arange(n, dtype=np.int64),
                np.arange(k + 1, dtype=np.int64),
                F,
                X,
                FC if FC is not None else F[:0],
            )
        else:
            Dw = np.nan_to_num(D) * w[:, :, None]
            F = np.einsum("nma,nmb->nab", Dw, Dw)
            X = np.empty((n, 3, k + 1))
            if k:
                X[:, :, :k] = np.einsum("nma,nmq->naq", Dw, Hr[:, :k].reshape(n, m, k))
            X[:, :, k] = np.einsum("nma,nm->na", Dw, Hr[:, k].reshape(n, m))
            FC = F @ C if C is not None else None
        self._parts.append((np.asarray(t, float), F, FC, X, np.asarray(cols, int)))

    def _add_into_window(self, t, D, w, C, Hr, cols) -> None:
        """One block added straight into the window's epochs (the span's epochs known: the
        frames' epoch indices are looked up, cached per frame-time array): ``F``, ``F C``
        and ``G`` per epoch in one compiled pass, no per-frame products kept."""
        t = np.asarray(t, float)
        if not t.size:
            return
        assert self.errors is not None  # the caller's condition
        g = self.errors.index(t)
        a, b = int(g.min()), int(g.max()) + 1
        win = self._cover(a, b)
        ext = np.append(np.asarray(cols, np.int64), self.p)
        FC = win.FC if C is not None and win.FC is not None else win.F[:0]
        _frame_products_into(
            D,
            w,
            Hr,
            np.ascontiguousarray(C) if FC.shape[0] else np.zeros((0, 3, 3)),
            (g - win.base).astype(np.int64),
            ext,
            win.F,
            win.G,
            FC,
        )
        win.lo, win.hi = min(win.lo, a), max(win.hi, b)

    def _cover(self, a: int, b: int) -> _Window:
        """The window's buffers, holding epochs ``[a, b)`` (global indices), zeroed where
        new: first allocated with a quarter's slack each side, re-based (copied) only when a
        later block reaches past that."""
        win = self._win
        if win is not None and win.base <= a and b <= win.base + win.F.shape[0]:
            return win
        lo, hi = (a, b) if win is None else (min(a, win.lo), max(b, win.hi))
        slack = (hi - lo) // 4 + 16
        base = max(lo - slack, 0)
        n_epochs = self.errors.T.size if self.errors is not None else hi + slack
        size = min(hi + slack, n_epochs) - base
        # buffers kept from window to window (and pass to pass with the caller's ``work``),
        # one set while a window is re-based onto the other
        tag = "" if win is None or win.tag else "'"
        new = _Window(
            base,
            self._buffer("wF" + tag, (size, 3, 3), zero=True),
            self._buffer("wG" + tag, (size, 3, self.p + 1), zero=True),
            self._buffer("wFC" + tag, (size, 3, 3), zero=True) if self.knots is not None else None,
            lo if win is None else win.lo,
            hi if win is None else win.hi,
            tag,
        )
        if win is not None:  # re-based: the epochs already added move with it
            o, u, v = win.lo - base, win.lo - win.base, win.hi - win.base
            new.F[o : o + v - u] = win.F[u:v]
            new.G[o : o + v - u] = win.G[u:v]
            if new.FC is not None and win.FC is not None:
                new.FC[o : o + v - u] = win.FC[u:v]
        self._win = new
        return new

    def flush(self) -> None:
        """Form the held window's epochs and subtract their pseudo-rows."""
        parts, self._parts, self._last = self._parts, [], -1
        win, self._win = self._win, None
        if win is not None and win.hi > win.lo:
            assert self.errors is not None  # windows are built only with the span's epochs
            u, v = win.lo - win.base, win.hi - win.base
            FC = win.FC[u:v] if win.FC is not None else None
            self._downdate(self.errors.T[win.lo : win.hi], win.F[u:v], win.G[u:v], FC, win.lo)
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

    def _window(self, parts) -> tuple[np.ndarray, list[np.ndarray], int]:
        """The window's epochs (sorted times), the epoch of each part's frames among them,
        and the first epoch's index in :attr:`EpochErrors.T` (0 without it). With the
        span's epochs known (:class:`EpochErrors`, every data time) the indices are looked
        up once per problem (cached by the frame-time arrays) and the window's epochs are
        a slice of them; epochs no part reaches have no rows and are dropped with the
        epochs without attitude-sensitive rows."""
        ro = self.errors
        if ro is None or not ro.T.size:
            T = np.unique(np.concatenate([p[0] for p in parts]))
            return T, [np.searchsorted(T, p[0]) for p in parts], 0
        gidx = [ro._locate(p[0])[0] for p in parts]
        lo = min(int(g[0]) for g in gidx if g.size)
        hi = max(int(g[-1]) for g in gidx if g.size) + 1
        return ro.T[lo:hi], [g - lo for g in gidx], lo

    def _eliminate(self, parts) -> None:
        parts = [q for q in parts if q[0].size]
        if not parts:
            return
        T, idxs, lo = self._window(parts)
        E, p = T.size, self.p
        F = self._buffer("F", (E, 3, 3), zero=True)
        G = self._buffer("G", (E, 3, p + 1), zero=True)  # D̃ᵀ[H̃ | r̃] per epoch
        FC = self._buffer("FC", (E, 3, 3), zero=True) if self.knots is not None else None
        for (_t, Fb, FCb, X, cols), idx in zip(parts, idxs):
            ext = np.append(cols, p)
            if COMPILED:  # one compiled pass adds F, F C and G (repeated epochs add in turn)
                with_fc = FC is not None and FCb is not None
                _scatter(
                    idx.astype(np.int64),
                    ext.astype(np.int64),
                    X,
                    G,
                    Fb,
                    F,
                    FCb if with_fc else Fb[:0],
                    FC if with_fc else F,
                )
                continue
            rep = idx.size > 1 and bool(np.any(np.diff(idx) <= 0))  # repeated times: unbuffered adds
            if rep:
                np.add.at(F, idx, Fb)
            else:
                F[idx] += Fb
            if FC is not None and FCb is not None:
                if rep:
                    np.add.at(FC, idx, FCb)
                else:
                    FC[idx] += FCb
            if rep:
                for q, c in enumerate(ext):
                    np.add.at(G[:, :, c], idx, X[:, :, q])
            else:  # the advanced indices' axes come first: (n, k + 1, 3)
                G[idx[:, None], :, ext[None, :]] += np.swapaxes(X, 1, 2)
        self._downdate(T, F, G, FC, lo)

    def _downdate(self, T, F, G, FC, lo: int) -> None:
        """Subtract the window's epochs (times T (E,), ``F``, ``G`` = D̃ᵀ[H̃ | r̃] (E, 3, p + 1),
        ``F C`` or None; ``lo`` the first epoch's index in :attr:`EpochErrors.T`)."""
        E, p = T.size, self.p
        keep = np.einsum("eaa->e", F) > 0  # epochs with attitude-sensitive rows
        k = np.arange(lo, lo + E)  # their indices in EpochErrors.T (with ``errors``)
        if not np.all(keep):
            T, F, G, k = T[keep], F[keep], G[keep], k[keep]
            FC = FC[keep] if FC is not None else None
        if not T.size:
            return
        ro = self.errors
        if ro is not None:
            # rows evaluated at ε̂: the gradient in ε is Σ D̃ᵀ r̃ − ε̂/σ_e², and the prior's
            # ‖ε̂‖²/σ_e² is part of the cost
            eps = ro.eps[k]
            G[:, :, p] -= self.inv_e2 * eps
            self.chi2_removed -= self.inv_e2 * float(np.sum(eps * eps))
        if COMPILED:
            # with M = L Lᵀ per epoch, V = L⁻¹ G: Gᵀ M⁻¹ G = Vᵀ V, one symmetric product
            # (BLAS syrk) for the normal matrix, the gradient and χ² at once; W = L⁻¹ F C
            # gives the knots' part the same way (subtract_factored_knot_rows)
            V, W, y_eps = self._buffer("V", G.shape, zero=False), np.empty_like(F), np.empty((F.shape[0], 3))
            _epoch_solve(F, G, FC if FC is not None else F[:0], self.inv_e2, V, W, y_eps)
            Vf = V.reshape(-1, p + 1)
            S = Vf.T @ Vf
            if p:
                self.A -= S[:p, :p]
                self.b -= S[:p, p]
            self.chi2_removed += float(S[p, p])
            if ro is not None:
                ro.cond[k] = eps + y_eps  # the conditional optimum given (x, z): ε̂ + M⁻¹ g_ε
                ro.stale = False
                if self.record and FC is not None:
                    ro.record(k, G[:, :, :p], F, FC, ro.cond[k])
            if self.knots is not None and FC is not None:
                subtract_factored_knot_rows(self.knots, W, T, V, np.arange(p))
            return
        Minv = inverse_spd3(F + self.inv_e2 * np.eye(3))
        Y = np.matmul(Minv, G)  # (E, 3, p + 1): M⁻¹ G
        Gf, Yf = G.reshape(-1, p + 1), Y.reshape(-1, p + 1)
        if p:
            S = Gf[:, :p].T @ Yf[:, :p]  # Σ G_xᵀ M⁻¹ G_x, symmetric to round-off
            self.A -= 0.5 * (S + S.T)
            self.b -= Gf[:, :p].T @ Yf[:, p]
        self.chi2_removed += float(Gf[:, p] @ Yf[:, p])
        if ro is not None:
            ro.cond[k] = eps + Y[:, :, p]  # the conditional optimum given (x, z): ε̂ + M⁻¹ g_ε
            ro.stale = False
            if self.record and FC is not None:
                ro.record(k, G[:, :, :p], F, FC, ro.cond[k])
        if self.knots is not None and FC is not None:
            subtract_knot_rows(self.knots, FC, np.matmul(Minv, FC), T, Y, np.arange(p))


def seed_errors(errors: EpochErrors, sensors, residuals, partials, sig_e2: float) -> None:
    """``errors``' conditional optimum ``M⁻¹ Σ D̃ᵀ r̃`` per epoch at ε = 0 from a pass's
    residuals (sensor -> :class:`~gcs_core.estimators.results.SensorResiduals`) and attitude
    partials (sensor -> (N, m, 3)) at the point where the fit starts, without knots (the
    batch's solution): what a pass without the Jacobian there finds, with no model
    evaluated; ``errors.seeded`` says so until the fit takes it."""
    ro = ReadoutEpochs(sig_e2, np.zeros((0, 0)), np.zeros(0), None, sensors, errors)
    for sd in sensors:
        D, res = partials.get(sd.name), residuals.get(sd.name)
        if D is None or res is None or not sd.n:
            continue
        used = np.asarray(res.used, bool)
        w = used[:, None] / sd.sigma[None, :]
        rw = np.where(used[:, None], np.asarray(res.residual, float), 0.0) / sd.sigma[None, :]
        ro.visit(sd)
        ro.add(np.asarray(sd.t, float), D, w, None, rw.reshape(-1, 1), np.zeros(0, np.int64))
    ro.finish()
    errors.seeded = True
