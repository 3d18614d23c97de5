"""The whole-span fit's result (:mod:`.fit`): a :class:`~gcs_core.estimators.results.BatchResult`
with its knot corrections, answering the questions of the result protocol with the knots
counted (:mod:`.uses`, :mod:`.elimination`). Without process noise (``dynamics`` None) it
answers as a static fit (:mod:`gcs_core.estimators.static_algebra`).
"""

from __future__ import annotations

from collections.abc import Mapping
from dataclasses import dataclass

import numpy as np

from gcs_core.estimators.results import BatchResult
from gcs_core.estimators.static_algebra import Elimination, HoldoutChi2, Influence
from gcs_core.estimators.whole_span import uses
from gcs_core.estimators.whole_span.elimination import KnotElimination
from gcs_core.estimators.whole_span.passes import Dynamics
from gcs_core.problem.attitude import AttitudeProvider
from gcs_core.problem.build import Problem

#: how a fit with knots forms its effective parameters
INFLUENCE_SOURCE = "trace of the influence matrix (static elements and knots)"


@dataclass(frozen=True)
class SmoothedResult(BatchResult):
    """A :class:`BatchResult` of the whole-span fit, with its knot corrections.

    dynamics : the knots (None when there is no process noise); chi2_process : the
    process term of ``chi2``; batch_delta_sigma : (n,) the batch solution's distance from
    this one in this fit's σ.
    """

    dynamics: Dynamics | None = None
    chi2_process: float = 0.0
    batch_delta_sigma: np.ndarray | None = None

    @property
    def carries_process_noise(self) -> bool:
        return self.dynamics is not None

    def warm_start(self) -> dict:
        """A refit of the same data starts at this solution, knots and edits included."""
        return {"start": self} if self.dynamics is not None else super().warm_start()

    def attitude_provider(self, provider: AttitudeProvider) -> AttitudeProvider:
        """The fitted attitude: the gyro-carried one corrected by the knots."""
        return self.dynamics.attitude(provider) if self.dynamics is not None else provider

    def attitude_wander_covariance(self, C: np.ndarray, t: np.ndarray, J: np.ndarray) -> np.ndarray:
        """(N, 3, 3) the knots' share of the attitude error covariance at ``t``
        (:func:`.uses.attitude_covariance`)."""
        if self.dynamics is None:
            return super().attitude_wander_covariance(C, t, J)
        return uses.attitude_covariance(self.dynamics, C, t, J)

    def holdout_rms(self, problem: Problem, masks: Mapping[str, np.ndarray]) -> dict[str, float]:
        """Held-out normalized RMS with the knots' uncertainty (:func:`.uses.smoothed_holdout_rms`)."""
        if self.dynamics is None:
            return super().holdout_rms(problem, masks)
        return uses.smoothed_holdout_rms(problem, self, masks)

    def holdout_chi2(self, problem: Problem, sel: Mapping[str, np.ndarray]) -> HoldoutChi2 | None:
        """Held-out χ² of a fit with knot corrections: each residual standardized by its full
        prediction variance, summed (``Σ z²`` on the held-out measurements). The correlation
        between held-out frames through common errors is neglected here (no joint covariance
        of the knots across a held-out block is formed), so the test is exact only where the
        prediction variance is small against the noise."""
        if self.dynamics is None:
            return super().holdout_chi2(problem, sel)
        acc: dict[str, list] = {}
        for name, r, noise, var in uses.smoothed_frames(problem, self, sel):
            a = acc.setdefault(name, [0.0, 0])
            a[0] += float(np.sum(r**2 / (noise + var)))
            a[1] += r.size
        per = {k: (v[0], v[1]) for k, v in acc.items() if v[1]}
        if not per:
            return None
        return HoldoutChi2(per, (sum(c for c, _ in per.values()), sum(m for _, m in per.values())))

    def influence(self, problem: Problem) -> Influence:
        """Sensor -> ``Σ_k tr(R⁻¹ Cov(ŷ_k))`` over its used frames.

        For a linear Gaussian smoother the influence of a measurement on its own prediction
        is ``∂ŷ_k/∂y_k = H_k P H_kᵀ R_k⁻¹`` with ``P`` the joint posterior of the static
        elements and the knot corrections, i.e. the prediction's variance over the noise
        variance (the same terms that standardize the held-out residuals). Summed over the
        used frames it is the sensor's effective parameters (Hastie et al. §7.6).
        """
        if self.dynamics is None:
            return super().influence(problem)
        used = {k: np.asarray(r.used, bool) for k, r in self.residuals.items()}
        out = {k: 0.0 for k in used}
        for name, _, noise, var in uses.smoothed_frames(problem, self, used):
            out[name] += float(np.sum(var / noise))
        return Influence(out, INFLUENCE_SOURCE, False)

    def candidate_elimination(self, problem: Problem, K: int, A: np.ndarray, g: np.ndarray) -> Elimination:
        """The knots (and the read-out errors) eliminated from the score tests' normal
        equations ``A``, ``g`` over ``K`` columns (:class:`.elimination.KnotElimination`)."""
        if self.dynamics is None:
            return super().candidate_elimination(problem, K, A, g)
        return KnotElimination(problem, self.dynamics, K, A, g)
