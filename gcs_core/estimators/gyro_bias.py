"""The gyro's bias along the span, with its σ, from a batch or whole-span fit (Eq 4-32, 4-38).

The estimators model the gyro's drift bias (in the gyro's frame) as::

    b(t) = b + ḃ (t − t_mid) + M β(t)

``b``, ``ḃ`` the static ``<GYRO>.bias_*`` and (when the bias-instability effect is in the
state) ``<GYRO>.bias_rate_*``, ``t_mid`` the middle of the gyro's span, ``M`` the gyro's
alignment (Eq 4-32, ``ω = Mᵀ (G⁻¹ y − b(t))``) and ``β`` the whole-span fit's body-axis
drift-bias correction (:mod:`gcs_core.estimators.whole_span.knots`): piecewise constant, ``β_j`` from knot
``τ_j`` to the next, a random walk with ``β(τ_0) = 0``. The static ``b`` alone is therefore
the bias at the first knot carried to ``t_mid`` by the drift, not a mean over the span:
two fits of different spans (halves of a trial) have their static biases at different
epochs, and a random-walking bias compared there differs by its walk. :func:`gyro_bias_at`
gives ``b(t)`` at any times, with the covariance of the statics, of the knot and their
cross-covariance (the smoother's marginals, :meth:`Dynamics.covariance`)::

    Var b(t) = J P Jᵀ + M Σ_ββ,j Mᵀ + J Cov(x, β_j) Mᵀ + M Cov(β_j, x) Jᵀ,
    J = ∂b(t)/∂x  (I on ``bias_*``, (t − t_mid) I on ``bias_rate_*``)

so two fits are compared where they overlap or meet, each σ carrying the walk the data
leave open there.

References
----------
Farrenkopf, R. L., J. Guidance Control 1(4), 1978 (the rate random walk of the bias).
Rauch, Tung & Striebel, AIAA J. 3(8), 1965 (the smoother's marginal covariances).
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from gcs_core.errors import InputError
from gcs_core.estimators.results import FitResult
from gcs_core.models import common as model_common
from gcs_core.problem.attitude import BIAS_RATE_NAMES
from gcs_core.problem.build import Problem

AXES = "xyz"


@dataclass(frozen=True)
class GyroBias:
    """The gyro's drift bias at given times.

    t : (N,) times [s since the mission epoch]; b : (N, 3) bias in the gyro's frame [rad/s];
    cov : (N, 3, 3) its covariance [(rad/s)²] (noise only: consider elements not included).
    """

    t: np.ndarray
    b: np.ndarray
    cov: np.ndarray

    @property
    def sigma(self) -> np.ndarray:
        """(N, 3) 1-σ per axis [rad/s]."""
        return np.sqrt(np.clip(np.einsum("nii->ni", self.cov), 0.0, None))


def gyro_bias_at(problem: Problem, result: FitResult, t) -> GyroBias:
    """``b(t)`` and its covariance at times ``t`` (module docstring), from ``result`` of
    a batch or whole-span fit of ``problem``; t : (N,) or scalar [s]. Times outside the
    gyro's span take the nearest knot's correction and the drift line extrapolated."""
    gyro = problem.gyro_name
    if gyro is None:
        raise InputError("the gyro's bias along the span needs a gyro-carried attitude (no gyro in the problem)")
    t = np.atleast_1d(np.asarray(t, dtype=float))
    att = problem.gyro_attitude
    values = result.state.values()
    knots = np.asarray(att.knots, dtype=float)
    t_mid = 0.5 * (knots[0] + knots[-1])
    names = list(result.solve_for)
    n = len(names)
    bias = np.array([values[f"{gyro}.bias_{a}"] for a in AXES])
    rate = np.array([values.get(f"{gyro}.{r}", 0.0) for r in BIAS_RATE_NAMES])
    # J = ∂b(t)/∂x over the solve-for statics: (N, 3, n)
    J = np.zeros((t.size, 3, n))
    for i, a in enumerate(AXES):
        if f"{gyro}.bias_{a}" in names:
            J[:, i, names.index(f"{gyro}.bias_{a}")] = 1.0
        if f"{gyro}.{BIAS_RATE_NAMES[i]}" in names:
            J[:, i, names.index(f"{gyro}.{BIAS_RATE_NAMES[i]}")] = t - t_mid
    b = bias[None, :] + (t - t_mid)[:, None] * rate[None, :]
    P = np.asarray(result.P, dtype=float)
    cov = np.einsum("nia,ab,njb->nij", J, P, J)
    dyn = result.dynamics
    if dyn is not None and dyn.grid.d == 6:
        M, _ = model_common.alignment_matrix(
            {k.split(".", 1)[1]: v for k, v in values.items() if k.startswith(gyro + ".")}
        )
        j = np.clip(np.searchsorted(dyn.grid.tau, t, side="right") - 1, 0, dyn.grid.K - 1)
        b = b + dyn.z[j, 3:6] @ M.T  # M β_j
        S, X = dyn.covariance()  # Σ_j (K, 6, 6), Cov(z_j, x) (K, 6, p) over dyn.names
        cols = [list(dyn.names).index(nm) for nm in names]
        Sbb = M @ S[j, 3:6, 3:6] @ M.T
        Xb = M @ X[j, 3:6][:, :, cols]  # Cov(M β_j, x) (N, 3, n)
        cross = np.einsum("nia,nja->nij", J, Xb)  # J Cov(x, β) Mᵀ
        cov = cov + Sbb + cross + np.swapaxes(cross, 1, 2)
    cov = 0.5 * (cov + np.swapaxes(cov, 1, 2))  # symmetric by construction; round-off
    return GyroBias(t, b, cov)
