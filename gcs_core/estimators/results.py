"""What every estimator gives back (seed §3.2): per-sensor post-fit residuals and one fit
result shape, :class:`FitResult`, that the batch (Eq 3-1, 3-2), the whole-span fit and the
Kalman filter + smoother (Eq 3-3, 3-4) all satisfy, so that the diagnosis, the reports and
the screens read any of them; plus the stepping filter's per-block and per-frame reports.
"""

from __future__ import annotations

from collections.abc import Mapping
from dataclasses import dataclass, field
from functools import cached_property
from typing import Any, Protocol

import numpy as np
from scipy import special

from gcs_core.estimators import static_algebra
from gcs_core.estimators.static_algebra import Elimination, HoldoutChi2, Influence, NoElimination
from gcs_core.frames.rotations import quat_to_dcm
from gcs_core.problem.attitude import AttitudeProvider
from gcs_core.problem.build import Problem
from gcs_core.problem.state import StateVector


class FitResult(Protocol):
    """The result of any fit, as the diagnosis, the reports and the screens read it.

    Attributes
    ----------
    state : the state with the estimated values; solve_for, consider : element names.
    x : (n,) solve-for estimates; P : (n, n) their covariance (noise only);
    P_consider : (n, n) covariance with the consider elements' contribution.
    sigma : name -> 1-σ (from ``P_consider``).
    residuals : sensor -> :class:`SensorResiduals`.
    chi2, dof : data χ² over used components and its degrees of freedom (components − n).
    status, message : the outcome (``"converged"``, ...) and a sentence about it.
    information : (n, n) data-only information ``Hᵀ R⁻¹ H``, or None where the estimator
        forms none (the filter: its covariance mixes the process noise in).
    unobservable : combinations the data cannot separate (text).
    consider_budget : consider element -> (n,) its σ contribution to each solve-for element.
    """

    @property
    def state(self) -> StateVector: ...

    @property
    def solve_for(self) -> tuple[str, ...]: ...

    @property
    def consider(self) -> tuple[str, ...]: ...

    @property
    def x(self) -> np.ndarray: ...

    @property
    def P(self) -> np.ndarray: ...

    @property
    def residuals(self) -> dict[str, SensorResiduals]: ...

    @property
    def status(self) -> str: ...

    @property
    def message(self) -> str: ...

    @property
    def unobservable(self) -> tuple[str, ...]: ...

    @property
    def P_consider(self) -> np.ndarray: ...

    @property
    def sigma(self) -> dict[str, float]: ...

    @property
    def chi2(self) -> float: ...

    @property
    def dof(self) -> int: ...

    @property
    def information(self) -> np.ndarray | None: ...

    @property
    def consider_budget(self) -> Mapping[str, np.ndarray]: ...

    # ---- the result's own algebra: what the diagnosis, VERIF and the reports ask of a fit
    @property
    def dynamics(self) -> Any:
        """The estimator's own dynamic corrections (a whole-span fit's knots, read by that
        estimator when it starts from this result), or None."""
        ...

    @property
    def carries_process_noise(self) -> bool:
        """True when the fit estimated the gyro's wander (its σ of gyro elements count it)."""
        ...

    @property
    def scores_own_residuals(self) -> bool:
        """True when the score tests read the result's own residuals (a smoother's, at the
        smoothed attitude) rather than the deterministic linearization's."""
        ...

    def warm_start(self) -> dict:
        """Keyword arguments that start a refit of the same data at this solution."""
        ...

    def attitude_provider(self, provider: AttitudeProvider) -> AttitudeProvider:
        """The fitted attitude, from the problem's attitude provider."""
        ...

    def attitude_wander_covariance(self, C: np.ndarray, t: np.ndarray, J: np.ndarray) -> np.ndarray:
        """(N, 3, 3) attitude error covariance at ``t`` beyond that of the static elements."""
        ...

    def holdout_rms(self, problem: Problem, masks: Mapping[str, np.ndarray]) -> dict[str, float]:
        """Sensor -> normalized RMS of the held-out frames ``masks``, each residual over its
        prediction's σ (noise and the fit's uncertainty carried there)."""
        ...

    def holdout_chi2(self, problem: Problem, sel: Mapping[str, np.ndarray]) -> HoldoutChi2 | None:
        """χ² sums of the held-out frames ``sel`` under this (training) fit."""
        ...

    def influence(self, problem: Problem) -> Influence:
        """Each sensor's share of the fit's effective parameters (goodness of fit)."""
        ...

    def candidate_elimination(self, problem: Problem, K: int, A: np.ndarray, g: np.ndarray) -> Elimination:
        """What the score tests of candidate columns must eliminate besides the state
        (normal equations ``A``, ``g`` over ``K`` columns, accumulated by the caller)."""
        ...


class StaticAlgebra:
    """The result protocol's algebra for a fit whose state is static between its parameters
    (:mod:`gcs_core.estimators.static_algebra`); the batch's and the filter's results."""

    #: the fitted state (a field of each result that mixes this in)
    state: StateVector

    @property
    def carries_process_noise(self) -> bool:
        return False

    @property
    def dynamics(self) -> Any:
        """A static fit has no dynamic corrections (a whole-span fit's knots)."""
        return None

    @property
    def scores_own_residuals(self) -> bool:
        return False

    def warm_start(self) -> dict:
        return {"initial": self.state.values()}

    def attitude_provider(self, provider: AttitudeProvider) -> AttitudeProvider:
        return provider

    def attitude_wander_covariance(self, C: np.ndarray, t: np.ndarray, J: np.ndarray) -> np.ndarray:
        return np.zeros((np.size(t), 3, 3))

    def holdout_rms(self, problem: Problem, masks: Mapping[str, np.ndarray]) -> dict[str, float]:
        return static_algebra.holdout_rms(problem, self, masks)

    def holdout_chi2(self, problem: Problem, sel: Mapping[str, np.ndarray]) -> HoldoutChi2 | None:
        return static_algebra.holdout_chi2(problem, self, sel)

    def influence(self, problem: Problem) -> Influence:
        return static_algebra.leverage(problem, self)

    def candidate_elimination(self, problem: Problem, K: int, A: np.ndarray, g: np.ndarray) -> Elimination:
        return NoElimination(problem)


@dataclass(frozen=True)
class SmoothedTrajectory:
    """Smoothed attitude (and gyro biases) at every epoch of the filter.

    Attributes
    ----------
    t : (N,) epoch times [s] (frame times, block boundaries; a boundary appears twice).
    q_BI : (N, 4) GCI-to-body quaternion, scalar last (ICD §2).
    sigma_att : (N, 3) 1-sigma of the attitude error about the body axes [rad].
    bias : (N, nb) smoothed random-walking gyro biases [rad/s], or None.
    sigma_bias : (N, nb) their 1-sigma, or None.
    bias_names : element names of the biases.
    """

    t: np.ndarray
    q_BI: np.ndarray
    sigma_att: np.ndarray
    bias: np.ndarray | None = None
    sigma_bias: np.ndarray | None = None
    bias_names: tuple[str, ...] = ()

    def C_BI(self, k) -> np.ndarray:
        """Attitude matrices at epochs ``k`` (index or array)."""
        return quat_to_dcm(self.q_BI[k])


@dataclass(frozen=True)
class SensorResiduals:
    """Post-fit residuals of one sensor.

    Attributes
    ----------
    t : (N,) frame times; y, y_pred, residual, normalized : (N, m).
    used : (N,) frames used in the fit (valid and not edited).
    valid : (N,) frames where the model is defined.
    edited : (N,) frames flagged by k-σ editing.
    rms : (m,) RMS of used residuals per component; rms_normalized : scalar, 1.0 = noise.

    ``normalized`` (``residual / sigma``) and, for a model whose residual is the plain
    difference, ``y_pred`` (``y − residual``, to round-off) may be passed as None: they
    are then formed when read rather than stored (two (N, m) arrays less on long spans).
    """

    name: str
    components: tuple[str, ...]
    unit: str
    t: np.ndarray
    y: np.ndarray
    y_pred_: np.ndarray | None = field(repr=False)
    residual: np.ndarray
    normalized_: np.ndarray | None = field(repr=False)
    sigma: np.ndarray
    used: np.ndarray
    valid: np.ndarray
    edited: np.ndarray

    @classmethod
    def of(cls, sd, y_pred, residual, valid, edited, *, sigma=None, normalized: bool = True) -> SensorResiduals:
        """Residuals of a prepared sensor ``sd`` (its name, components, unit, times, data and
        σ unless ``sigma`` is given): ``residual`` (NaN already where not ``valid``), the
        ``edited`` frames counted only where valid; ``normalized`` stores ``residual / σ``
        (else it is formed when read)."""
        sigma = sd.sigma if sigma is None else sigma
        ed = (np.zeros(valid.shape, bool) if edited is None else np.asarray(edited, bool)) & valid
        return cls(
            sd.name,
            tuple(sd.model.components),
            sd.model.unit,
            sd.t,
            sd.y,
            y_pred,
            residual,
            residual / sigma if normalized else None,
            sigma,
            valid & ~ed,
            valid,
            ed,
        )

    @property
    def y_pred(self) -> np.ndarray:
        return self.y - self.residual if self.y_pred_ is None else self.y_pred_

    @property
    def normalized(self) -> np.ndarray:
        return self.residual / self.sigma if self.normalized_ is None else self.normalized_

    @property
    def n(self) -> int:
        return int(np.count_nonzero(self.used))

    @property
    def rms(self) -> np.ndarray:
        r = self.residual[self.used]
        return np.sqrt(np.mean(r**2, axis=0)) if r.size else np.full(self.residual.shape[1], np.nan)

    @property
    def rms_normalized(self) -> float:
        r = self.normalized[self.used]
        return float(np.sqrt(np.mean(r**2))) if r.size else float("nan")

    @property
    def chi2(self) -> float:
        return float(np.sum(self.normalized[self.used] ** 2))


@dataclass(frozen=True)
class BatchResult(StaticAlgebra):
    """Outcome of a batch fit, with its diagnostics.

    Attributes
    ----------
    state : the state with solve-for values updated.
    solve_for, consider : element names.
    x : (n,) solve-for estimates; P : (n, n) their covariance (noise only);
    P_consider : (n, n) covariance including consider elements.
    sigma : dict name -> 1-sigma (with consider contributions).
    residuals : sensor -> :class:`SensorResiduals`.
    chi2, dof : data chi-square and degrees of freedom (used components − n).
    cost_history : cost per iteration; iterations; status; message.
    information : (n, n) data-only information Hᵀ R⁻¹ H.
    unobservable : human-readable combinations the data cannot separate.
    """

    state: StateVector
    solve_for: tuple[str, ...]
    consider: tuple[str, ...]
    x: np.ndarray
    P: np.ndarray
    P_consider: np.ndarray
    residuals: dict[str, SensorResiduals]
    chi2: float
    dof: int
    cost_history: tuple[float, ...]
    iterations: int
    status: str
    message: str
    information: np.ndarray
    unobservable: tuple[str, ...] = ()
    consider_budget: Mapping[str, np.ndarray] = field(default_factory=dict)

    @property
    def sigma(self) -> dict[str, float]:
        return {n: float(np.sqrt(self.P_consider[i, i])) for i, n in enumerate(self.solve_for)}

    @property
    def values(self) -> dict[str, float]:
        return self.state.values()

    def correlation(self) -> np.ndarray:
        d = np.sqrt(np.diag(self.P))
        return self.P / np.outer(d, d)


@dataclass(frozen=True)
class FrameDiagnostics:
    """Per-frame filter diagnostics of one sensor (m measurement components).

    Attributes
    ----------
    name : sensor; t : (N,) frame times; index : (N,) frame numbers in the sensor's data.
    innovation : (N, m) ``ν = y − h(x⁻)``, telemetry units (NaN where not processed).
    S : (N, m, m) innovation covariance ``H P⁻ Hᵀ + R``.
    nis : (N,) ``νᵀ S⁻¹ ν``; k_norm : (N,) Frobenius norm of the gain K (mixed units).
    gated : (N,) refused by the k-σ gate (flagged and skipped, never dropped silently).
    used : (N,) updated the state; valid : (N,) the model is defined there.
    """

    name: str
    t: np.ndarray
    index: np.ndarray
    innovation: np.ndarray
    S: np.ndarray
    nis: np.ndarray
    k_norm: np.ndarray
    gated: np.ndarray
    used: np.ndarray
    valid: np.ndarray


@dataclass(frozen=True)
class InnovationStats:
    """Innovation statistics of one sensor over one block.

    Attributes
    ----------
    n_frames, n_valid, n_used, n_gated : frame counts.
    nis : Σ NIS over used frames; dof : Σ m over used frames; p_value : ``P(χ²_dof ≥ nis)``.
    rms_normalized : RMS of ``ν_i / sqrt(S_ii)`` over used frames (1.0 when consistent).
    """

    name: str
    n_frames: int
    n_valid: int
    n_used: int
    n_gated: int
    nis: float
    dof: int
    p_value: float
    rms_normalized: float


@dataclass(frozen=True)
class BlockReport:
    """What one :meth:`Filtr.step` did.

    Attributes
    ----------
    index : block number in the pass; n_blocks : blocks per pass; pass_index : 0-based.
    t_start, t_end : the block's time window [s].
    names : solve-for element names (``problem.state.solve_for`` order).
    prior_x, prior_sigma : (n,) estimates and 1-sigma at the block start;
    x, sigma : (n,) after the block. With a gyro, ``att.roll/pitch/yaw`` are those of the
        *current* attitude (at ``t_start`` / ``t_end``) relative to the reference frame.
    q_BI : (4,) attitude at ``t_end`` (gyro missions) or None.
    sensors : sensor -> :class:`InnovationStats`.
    nis, dof, p_value : block totals over used frames.
    frames_used, frames_gated, frames_invalid : counts over all sensors.
    frames : sensor -> :class:`FrameDiagnostics` of this block's frames.
    """

    index: int
    n_blocks: int
    pass_index: int
    t_start: float
    t_end: float
    names: tuple[str, ...]
    prior_x: np.ndarray
    prior_sigma: np.ndarray
    x: np.ndarray
    sigma: np.ndarray
    q_BI: np.ndarray | None
    sensors: Mapping[str, InnovationStats]
    nis: float
    dof: int
    p_value: float
    frames_used: int
    frames_gated: int
    frames_invalid: int
    frames: Mapping[str, FrameDiagnostics] = field(repr=False, default_factory=dict)

    @property
    def fraction(self) -> float:
        """Progress within the pass, 0..1."""
        return (self.index + 1) / self.n_blocks


@dataclass(frozen=True)
class FilterResult(StaticAlgebra):
    """Outcome of a filter + smoother run, with its diagnostics (a :class:`FitResult`).

    Attributes
    ----------
    state : the state with estimated values (attitude: roll/pitch/yaw at the reference
        time, from the smoothed attitude, as :class:`BatchResult`).
    solve_for : element names; x : (n,) estimates; P : (n, n) covariance (same order).
    residuals : sensor -> post-fit :class:`SensorResiduals`.
    trajectory : smoothed attitude at every epoch (gyro missions) or None.
    frames : sensor -> :class:`FrameDiagnostics` of the last pass.
    blocks : every :class:`BlockReport` of every pass.
    passes : passes made; status : "converged", "max_passes", "single_pass" or "cancelled".
    nis, nis_dof, nis_p_value : innovation totals of the last pass (Σ NIS, Σ m, its χ² p).
    consider : none (the filter holds consider elements at their values, ``message``);
    unobservable : none named (the filter forms no data-only information).
    """

    state: StateVector
    solve_for: tuple[str, ...]
    x: np.ndarray
    P: np.ndarray
    residuals: dict[str, SensorResiduals]
    trajectory: SmoothedTrajectory | None
    frames: Mapping[str, FrameDiagnostics]
    blocks: tuple[BlockReport, ...]
    passes: int
    status: str
    message: str
    nis: float
    nis_dof: int
    nis_p_value: float
    consider: tuple[str, ...] = ()
    unobservable: tuple[str, ...] = ()

    @property
    def scores_own_residuals(self) -> bool:
        """True: the score tests read the smoother's residuals. It has removed the attitude
        wander of the gyro noise, which the deterministic residuals would offer as a
        signature (:func:`gcs_core.diagnosis.ranking.rank_candidates`)."""
        return True

    @property
    def P_consider(self) -> np.ndarray:
        return self.P

    @property
    def sigma(self) -> dict[str, float]:
        return {n: float(np.sqrt(self.P[i, i])) for i, n in enumerate(self.solve_for)}

    @property
    def values(self) -> dict[str, float]:
        return self.state.values()

    @cached_property
    def chi2(self) -> float:
        """Post-fit χ² of the smoothed residuals over used frames."""
        return float(sum(r.chi2 for r in self.residuals.values()))

    @cached_property
    def dof(self) -> int:
        """Used measurement components − solve-for elements."""
        return int(sum(r.n * len(r.components) for r in self.residuals.values())) - len(self.solve_for)

    @property
    def information(self) -> None:
        """None: the filter's covariance mixes the process noise in; there is no data-only
        information matrix to name weak directions from."""
        return None

    @property
    def consider_budget(self) -> Mapping[str, np.ndarray]:
        return {}

    def correlation(self) -> np.ndarray:
        d = np.sqrt(np.diag(self.P))
        return self.P / np.outer(d, d)


def passes_text(n: int, status: str) -> str:
    """The run's status in words: the iterated smoother's passes are a refinement, and
    ending at the pass limit is normal, not a failure."""
    passes = f"{n} pass{'es' if n != 1 else ''}"
    return {
        "converged": f"converged after {passes}",
        "max_passes": f"{passes} done, as configured (max_passes): each relinearizes about the smoothed estimate",
        "single_pass": "one pass (filter and smoother)",
        "cancelled": f"cancelled during pass {n}",
    }.get(status, f"{passes}, {status}")


def nis_p_value(nis: float, dof: int) -> float:
    """``P(χ²_dof ≥ nis)``: the upper tail of a normalized innovation squared (NaN without dof)."""
    return float(special.chdtrc(dof, nis)) if dof > 0 else float("nan")
