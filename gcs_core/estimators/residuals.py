"""Per-sensor residuals of a pass (seed Eq 3-1, 3-2): the buffers a streaming pass fills,
the normal-equation accumulation over a whole-span linearization and the
:class:`~gcs_core.estimators.results.SensorResiduals` built from either.
"""

from __future__ import annotations

from collections.abc import Mapping, Sequence
from dataclasses import dataclass, field

import numpy as np

from gcs_core.estimators.results import SensorResiduals
from gcs_core.models.base import ObservationModel
from gcs_core.problem.build import Problem
from gcs_core.problem.linearization import Linearization


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
        w = used[:, None] / lin.sigma[None, :]  # (N, m)
        rw = (lin.r * w).reshape(-1)  # R^-1/2 r
        if n:
            Hw = (lin.H * w[:, :, None]).reshape(-1, n)  # R^-1/2 H
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
    #: sensor -> (N, m, 3) the model's attitude partials, kept only when asked (:meth:`ensure`)
    d_att: dict[str, np.ndarray] = field(default_factory=dict)

    def ensure(self, problem: Problem, *, attitude_partials: bool = False) -> Residuals:
        for sd in problem.sensors:
            m = len(sd.sigma)
            if sd.name not in self.r:
                if type(sd.model).residual is not ObservationModel.residual:
                    self.y_pred[sd.name] = np.empty((sd.n, m))
                self.r[sd.name] = np.empty((sd.n, m))
                self.valid[sd.name] = np.empty(sd.n, bool)
            if attitude_partials and sd.name not in self.d_att:
                self.d_att[sd.name] = np.zeros((sd.n, m, 3))
        return self


def residuals_from(problem: Problem, buffers: Residuals, edits: Mapping[str, np.ndarray]) -> dict[str, SensorResiduals]:
    """:class:`SensorResiduals` from the buffers of a pass (taken over, not copied)."""
    out = {}
    for sd in problem.sensors:
        valid = buffers.valid[sd.name]
        r = buffers.r[sd.name]
        r[~valid] = np.nan
        out[sd.name] = SensorResiduals.of(
            sd, buffers.y_pred.get(sd.name), r, valid, edits.get(sd.name), normalized=False
        )
    return out


def _zero_invalid(lin: Linearization) -> Linearization:
    if np.all(lin.valid):
        return lin
    H = np.where(lin.valid[:, None, None], lin.H, 0.0)
    r = np.where(lin.valid[:, None], lin.r, 0.0)
    return Linearization(lin.name, lin.y_pred, r, H, lin.valid, lin.sigma)


def make_residuals(
    problem: Problem, lins: Sequence[Linearization], edits: Mapping[str, np.ndarray]
) -> dict[str, SensorResiduals]:
    out = {}
    for lin in lins:
        sd = problem.sensor(lin.name)
        r = np.where(lin.valid[:, None], lin.r, np.nan)
        out[lin.name] = SensorResiduals.of(sd, lin.y_pred, r, lin.valid, edits.get(lin.name), sigma=lin.sigma)
    return out
