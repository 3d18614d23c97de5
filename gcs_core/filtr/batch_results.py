"""Results of the batch estimator (seed Eq 3-1, 3-2): per-sensor post-fit residuals, the
fit's outcome, the residual buffers of a streaming pass. Split from
:mod:`gcs_core.filtr.batch`, which re-exports these names.
"""

from __future__ import annotations

from collections.abc import Mapping, Sequence
from dataclasses import dataclass, field

import numpy as np

from gcs_core.filtr.linearization import Linearization
from gcs_core.filtr.problem import Problem
from gcs_core.models.base import ObservationModel
from gcs_core.sodl.state import StateVector

__all__ = ["SensorResiduals", "BatchResult", "Residuals", "accumulate", "weighted_masks",
           "residuals_from", "make_residuals"]


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
        return np.sqrt(np.mean(r ** 2, axis=0)) if r.size else np.full(self.residual.shape[1], np.nan)

    @property
    def rms_normalized(self) -> float:
        r = self.normalized[self.used]
        return float(np.sqrt(np.mean(r ** 2))) if r.size else float("nan")

    @property
    def chi2(self) -> float:
        return float(np.sum(self.normalized[self.used] ** 2))


@dataclass(frozen=True)
class BatchResult:
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


# ----------------------------------------------------------------------------------------
def weighted_masks(lins: Sequence[Linearization], edited: Mapping[str, np.ndarray]):
    for lin in lins:
        used = lin.valid & ~edited.get(lin.name, np.zeros(lin.valid.shape, bool))
        yield lin, used


def accumulate(lins: Sequence[Linearization], edited: Mapping[str, np.ndarray], n: int):
    """``A = Σ Hᵀ R⁻¹ H``, ``b = Σ Hᵀ R⁻¹ r``, ``χ² = Σ rᵀ R⁻¹ r`` over used frames
    (whole-span :class:`Linearization` form; the estimators use :func:`normal_equations`)."""
    A = np.zeros((n, n))
    b = np.zeros(n)
    chi2 = 0.0
    m_used = 0
    for lin, used in weighted_masks(lins, edited):
        if not np.any(used):
            continue
        # R^-1/2 with unused frames weighted zero (cheaper than copying the used rows)
        w = used[:, None] / lin.sigma[None, :]                # (N, m)
        rw = (lin.r * w).reshape(-1)                          # R^-1/2 r
        if n:
            Hw = (lin.H * w[:, :, None]).reshape(-1, n)       # R^-1/2 H
            A += Hw.T @ Hw
            b += Hw.T @ rw
        chi2 += float(rw @ rw)
        m_used += int(np.count_nonzero(used)) * lin.r.shape[1]
    return A, b, chi2, m_used


@dataclass
class Residuals:
    """Per-sensor buffers of one pass, reused across passes: r (N, m), valid (N,), and
    y_pred (N, m) for models whose residual is not the plain difference ``y − y_pred``
    (the others give it back as ``y − r``, :class:`SensorResiduals`)."""

    y_pred: dict[str, np.ndarray] = field(default_factory=dict)
    r: dict[str, np.ndarray] = field(default_factory=dict)
    valid: dict[str, np.ndarray] = field(default_factory=dict)

    def ensure(self, problem: Problem) -> Residuals:
        for sd in problem.sensors:
            if sd.name not in self.r:
                m = len(sd.sigma)
                if type(sd.model).residual is not ObservationModel.residual:
                    self.y_pred[sd.name] = np.empty((sd.n, m))
                self.r[sd.name] = np.empty((sd.n, m))
                self.valid[sd.name] = np.empty(sd.n, bool)
        return self


def residuals_from(problem: Problem, buffers: Residuals,
                   edits: Mapping[str, np.ndarray]) -> dict[str, SensorResiduals]:
    """:class:`SensorResiduals` from the buffers of a pass (taken over, not copied)."""
    out = {}
    for sd in problem.sensors:
        valid = buffers.valid[sd.name]
        ed = edits.get(sd.name, np.zeros(valid.shape, bool)) & valid
        r = buffers.r[sd.name]
        r[~valid] = np.nan
        out[sd.name] = SensorResiduals(sd.name, tuple(sd.model.components), sd.model.unit, sd.t, sd.y,
                                       buffers.y_pred.get(sd.name), r, None, sd.sigma, valid & ~ed,
                                       valid, ed)
    return out


def _zero_invalid(lin: Linearization) -> Linearization:
    if np.all(lin.valid):
        return lin
    H = np.where(lin.valid[:, None, None], lin.H, 0.0)
    r = np.where(lin.valid[:, None], lin.r, 0.0)
    return Linearization(lin.name, lin.y_pred, r, H, lin.valid, lin.sigma)


def make_residuals(problem: Problem, lins: Sequence[Linearization],
                   edits: Mapping[str, np.ndarray]) -> dict[str, SensorResiduals]:
    out = {}
    for lin in lins:
        sd = problem.sensor(lin.name)
        ed = edits.get(lin.name, np.zeros(lin.valid.shape, bool)) & lin.valid
        used = lin.valid & ~ed
        r = np.where(lin.valid[:, None], lin.r, np.nan)
        out[lin.name] = SensorResiduals(lin.name, tuple(sd.model.components), sd.model.unit, sd.t, sd.y,
                                        lin.y_pred, r, r / lin.sigma, lin.sigma, used, lin.valid, ed)
    return out
