"""Gyro process noise as dynamic attitude and bias corrections at knots (seed §3.2.1, Eq 4-38).

The batch carries the attitude with the gyros from the roll/pitch/yaw at ``t_ref`` and
treats the propagation as exact between its static parameters. The gyro's angle random
walk (σ_v) and rate random walk (σ_u) make the true attitude wander away from that
trajectory. Here the wander is a correction to the gyro-carried attitude, held at knots
``τ_0 < τ_1 < … < τ_{K−1}`` along the span: per knot ``z_j = (α_j, β_j)``, ``α`` a
small GCI-frame rotation (the body-frame error is ``δθ = C α``, the convention of
:mod:`gcs_core.problem.attitude` where ``Cᵀ δθ`` is the cumulative sum) and ``β`` a
body-axis drift-bias correction. Between knots the correction is carried by the bias::

    α(t) = α_j + Γ_j(t) β_j,   Γ_j(t) = −(t − τ_j) R_j,   R_j = C(τ_j + Δ_j/2)ᵀ

and from knot to knot the increments are the process noise of Farrenkopf's model
(:func:`gcs_core.models.gyro_noise.farrenkopf_q` with ``W_y = I``, ``W_b = −R``; ``R`` is a
rotation)::

    z_{j+1} = Φ_j z_j + w_j,   Φ_j = [[I, −Δ_j R_j], [0, I]],   w_j ~ N(0, Q_j)
    Q_j = [[a I, c R_j], [c R_jᵀ, e I]],  a = σ_v² Δ + σ_u² Δ³/3,  c = −σ_u² Δ²/2,  e = σ_u² Δ
    Q_j⁻¹ = [[e I, −c R_j], [−c R_jᵀ, a I]] / (a e − c²)

``z_0 = 0``: the static roll/pitch/yaw and gyro bias carry the initial condition, so the
prior on the increments alone defines the problem and ``Q → 0`` forces ``z ≡ 0`` (the
batch). Without a rate random walk (σ_u = 0) only ``α`` is dynamic (d = 3).

The whole-span MAP problem in ``(x, z_1 … z_{K−1})`` has a normal matrix that is
block-tridiagonal in the knots with a dense border to the p static columns.
:class:`KnotSystem` accumulates the knot blocks from the measurement rows and
eliminates them (forward block Cholesky, the information filter), leaving the p × p
reduced (marginal) normal matrix of the static elements, whose inverse is their
covariance; back-substitution (the RTS smoother) gives the knot steps, and a backward
recursion the knots' marginal covariances and their cross-covariance with ``x``.

References
----------
Farrenkopf, R. L., "Analytic steady-state accuracy solutions for two common spacecraft
attitude estimators", J. Guidance Control 1(4), 1978 (the Q above). Bell, B. M., "The
iterated Kalman smoother as a Gauss–Newton method", SIAM J. Optim. 4(3), 1994.
Rauch, Tung & Striebel, AIAA J. 3(8), 1965. Golub & Van Loan, *Matrix Computations*,
4th ed., §4.5 (block tridiagonal elimination).
"""

from __future__ import annotations

import warnings
from dataclasses import dataclass

import numpy as np

from gcs_core import limits
from gcs_core.compiled import COMPILED, jit
from gcs_core.errors import InputError
from gcs_core.estimators.whole_span.knot_kernels import _accumulate, _accumulate_fused, _accumulate_numpy
from gcs_core.models.gyro_noise import GyroNoise, farrenkopf_q

_jit = jit()
# the 6×6 knot products below run on strided slices by design; numba's advice to copy them
# first is noise to a user reading the first (compiling) run's output
warnings.filterwarnings("ignore", message="'@' is faster on contiguous arrays")

#: intra-interval wander variance allowed against the attitude variance the data give
#: over one knot interval (the knot-spacing rule of :func:`knot_spacing`)
SPACING_EPS = 0.05
#: halvings of the first knot interval, where the static attitude is (:func:`make_grid`)
START_REFINE = 3
#: knot corrections below this [rad] chain through ``C`` alone (:func:`chained_attitude`):
#: the left Jacobian differs from I by |α|/2 ≤ 1e-4 there, below what moves a solution
SMALL_CORRECTION = 2e-4


@dataclass(frozen=True)
class KnotGrid:
    """Knot times and the gyro noise of the dynamic corrections (module docstring).

    tau : (K,) knot times [s]; sigma_v [rad/s^0.5], sigma_u [rad/s^1.5]; d : 3 or 6.
    """

    tau: np.ndarray
    sigma_v: float
    sigma_u: float

    @property
    def d(self) -> int:
        return 6 if self.sigma_u > 0 else 3

    @property
    def K(self) -> int:
        return int(self.tau.size)

    def index(self, t) -> np.ndarray:
        """(N,) knot of each time: ``τ_j ≤ t < τ_{j+1}`` (clipped to the grid)."""
        return np.clip(np.searchsorted(self.tau, t, side="right") - 1, 0, self.K - 1)

    def mid_times(self) -> np.ndarray:
        return 0.5 * (self.tau[:-1] + self.tau[1:])


def make_grid(
    t0: float,
    t1: float,
    spacing: float,
    sigma_v: float,
    sigma_u: float,
    refine: int = START_REFINE,
    min_step: float = 0.0,
) -> KnotGrid:
    """Knots from ``t0`` to past ``t1`` at (about) ``spacing`` seconds, equally spaced,
    except near ``t0``: the first interval cut at ``Δ/2, Δ/4, … Δ/2^refine`` from ``t0``,
    the next two halved (a graded mesh).

    The static roll/pitch/yaw are the attitude at ``t0`` (``z_0 = 0``), an end of the
    span, where the data on one side only determine it: over about the first knot
    interval, where the corrections are held at zero. The wander inside that interval,
    which a knot's correction does not follow, is then a sizeable part of the attitude's
    error: with equal intervals the fitted σ of the attitude at ``t0`` came out 5–10 %
    below its Monte-Carlo scatter (``benchmarks/optimizer_montecarlo.py``), while every
    element averaged over the span matched. Halving the first interval ``refine`` times
    shrinks that wander by ``2^refine`` at ``t0``, halving the next two covers the
    rest of the data that determine it (the spacing is a third of the time over which
    the data balance the wander, :func:`knot_spacing`); the grid beyond is left alone,
    so a fit gains ``refine + 2`` knots. No cut makes an interval shorter than ``min_step`` (the
    gyro's sample interval).
    """
    span = max(float(t1 - t0), 1e-9)
    if span / max(spacing, 1e-9) > limits.MAX_KNOTS:  # before any allocation
        raise InputError(
            f"{span / max(spacing, 1e-9):.3g} knots of {spacing:g} s over {span:g} s; at most {limits.MAX_KNOTS} "
            "(the spacing follows the gyro's arw, rrw and sample interval)",
            key="whole_span.knots",
        )
    n = max(1, int(np.ceil(span / max(spacing, 1e-9))))
    tau = t0 + np.arange(n + 1) * (span / n)
    tau[-1] = t1 + 1e-6 * (span / n)  # the last knot closes the span
    h = tau[1] - tau[0]
    cuts = [h / 2.0**k for k in range(refine, 0, -1) if h / 2.0**k >= min_step]
    if h / 2.0 >= min_step:  # and the next two intervals halved
        cuts += [h * (j + 0.5) for j in range(1, min(3, n))]
    if cuts:
        tau = np.sort(np.concatenate([tau, t0 + np.array(cuts)]))
    return KnotGrid(tau, float(sigma_v), float(sigma_u))


def knot_spacing(
    sigma_v: float, info_rate: float, *, dt_min: float = 1.0, dt_max: float = 300.0, eps: float = SPACING_EPS
) -> float:
    """Knot spacing Δ that makes the wander not modelled inside an interval negligible
    against what the data determine over it.

    Inside an interval the random walk's variance about the carried correction averages
    ``σ_v² Δ/2``; the data give the attitude to a variance ``1/(I Δ)`` over the interval
    (``I`` the attitude information per second of the best-determined axis). Their ratio
    ``σ_v² I Δ²/2 ≤ eps`` gives ``Δ = sqrt(2 eps/(σ_v² I))``, clipped to
    ``[dt_min, dt_max]``.
    """
    if sigma_v <= 0 or info_rate <= 0:
        return dt_max
    return float(np.clip(np.sqrt(2.0 * eps / (sigma_v**2 * info_rate)), dt_min, dt_max))


def transitions(grid: KnotGrid, R: np.ndarray):
    """Φ_j, Q_j⁻¹ (K−1, d, d) of every interval from the mid-interval ``R_j`` (K−1, 3, 3).

    ``Q_j`` is Farrenkopf's (:func:`~gcs_core.models.gyro_noise.farrenkopf_q`) for the
    GCI-frame ``α`` (``W_y = I``, ``W_b = −R_j``); it is inverted scaled to unit diagonal
    (the α and β variances differ by many decades; their correlation is at most √3/2).
    """
    dt = np.diff(grid.tau)
    n, d = dt.size, grid.d
    Phi = np.zeros((n, d, d))
    eye = np.eye(3)
    Phi[:, :3, :3] = eye
    if d == 6:
        Phi[:, 3:, 3:] = eye
        Phi[:, :3, 3:] = -dt[:, None, None] * R
    Q = farrenkopf_q(dt, GyroNoise(grid.sigma_v, grid.sigma_u), eye, -R if d == 6 else eye, range(3) if d == 6 else ())
    s = 1.0 / np.sqrt(np.einsum("kii->ki", Q))
    W = np.linalg.inv(Q * s[:, :, None] * s[:, None, :]) * s[:, :, None] * s[:, None, :]
    return Phi, 0.5 * (W + np.swapaxes(W, 1, 2))


def knot_rows(
    D: np.ndarray,
    C: np.ndarray,
    t: np.ndarray,
    j: np.ndarray,
    grid: KnotGrid,
    R: np.ndarray,
    w: np.ndarray | None = None,
) -> np.ndarray:
    """(N, m, d) partials of the measurements with respect to their knot's ``z_j``:
    ``∂y/∂α = D C`` and ``∂y/∂β = D C Γ_j(t)`` (module docstring), rows scaled by ``w``.

    D : (N, m, 3) model attitude partials; C : (N, 3, 3) attitude; t, j : (N,) times and
    knots; R : (K−1, 3, 3) mid-interval rotations.
    """
    DC = np.matmul(D, C)
    if w is not None:
        DC *= w[:, :, None]
    if grid.d == 3:
        return DC
    out = np.empty(D.shape[:2] + (6,))
    out[:, :, :3] = DC
    Rj = R[np.minimum(j, R.shape[0] - 1)] if R.shape[0] else np.broadcast_to(np.eye(3), (t.size, 3, 3))
    s = -(t - grid.tau[j])
    np.matmul(DC, Rj * s[:, None, None], out=out[:, :, 3:])
    return out


def left_jacobian(v: np.ndarray) -> np.ndarray:
    """(N, 3, 3) left Jacobian of SO(3) at rotation vectors ``v`` (N, 3)::

        J_l(v) = I + (1 − cos θ)/θ² [v×] + (θ − sin θ)/θ³ [v×]²,   θ = |v|

    (series below θ = 1e-4). With ``E(v) = exp(−[v×])`` (:func:`rotvec_to_dcm`),
    ``E(v + dv) = E(J_l(v) dv)·E(v)`` to first order in ``dv`` once moved into the frame
    ``C`` (``C_corr = C E(α)``): the body-frame error is ``δθ = C_corr J_l(α) dα``.

    References
    ----------
    Barfoot, *State Estimation for Robotics*, Cambridge 2017, §7.1.5 (Jacobians of SO(3)).
    """
    v = np.asarray(v, float)
    th = np.linalg.norm(v, axis=-1)[:, None, None]
    K = np.zeros(v.shape[:1] + (3, 3))
    K[:, 0, 1], K[:, 0, 2], K[:, 1, 2] = -v[:, 2], v[:, 1], -v[:, 0]
    K[:, 1, 0], K[:, 2, 0], K[:, 2, 1] = v[:, 2], -v[:, 1], v[:, 0]
    small = th < 1e-4
    safe = np.where(small, 1.0, th)
    a = np.where(small, 0.5 - th**2 / 24.0, (1.0 - np.cos(safe)) / safe**2)
    b = np.where(small, 1.0 / 6.0 - th**2 / 120.0, (safe - np.sin(safe)) / safe**3)
    return np.eye(3) + a * K + b * (K @ K)


def chained_attitude(C: np.ndarray, grid: KnotGrid, z: np.ndarray, R: np.ndarray, t: np.ndarray) -> np.ndarray:
    """(N, 3, 3) the matrix the knot partials chain through, ``C J_l(α(t))``: ``C`` is the
    corrected attitude at times ``t``, ``α(t)`` the correction there (:func:`left_jacobian`).

    ``C`` alone is the first-order chain, exact at ``α = 0``. Its error grows as |α|/2
    (6 % at 7°), and where static and knot steps nearly cancel (the gyro bias against the
    knots' drift corrections over days) a few per cent in the knot columns turned the
    Gauss–Newton direction of a week-long span into one along which the cost barely falls.
    """
    if not np.any(z) or C is None or not t.size:
        return C
    if _correction_bound(grid, z, t) < SMALL_CORRECTION:
        return C  # every |α| is below it (a bound from the knots alone, no per-frame work)
    a = alpha_at(grid, z, R, t)
    if not a.size or float(np.max(np.abs(a))) < SMALL_CORRECTION:
        return C
    return np.matmul(C, left_jacobian(a))


def _correction_bound(grid: KnotGrid, z: np.ndarray, t: np.ndarray) -> float:
    """An upper bound of ``max |α(t)|`` (every component) over the times ``t``:
    ``|α_c| ≤ |α_j,c| + |t − τ_j| |β_j|`` (``R_j`` a rotation), ``|t − τ_j|`` at most the
    longest interval or the times' overhang of the grid's ends (with a margin for
    round-off in ``R``)."""
    a = float(np.max(np.abs(z[:, :3])))
    if grid.d == 6:
        tau = grid.tau
        s_max = max(
            float(np.max(np.diff(tau))) if tau.size > 1 else 0.0,
            float(np.max(t)) - float(tau[-1]),
            float(tau[0]) - float(np.min(t)),
        )
        a += abs(s_max) * float(np.max(np.linalg.norm(z[:, 3:], axis=1)))
    return a * (1.0 + 1e-6)


def alpha_at(grid: KnotGrid, z: np.ndarray, R: np.ndarray, t: np.ndarray) -> np.ndarray:
    """(N, 3) GCI-frame attitude correction ``α(t) = α_j + Γ_j(t) β_j``."""
    j = grid.index(t)
    a = z[j, :3].copy()
    if grid.d == 6 and R.shape[0]:
        s = -(t - grid.tau[j])
        a += s[:, None] * np.einsum("nab,nb->na", R[np.minimum(j, R.shape[0] - 1)], z[j, 3:])
    return a


class KnotSystem:
    """Knot blocks of the whole-span normal equations over ``p`` static columns.

    Per knot ``Σ uᵀu`` (d, d) and ``Σ uᵀ [H | r]`` (d, p+1) over the weighted rows, and the
    forward elimination (:func:`_forward_range`). With ``stream`` the knots are eliminated
    as soon as the data have passed them (:meth:`flush`), so only the knots still open are
    held (bounded memory whatever the span), and ``keep`` stores the factors the
    back-substitution and covariances need (d × (p+1) per knot); without ``stream`` the
    full ``Dk`` (K, d, d), ``Bk`` (K, d, p+1) are kept until :meth:`eliminate`.
    """

    def __init__(
        self, grid: KnotGrid, p: int, R: np.ndarray, z: np.ndarray, *, stream: bool = False, keep: bool = True
    ):
        self.grid, self.p, self.R, self.z = grid, p, R, z
        self.stream, self.keep = stream, keep
        d, K = grid.d, grid.K
        self.Phi, self.W = transitions(grid, R)
        e = z[1:] - np.einsum("nab,nb->na", self.Phi, z[:-1])
        self._We = np.einsum("nab,nb->na", self.W, e)
        self._prior = float(np.einsum("na,na->", e, self._We))
        self.base = 0  # first knot not yet eliminated
        cap = K if not stream else min(K, 64)
        self.Dk = np.zeros((cap, d, d))
        self.Bk = np.zeros((cap, d, p + 1))
        self.Msub = np.zeros((p + 1, p + 1))  # Σ B̂ᵀ S⁻¹ B̂ over eliminated knots
        self._carry = (np.zeros((d, d)), np.zeros((d, p + 1)), np.zeros((d, d)))
        if keep:
            self._fac = (np.zeros((K, d, d)), np.zeros((K, d, p + 1)), np.zeros((K, d, d)))
        else:
            self._fac = (np.zeros((1, d, d)), np.zeros((1, d, p + 1)), np.zeros((1, d, d)))
        self.knot_gain = 0.0

    # ----------------------------------------------------------------- accumulation
    def _local(self, knot: np.ndarray) -> np.ndarray:
        """Knot indices relative to the held buffer (grown to hold them)."""
        if knot.size and int(knot[0]) < self.base:
            raise AssertionError("knot data arrived after the knot was eliminated")
        top = int(knot.max()) - self.base + 1 if knot.size else 0
        if top > self.Dk.shape[0]:
            cap = max(top, 2 * self.Dk.shape[0])
            for name in ("Dk", "Bk"):
                old = getattr(self, name)
                new = np.zeros((cap,) + old.shape[1:])
                new[: old.shape[0]] = old
                setattr(self, name, new)
        return knot - self.base

    def add_rows(self, D, C, w, t, Hr, cols) -> None:
        """Add one block from the model's attitude partials ``D`` (N, m, 3), the attitude
        ``C`` (N, 3, 3), row weights ``w`` (N, m) and ``Hr`` (N·m, k + 1): the weighted
        static rows over ``cols`` (k,), the weighted residual last."""
        m = D.shape[1]
        if not COMPILED:
            j = self.grid.index(t)
            U = knot_rows(np.nan_to_num(D), C, t, j, self.grid, self.R, w)
            Hr = Hr.reshape(D.shape[0], m, -1)
            self.add(U, Hr[:, :, :-1], Hr[:, :, -1], t, cols)
            return
        knot = self._local(self.grid.index(t).astype(np.int64))
        R = self.R if self.R.shape[0] else np.eye(3)[None]
        # the fused kernel reads the knot times through the held buffer's offset
        _accumulate_fused(
            D,  # read through nan_to_num in the kernel
            C,
            w,
            t,
            knot,
            self.grid.tau[self.base :],
            R[self.base :] if self.base < R.shape[0] else R[-1:],
            np.ascontiguousarray(Hr),
            m,
            np.asarray(cols, np.int64),
            self.Dk,
            self.Bk,
        )

    def add(self, U, H, rw, t, cols) -> None:
        """Add one block's weighted rows: U (N, m, d), H (N, m, k) over static ``cols``,
        rw (N, m) the weighted residuals; t (N,) frame times."""
        knot = self._local(self.grid.index(t).astype(np.int64))
        args = (
            np.ascontiguousarray(U),
            np.ascontiguousarray(H),
            np.ascontiguousarray(rw),
            knot,
            np.asarray(cols, np.int64),
            self.Dk,
            self.Bk,
        )
        (_accumulate if COMPILED else _accumulate_numpy)(*args)

    def track(self, sensors) -> None:
        """Follow the data of ``sensors`` (their frame times) for :meth:`passed`."""
        self._last = {sd.name: (-np.inf if sd.n else np.inf) for sd in sensors}

    def passed(self, sd, hi: int) -> None:
        """Sensor ``sd`` has delivered its frames up to ``hi``; eliminate (when streaming)
        the knots no frame still to come can reach (every later frame of a sensor is past
        its last delivered one)."""
        self._last[sd.name] = np.inf if hi >= sd.n else float(sd.t[hi - 1])
        if self.stream:
            self.flush(min(self._last.values()))

    # ----------------------------------------------------------------- elimination
    def prior_cost(self) -> float:
        """``Σ e_jᵀ Q_j⁻¹ e_j``, ``e_j = z_{j+1} − Φ_j z_j``."""
        return self._prior

    def increments(self) -> np.ndarray:
        z = self.z
        return z[1:] - np.einsum("nab,nb->na", self.Phi, z[:-1])

    def flush(self, t_done: float) -> None:
        """Eliminate the held knots that no later frame can reach (``τ_{j+1} ≤ t_done``)."""
        K = self.grid.K
        if t_done == -np.inf:
            return
        j1 = K if t_done == np.inf else int(np.searchsorted(self.grid.tau, t_done, side="right")) - 1
        j1 = min(max(j1, self.base), K)
        if j1 <= self.base:
            return
        n = j1 - self.base
        self._local(np.array([j1 - 1]))  # knots without data are held too
        j = np.arange(self.base, j1)
        Baug = self.Bk[:n].copy()
        gz = Baug[:, :, -1]
        lo = j >= 1
        gz[lo] -= self._We[j[lo] - 1]  # −∂/∂z_{j} of ½ e_{j−1}ᵀ W e_{j−1}
        hi = j <= K - 2
        gz[hi] += np.einsum("nba,nb->na", self.Phi[j[hi]], self._We[j[hi]])
        Sc, Bc, Oc = self._carry
        _forward_range(
            self.Dk[:n],
            Baug,
            self.Phi,
            self.W,
            self.Msub,
            self.base,
            K,
            Sc,
            Bc,
            Oc,
            self._fac[0],
            self._fac[1],
            self._fac[2],
            self.keep,
        )
        # the held buffer moves past the eliminated knots
        rest = self.Dk.shape[0] - n
        self.Dk[:rest] = self.Dk[n:].copy()
        self.Dk[rest:] = 0.0
        self.Bk[:rest] = self.Bk[n:].copy()
        self.Bk[rest:] = 0.0
        self.base = j1

    def eliminate(self, N: np.ndarray, g: np.ndarray):
        """Reduce ``[N | g]`` (p × p and p, the static block with its prior) by the knots.

        Returns (N_red, g_red, factors); ``factors`` (with ``keep``) feed
        :meth:`back_substitute` and :meth:`covariance`. May be called again (with other
        static blocks) once the knots are eliminated.
        """
        if self.base < self.grid.K:
            self.flush(np.inf)
        p = self.p
        self.knot_gain = float(self.Msub[p, p])  # Σ ĝ_jᵀ S_j⁻¹ ĝ_j: the knots' part of gᵀN⁻¹g
        N_red = N - self.Msub[:p, :p]
        N_red = 0.5 * (N_red + N_red.T)
        return N_red, g - self.Msub[:p, p], (self._fac if self.keep else None)

    @staticmethod
    def back_substitute(factors, dx: np.ndarray) -> np.ndarray:
        """(K, d) knot steps given the static step (``δz_0 = 0``)."""
        Sinv, Bh, O = (np.ascontiguousarray(a) for a in factors)
        return _backward(Sinv, Bh, O, np.ascontiguousarray(dx))

    @staticmethod
    def covariance(factors, P: np.ndarray):
        """Marginal covariance of each knot (K, d, d) and with the statics (K, d, p)."""
        Sinv, Bh, O = (np.ascontiguousarray(a) for a in factors)
        return _cov_backward(Sinv, Bh, O, np.ascontiguousarray(P))


@_jit
def _forward_range(Dk, Baug, Phi, W, Msub, j0, K, Sc, Bc, Oc, Sinv, Bh, O, keep):
    """Forward block elimination of knots ``j0 … j0 + n − 1`` (held in ``Dk``, ``Baug``
    from row 0), continuing from the carry ``(S⁻¹, B̂, O)`` of knot ``j0 − 1`` (updated in
    place); knot 0 is fixed (z_0 = 0) and skipped. ``Msub += B̂ᵀ S⁻¹ B̂`` per knot.

    Knot j's diagonal is ``Dk_j + W_{j−1} + Φ_jᵀ W_j Φ_j``, its coupling to j+1 is
    ``O_j = −Φ_jᵀ W_j``. With ``keep`` S_j⁻¹, B̂_j, O_j go to row j of ``Sinv``, ``Bh``, ``O``.
    """
    for r in range(Dk.shape[0]):
        j = j0 + r
        if j == 0:
            continue
        S = Dk[r] + W[j - 1]
        B = Baug[r].copy()
        Oj = np.zeros_like(S)
        if j < K - 1:
            PtW = np.ascontiguousarray(Phi[j].T) @ W[j]
            S = S + PtW @ Phi[j]
            Oj = -PtW
        if j > 1:
            T = Sc @ Oc  # coupling (j−1, j)
            S = S - np.ascontiguousarray(Oc.T) @ T
            B = B - np.ascontiguousarray(T.T) @ Bc
        S = 0.5 * (S + S.T)
        Si = _sym_inv(S)
        Msub += np.ascontiguousarray(B.T) @ (Si @ B)
        Sc[:, :] = Si
        Bc[:, :] = B
        Oc[:, :] = Oj
        if keep:
            Sinv[j] = Si
            Bh[j] = B
            O[j] = Oj


@_jit
def _sym_inv(S):
    """Inverse of a small symmetric positive definite matrix (equilibrated Cholesky)."""
    n = S.shape[0]
    dg = np.sqrt(np.abs(np.diag(S.copy())))
    for i in range(n):
        if dg[i] == 0.0:
            dg[i] = 1.0
    Ss = S / np.outer(dg, dg)
    L = np.linalg.cholesky(Ss)
    Li = np.linalg.inv(L)
    inv = Li.T @ Li
    return inv / np.outer(dg, dg)


@_jit
def _backward(Sinv, Bh, O, dx):
    K, d = Sinv.shape[0], Sinv.shape[1]
    p = dx.shape[0]
    dz = np.zeros((K, d))
    for j in range(K - 1, 0, -1):
        rhs = Bh[j][:, p] - np.ascontiguousarray(Bh[j][:, :p]) @ dx
        if j < K - 1:
            rhs = rhs - O[j] @ dz[j + 1]
        dz[j] = Sinv[j] @ rhs
    return dz


@_jit
def _cov_backward(Sinv, Bh, O, P):
    """``z_j = −S_j⁻¹ (O_j z_{j+1} + B̂_j x) + e_j``, ``e_j ~ N(0, S_j⁻¹)`` independent of
    ``(z_{j+1}, x)``: Σ_j = S_j⁻¹ + L Cov(f) Lᵀ, Cov(z_j, x) = (L Cov(f))_x."""
    K, d = Sinv.shape[0], Sinv.shape[1]
    p = P.shape[0]
    Sig = np.zeros((K, d, d))
    X = np.zeros((K, d, p))
    for j in range(K - 1, 0, -1):
        Bx = np.ascontiguousarray(Bh[j][:, :p])
        if j < K - 1:
            # L Cov(f) with f = (z_{j+1}, x), L = −S⁻¹ [O_j, B̂_j]
            LC_z = -(Sinv[j] @ (O[j] @ Sig[j + 1] + Bx @ X[j + 1].T))
            LC_x = -(Sinv[j] @ (O[j] @ X[j + 1] + Bx @ P))
            Sig[j] = Sinv[j] - LC_z @ (Sinv[j] @ O[j]).T - LC_x @ (Sinv[j] @ Bx).T
        else:
            LC_x = -(Sinv[j] @ (Bx @ P))
            Sig[j] = Sinv[j] - LC_x @ (Sinv[j] @ Bx).T
        Sig[j] = 0.5 * (Sig[j] + Sig[j].T)
        X[j] = LC_x
    return Sig, X
