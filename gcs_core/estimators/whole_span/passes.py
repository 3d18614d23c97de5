"""The whole-span fit's moving parts (module docstring of :mod:`gcs_core.estimators.whole_span.fit`):
the knot corrections as an attitude provider (:class:`CorrectedAttitude`), their state
(:class:`Dynamics`), the drift-bias axes at the knots (:func:`mid_rotations`) and one
Gauss–Newton pass over the data (:class:`Passes`: linearize, accumulate per knot, eliminate)."""

from __future__ import annotations

import logging
from dataclasses import dataclass, field, replace

import numpy as np

from gcs_core.compiled import COMPILED
from gcs_core.estimators.residuals import Residuals
from gcs_core.estimators.whole_span import knots as kn
from gcs_core.estimators.whole_span.epoch_errors import EpochErrors
from gcs_core.estimators.whole_span.knot_kernels import correct_attitude, rotate_by_rotvec
from gcs_core.estimators.whole_span.readout import ReadoutEpochs, row_readout
from gcs_core.frames.rotations import rotvec_to_dcm
from gcs_core.problem.attitude import AttitudeEval, FrameAttitude
from gcs_core.problem.build import Problem
from gcs_core.problem.gyro_attitude import GyroAttitude
from gcs_core.problem.linearization import iter_blocks

log = logging.getLogger(__name__)

#: a Gauss–Newton step that would lower the cost by less than this is negligible
GAIN_TOL = 1e-3
#: ... and, when no shortened step lowers the cost, a predicted gain below this fraction
#: of the cost (the first-order knot partials' accuracy where the corrections are large)
NOISE_GAIN = 1e-6


@dataclass
class Dynamics:
    """The knot corrections of a whole-span fit and what their covariance needs.

    grid : the knots; z : (K, d) corrections; R : (K−1, 3, 3) mid-interval rotations;
    names : the static columns of ``factors`` and ``P``; factors : the elimination at the
    solution (:meth:`KnotSystem.eliminate`); P : covariance of the statics; sig_e2 : the
    gyro's read-out noise σ_e² [rad²] the fit carried and errors its per-epoch estimates
    ε̂ at the solution (:mod:`gcs_core.estimators.whole_span.readout`).
    """

    grid: kn.KnotGrid
    z: np.ndarray
    R: np.ndarray
    names: tuple = ()
    factors: tuple | None = None
    P: np.ndarray | None = None
    sig_e2: float = 0.0
    errors: EpochErrors | None = None
    _cov: tuple | None = field(default=None, repr=False)

    def attitude(self, base, *, readout: bool = False) -> CorrectedAttitude:
        return CorrectedAttitude(base, self.grid, self.z, self.R, self.errors if readout else None)

    def problem(self, problem: Problem, *, readout: bool = False) -> Problem:
        """The problem with its attitude corrected by the knots (caches shared); with
        ``readout`` also by the per-epoch read-out errors ε̂ (the fit's linearization)."""
        base = problem.attitude.base if isinstance(problem.attitude, CorrectedAttitude) else problem.attitude
        out = replace(problem, attitude=self.attitude(base, readout=readout))
        out.__dict__["_variant_cache"] = problem.__dict__.setdefault("_variant_cache", {})
        return out

    def covariance(self):
        """(Σ_j (K, d, d), Cov(z_j, x) (K, d, n)) at the solution (computed once)."""
        if self._cov is None and self.factors is not None:
            assert self.P is not None  # set with the factors
            self._cov = kn.KnotSystem.covariance(self.factors, self.P)
        return self._cov

    def knot_partials(self, blk) -> tuple[np.ndarray, np.ndarray] | None:
        """``(U, j)`` of a weighted block (:func:`~gcs_core.problem.linearization.iter_blocks`
        on :meth:`problem`): its rows' partials in their frames' knot columns ``U`` (n, m, d),
        weighted and zero where unused as the fit forms them (:func:`.knots.knot_rows`), and
        each frame's knot ``j`` (n,); None for rows without attitude partials."""
        D = getattr(blk.pred, "d_att", None)
        if D is None or blk.geom.C_BI is None:
            return None
        sd = blk.sensor
        t = sd.t[blk.lo : blk.hi]
        j = self.grid.index(t)
        C = kn.chained_attitude(blk.geom.C_BI, self.grid, self.z, self.R, t)
        w = blk.used[:, None] / sd.sigma[None, :]
        return kn.knot_rows(np.nan_to_num(D), C, t, j, self.grid, self.R, w), j

    def knot_sigma(self) -> np.ndarray:
        """(K, d) 1-sigma of the corrections."""
        S = self.covariance()[0]
        return np.sqrt(np.clip(np.einsum("kaa->ka", S), 0, None))


class CorrectedAttitude:
    """The gyro-carried attitude with the knot corrections applied exactly:
    ``C(t) = exp(−[δθ×]) C_gyro(t)``, ``δθ = C_gyro α(t)`` (:mod:`gcs_core.estimators.whole_span.knots`).
    Partials stay factored as the base provider's (chained through the corrected C)."""

    def __init__(self, base, grid: kn.KnotGrid, z: np.ndarray, R: np.ndarray, errors: EpochErrors | None = None):
        self.base, self.grid, self.z, self.R = base, grid, z, R
        self.errors = errors  # per-epoch read-out errors ε̂: C ← exp(−[ε̂×]) C (readout.py)

    def __getattr__(self, name):
        return getattr(self.base, name)

    @property
    def names(self):
        return self.base.names

    def _correct(self, C, t):
        C = self._correct_knots(C, t)
        if self.errors is not None and self.errors.nonzero:
            if COMPILED:
                out = np.empty_like(C)
                rotate_by_rotvec(self.errors.at(t), np.ascontiguousarray(C), out)
                return out
            C = rotvec_to_dcm(self.errors.at(t)) @ C
        return C

    def _rate(self, w, t):
        """The body rate of the corrected attitude: the gyro's rate over the interval
        ``(τ_{k−1}, τ_k]`` holding ``t`` plus ``(ε̂(τ_k) − ε̂(τ_{k−1}))/(τ_k − τ_{k−1})``
        (``C = exp(−[ε̂×]) C_gyro`` ⇒ ``ω = ω_gyro + ε̂̇``; ε̂ = 0 where no datum is). The
        gyro's rate carries ``(e_k − e_{k−1})/Δ``: a time-tag offset's partials
        ``−ω × v`` made from it would be a regressor with errors, correlated with the
        residuals; corrected, its error is the posterior one, uncorrelated with them."""
        er, base = self.errors, self.base
        if er is None or w is None or not er.nonzero or not hasattr(base, "knots"):
            return w
        k = base._rows(t)
        t1, t0 = base.knots[k], base.knots[k - 1]
        return w + (er.at(t1, t, "interval end") - er.at(t0, t, "interval start")) / (t1 - t0)[:, None]

    def _correct_knots(self, C, t):
        if not np.any(self.z):
            return C
        if COMPILED:
            out = np.empty_like(C)
            correct_attitude(
                np.ascontiguousarray(C),
                t,
                self.grid.index(t).astype(np.int64),
                self.grid.tau,
                self.z,
                self.R if self.R.shape[0] else np.eye(3)[None],
                out,
            )
            return out
        a = kn.alpha_at(self.grid, self.z, self.R, t)
        return rotvec_to_dcm(np.einsum("nab,nb->na", C, a)) @ C

    def frames(self, values, t, *, partials: bool = True) -> FrameAttitude:
        t = np.atleast_1d(np.asarray(t, float))
        fr = self.base.frames(values, t, partials=partials)
        # the statics' partials stay the gyro-carried attitude's (C_chain, exact: a body-frame
        # perturbation ε of C_gyro moves C = C_gyro exp(−[α×]) by the same ε)
        return FrameAttitude(
            self._correct(fr.C_BI, t),
            None,
            self._rate(fr.omega_B, t),
            fr.names,
            J=fr._J,
            gyro=fr._gyro,
            C_chain=fr.C_chain,
        )

    def evaluate(self, values, t) -> AttitudeEval:
        t = np.atleast_1d(np.asarray(t, float))
        ev = self.base.evaluate(values, t)
        return AttitudeEval(self._correct(ev.C_BI, t), None, ev.names, ev.J, omega_B=self._rate(ev.omega_B, t))


def mid_rotations(att: GyroAttitude, values, t: np.ndarray) -> np.ndarray:
    """``C_gyro(t)ᵀ`` (N, 3, 3) at times ``t``, block by block of the propagation."""
    out = np.empty((t.size, 3, 3))
    if not t.size:
        return out
    b = (att._rows(t) - 1) // att.block_knots
    for bb in np.unique(b):
        sel = np.flatnonzero(b == bb)
        out[sel] = np.swapaxes(att.frames(values, t[sel], partials=False).C_BI, 1, 2)
    return out


@dataclass
class SpanLinearization:
    """One pass of the whole-span problem linearized at (x, z) (:meth:`Passes.run`).

    A : (n, n) the statics' data information ``Hᵀ R⁻¹ H``; b : (n,) ``Hᵀ R⁻¹ r``;
    chi2 : the data χ² (generalized with the read-out noise, :mod:`.readout`); m_used :
    measurement components used; system : the knot rows accumulated, ready to be
    eliminated (:class:`.knots.KnotSystem`); R : (K−1, 3, 3) the knots' drift-bias axes.
    """

    A: np.ndarray
    b: np.ndarray
    chi2: float
    m_used: int
    system: kn.KnotSystem
    R: np.ndarray


class Passes:
    """Linearization passes of the whole-span problem at (x, z)."""

    def __init__(self, problem: Problem, names, grid: kn.KnotGrid, x_bar, prior_info, sig_e2: float = 0.0):
        self.problem, self.names, self.grid = problem, tuple(names), grid
        # the gyro's read-out noise, eliminated per epoch (readout.py); 0: the rows independent
        self.sig_e2 = float(sig_e2)
        # sensor -> (N, m) σ_e² |D_i|², each row's read-out variance at the last pass
        self.readout_var: dict[str, np.ndarray] = {}
        # the per-epoch read-out errors the passes linearize about (readout.py)
        self.errors = EpochErrors(problem.sensors) if self.sig_e2 else None
        self.base = problem.gyro_attitude  # the whole-span problem is gyro-carried
        self.x_bar, self.prior_info = x_bar, prior_info
        self.values = problem.state.values()
        self.work: dict = {}
        self.readout_work: dict = {}  # the read-out elimination's window buffers (readout.py)
        self.buffers = Residuals().ensure(problem)
        self.stream, self.keep = True, True  # knots eliminated as the data pass them
        # the knots' drift-bias axes R_j (knots.py), taken from the trajectory where the fit
        # starts and then held: the cost is a function of (x, z) alone, and the Jacobian
        # (which has no ∂R/∂x) is its exact one. Re-taken at every x, R moved with steps of
        # the statics of degrees (a week's wander) and the steps stopped lowering the cost.
        self.R_fixed: np.ndarray | None = None

    def set_x(self, x, names=None):
        for j, nm in enumerate(self.names if names is None else names):
            self.values[nm] = x[j]

    def run(self, x, z, edits, *, columns=None, jacobian=True) -> SpanLinearization:
        """One pass at (x, z) (:class:`SpanLinearization`); the residual buffers are filled."""
        cols = tuple(columns or self.names)
        self.set_x(x)
        if self.R_fixed is None:
            self.R_fixed = mid_rotations(self.base, self.values, self.grid.mid_times())
        R = self.R_fixed
        sysk = kn.KnotSystem(self.grid, len(cols) if jacobian else 0, R, z, stream=self.stream, keep=self.keep)
        sysk.track(self.problem.sensors)
        prob = replace(self.problem, attitude=CorrectedAttitude(self.base, self.grid, z, R, self.errors))
        n = len(cols) if jacobian else 0
        A, b = np.zeros((n, n)), np.zeros(n)
        chi2, m_used = 0.0, 0
        ro = (
            ReadoutEpochs(
                self.sig_e2,
                A,
                b,
                sysk if jacobian else None,
                self.problem.sensors,
                self.errors,
                self.readout_work,
                record=jacobian,
            )
            if self.sig_e2
            else None
        )
        passed = sysk.passed if ro is None else ro.passed
        for blk in iter_blocks(
            prob,
            self.values,
            cols if jacobian else (),
            exclude=edits,
            weighted=True,
            jacobian=jacobian,
            work=self.work,
            augmented=True,
        ):
            if blk.name in self.buffers.y_pred:
                self.buffers.y_pred[blk.name][blk.lo : blk.hi] = blk.y_pred
            self.buffers.r[blk.name][blk.lo : blk.hi] = blk.r
            self.buffers.valid[blk.name][blk.lo : blk.hi] = blk.valid
            if ro is not None:
                ro.visit(blk.sensor)
                self._readout_rows(blk)
            nu = int(np.count_nonzero(blk.used))
            if not nu:
                passed(blk.sensor, blk.hi)
                continue
            m_used += nu * blk.r.shape[1]
            sd = blk.sensor
            c = blk.cols
            if jacobian and blk.Hr is not None:
                # [H r]ᵀ [H r]: Hᵀ R⁻¹ H, Hᵀ R⁻¹ r and χ² in one product
                G = blk.Hr.T @ blk.Hr
                k = c.size
                chi2 += float(G[k, k])
                A[np.ix_(c, c)] += G[:k, :k]
                b[c] += G[:k, k]
                rw = None
            else:
                rw = np.where(blk.used[:, None], blk.r, 0.0) / sd.sigma
                chi2 += float(np.sum(rw * rw))
            if not jacobian:
                if ro is not None:
                    self._readout_add(ro, blk, None, rw)
                continue
            C = self._knot_rows(blk, sysk, rw, R)
            if ro is not None:
                self._readout_add(ro, blk, C, rw)
            passed(sd, blk.hi)
        if ro is not None:
            chi2 -= ro.finish()
        return SpanLinearization(A, b, chi2, m_used, sysk, R)

    def _knot_rows(self, blk, sysk, rw, R) -> np.ndarray | None:
        """The block's rows in the knot columns, added to the knot system; returns the
        attitude they chain through (None for rows without attitude partials)."""
        sd = blk.sensor
        D = getattr(blk.pred, "d_att", None)
        if D is None or blk.geom.C_BI is None:
            return None
        t = sd.t[blk.lo : blk.hi]
        w = blk.used[:, None] / sd.sigma[None, :]
        C = np.ascontiguousarray(kn.chained_attitude(blk.geom.C_BI, self.grid, sysk.z, R, t))
        if blk.Hr is not None:
            sysk.add_rows(D, C, w, t, blk.Hr, blk.cols)
        else:
            sysk.add_rows(D, C, w, t, rw.reshape(-1, 1), np.zeros(0, np.int64))
        return C

    def _readout_rows(self, blk) -> None:
        """Each row's read-out variance σ_e² |D_i|² (for the normalized residuals), and the
        residual buffer at ε = 0: ``r + D ε̂`` (to first order in ε̂, ~1e-4 rad), the
        marginal residual whose variance is ``σ² + σ_e² |D|² − (prediction variance)``."""
        sd = blk.sensor
        buf = self.readout_var.get(sd.name)
        if buf is None or buf.shape[0] != sd.n:
            buf = self.readout_var[sd.name] = np.zeros((sd.n, len(sd.sigma)))
        D = getattr(blk.pred, "d_att", None)
        if D is None or blk.geom.C_BI is None:
            buf[blk.lo : blk.hi] = 0.0
            return
        eps = self.errors.at(sd.t[blk.lo : blk.hi]) if self.errors is not None and self.errors.nonzero else None
        buf[blk.lo : blk.hi], De = row_readout(D, self.sig_e2, eps)
        if De is not None:
            self.buffers.r[sd.name][blk.lo : blk.hi] += De
            if sd.name in self.buffers.y_pred:  # the prediction at ε = 0 likewise
                self.buffers.y_pred[sd.name][blk.lo : blk.hi] -= De

    def _readout_add(self, ro: ReadoutEpochs, blk, C, rw) -> None:
        """The block's rows in the per-epoch elimination of the read-out error."""
        sd = blk.sensor
        D = getattr(blk.pred, "d_att", None)
        if D is None or blk.geom.C_BI is None:
            return
        t = sd.t[blk.lo : blk.hi]
        w = blk.used[:, None] / sd.sigma[None, :]
        if blk.Hr is not None and ro.p:
            ro.add(t, D, w, C, blk.Hr, blk.cols)
        else:
            rwf = blk.Hr[:, -1:] if blk.Hr is not None else rw.reshape(-1, 1)
            ro.add(t, D, w, C, rwf, np.zeros(0, np.int64))

    def marginal_sigma(self) -> dict[str, np.ndarray]:
        """sensor -> (N, m) each row's marginal σ at the last pass, ``sqrt(σ² + σ_e² |D|²)``
        ({} without read-out noise: the data-book σ)."""
        return {
            sd.name: np.sqrt(sd.sigma[None, :] ** 2 + v)
            for sd in self.problem.sensors
            if (v := self.readout_var.get(sd.name)) is not None
        }

    def cost(self, x, chi2, sysk) -> float:
        d = self.x_bar - x
        return chi2 + float(np.sum(self.prior_info * d * d)) + sysk.prior_cost()
