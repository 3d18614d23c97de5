"""The gyro's rate random walk from the data: the whole-span fit's evidence over σ_u.

The whole-span fit (:mod:`gcs_core.estimators.whole_span.fit`) takes the gyro's σ_v, σ_u from
its data book. A book read off the unit's own rest (the Allan deviation of a short rest,
:mod:`gcs_core.noise.measured`) can miss how much the drift bias really wanders in use, and
every σ of the bias along the span (:mod:`gcs_core.estimators.gyro_bias`) rests on σ_u. The
data themselves say which σ_u they support: the marginal likelihood of the measurements
given the process noise, with the statics and the knot corrections ``w = (x, z)``
integrated out. For the linearized problem at the MAP solution (Laplace's approximation;
exact for a linear model)::

    −2 log p(y | σ_u) = J(ŵ) + log det N + Σ_j log det Q_j + const
    log det N = −log det P − Σ_j log det S_j⁻¹
    det Q_j = (a_j e_j − c_j²)³   (Farrenkopf's Q of :mod:`gcs_core.estimators.whole_span.knots`)

``J`` the whole cost (data χ², static prior, process term), ``N`` the normal matrix of
``w``: its determinant is the product of the knot pivots ``S_j`` of the forward
elimination and of the reduced statics' information ``P⁻¹``. The constant holds the
measurement noise and the static prior, the same for every σ_u as long as the data, the
edits and the knot grid are the same: :func:`rrw_profile` refits with the grid and the
edits of a base fit held, σ_u scaled, and returns ``−2 log p`` per scale; the smallest is
the data's σ_u (a difference of 2 is one unit of log-likelihood).

References
----------
Shumway, R. H. & Stoffer, D. S., *Time Series Analysis and Its Applications*, 4th ed.,
Springer 2017, §6.3 (maximum likelihood for state-space noise). Tierney, L. & Kadane,
J. B., JASA 81(393), 1986 (Laplace's approximation). Farrenkopf, R. L., J. Guidance
Control 1(4), 1978.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from gcs_core.errors import InputError
from gcs_core.estimators.batch.least_squares import BatchOptions
from gcs_core.estimators.results import BatchResult, FitResult
from gcs_core.estimators.whole_span.fit import whole_span_fit
from gcs_core.models.gyro_noise import GyroNoise
from gcs_core.problem.build import Problem


def _dynamics(result: FitResult):
    dyn = result.dynamics
    if dyn is None or dyn.factors is None or dyn.grid.d != 6:
        raise InputError("the evidence over σ_u needs a whole-span fit with a gyro rate random walk (rrw > 0)")
    return dyn


def neg2_log_evidence(problem: Problem, result: FitResult) -> float:
    """``−2 log p(y | σ_v, σ_u)`` of a whole-span fit, up to a constant that depends on the
    data, edits and knot grid only (module docstring)."""
    dyn = _dynamics(result)
    names = tuple(result.solve_for)
    state = problem.state
    x_bar = np.array([state[nm].value for nm in names])
    s0 = np.array([state[nm].sigma0 for nm in names])
    prior_info = np.where(np.isfinite(s0) & (s0 > 0), 1.0 / np.where(s0 > 0, s0, 1.0) ** 2, 0.0)
    d = x_bar - np.asarray(result.x, dtype=float)
    J = float(result.chi2) + float(np.sum(prior_info * d * d))  # chi2: data + process terms
    _, logdet_P = np.linalg.slogdet(np.asarray(result.P, dtype=float))
    Sinv = dyn.factors[0][1:]  # knot 0 is fixed (z_0 = 0): no pivot
    _, logdet_Sinv = np.linalg.slogdet(Sinv)
    grid = dyn.grid
    D = np.diff(grid.tau)
    v2, u2 = grid.sigma_v**2, grid.sigma_u**2
    a, c, e = v2 * D + u2 * D**3 / 3.0, -u2 * D**2 / 2.0, u2 * D
    logdet_Q = 3.0 * np.sum(np.log(a * e - c * c))
    return J - float(logdet_P) - float(np.sum(logdet_Sinv)) + float(logdet_Q)


@dataclass(frozen=True)
class RrwProfile:
    """The evidence over scales of the book's σ_u.

    scales : (k,) factors on σ_u; sigma_u : (k,) [rad/s^1.5]; neg2_log_evidence : (k,);
    best : the scale of the smallest; results : the fits, one per scale.
    """

    scales: np.ndarray
    sigma_u: np.ndarray
    neg2_log_evidence: np.ndarray
    best: float
    results: tuple


def rrw_profile(
    problem: Problem,
    result: BatchResult,
    scales=(0.5, 1.0, 2.0, 4.0, 8.0),
    *,
    arw_scale: float = 1.0,
    options: BatchOptions | None = None,
) -> RrwProfile:
    """Refit ``problem`` with σ_u scaled by each of ``scales`` (σ_v the fit's times
    ``arw_scale``), the knot grid and edits of ``result`` held, starting at ``result``'s
    statics; ``−2 log p`` each."""
    dyn = _dynamics(result)
    grid = dyn.grid
    spacing = float(np.median(np.diff(grid.tau)))
    edits = {nm: np.asarray(r.edited, bool) for nm, r in result.residuals.items()}
    opts = options or BatchOptions(edit_k=None)
    values, fits = [], []
    for k in scales:
        noise = GyroNoise(arw_scale * grid.sigma_v, k * grid.sigma_u)
        fit = whole_span_fit(problem, opts, edited=edits, noise=noise, spacing=spacing, start=result)
        fits.append(fit)
        values.append(neg2_log_evidence(problem, fit))
    v = np.array(values)
    s = np.asarray(scales, dtype=float)
    return RrwProfile(s, s * grid.sigma_u, v, float(s[int(np.argmin(v))]), tuple(fits))
