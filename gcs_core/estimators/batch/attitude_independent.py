"""Attitude-independent calibrations of seed §2 (SMM practice, §2.1.2 and §2.2.2).

**Magnetometer bias from the field magnitude** (§2.1.2 item 2). A constant bias changes the
magnitude of the measured field while an attitude error does not, so the bias can be
found whatever the attitude accuracy::

    minimize Σ_k (|B_k − b| − |B_ref,k|)² / σ²,     ∂|B_k − b|/∂b = −(B_k − b)/|B_k − b|

solved by Gauss–Newton from ``b = 0``. As §2.1.2 explains, a short pass gives an unreliable
``b`` (the field direction must vary); the covariance returned says so honestly.

**Star-tracker scale factors from angular separations** (§2.2.2 item 1). The angle between
two stars seen by one tracker is independent of the attitude and of the tracker's
alignment. For stars seen in sequence the body turns between the sightings; the gyros give
that relative rotation, ``R = C(t_j) C(t_i)ᵀ`` (only the *relative* attitude, which does
not depend on the absolute attitude error)::

    F(h, v; S_H, S_V) = (cos S_H h cos S_V v, cos S_H h sin S_V v, sin S_H h)     (Eq 4-29 inverted)
    cos θ_meas = F_i · (M R_ijᵀ Mᵀ) F_j,      cos θ_cat = û_i · û_j
    minimize Σ (θ_meas − θ_cat)² / σ_θ²,      σ_θ² ≈ 2 σ²

References
----------
Shuster, M. D. & Alonso, R., "Attitude-independent magnetometer-bias determination: a
survey", J. Astronautical Sciences 50(4), 2002. Wertz (ed.) 1978, §7.6 (star sensors).
"""

from __future__ import annotations

from collections.abc import Mapping
from dataclasses import dataclass

import numpy as np

from gcs_core.errors import EstimationError
from gcs_core.models import common as model_common
from gcs_core.problem.build import Problem


@dataclass(frozen=True)
class IndependentResult:
    """Estimate of an attitude-independent calibration.

    Attributes
    ----------
    names : element names estimated; x : (k,) estimates; P : (k, k) covariance.
    residual_rms_normalized : RMS of residuals / σ (1.0 = noise floor).
    n : observations used; iterations : Gauss–Newton iterations.
    """

    names: tuple[str, ...]
    x: np.ndarray
    P: np.ndarray
    residual_rms_normalized: float
    n: int
    iterations: int

    @property
    def sigma(self) -> dict[str, float]:
        return {nm: float(np.sqrt(self.P[i, i])) for i, nm in enumerate(self.names)}

    @property
    def values(self) -> dict[str, float]:
        return {nm: float(self.x[i]) for i, nm in enumerate(self.names)}


def _gauss_newton(fun, x0: np.ndarray, max_iter: int = 20, tol: float = 1e-10):
    x = x0.astype(float).copy()
    for it in range(1, max_iter + 1):  # noqa: B007 — the count is returned after the loop
        r, J = fun(x)
        JTJ = J.T @ J
        step = np.linalg.solve(JTJ, -(J.T @ r))
        x = x + step
        if np.max(np.abs(step)) < tol * max(1.0, float(np.max(np.abs(x)))):
            break
    r, J = fun(x)
    return x, np.linalg.inv(J.T @ J), r, it


def magnetometer_bias_from_magnitude(
    problem: Problem, sensor: str, values: Mapping[str, float] | None = None
) -> IndependentResult:
    """§2.1.2: TAM bias from |B_measured − b| against |B_reference| (module docstring)."""
    sd = problem.sensor(sensor)
    if sd.model.type_name != "magnetometer":
        raise EstimationError(f"{sensor} is not a magnetometer")
    B_m = sd.y
    if sd.geom.B_I is None:
        raise EstimationError(f"{sensor}: no reference field in the geometry")
    ref = np.linalg.norm(sd.geom.B_I, axis=1)
    sigma = float(np.mean(sd.sigma))
    ok = np.all(np.isfinite(B_m), axis=1) & np.isfinite(ref)
    B_m, ref = B_m[ok], ref[ok]
    if B_m.shape[0] < 4:
        raise EstimationError(f"{sensor}: too few samples for a bias from the field magnitude")

    def fun(b):
        d = B_m - b
        mag = np.linalg.norm(d, axis=1)
        return (mag - ref) / sigma, -(d / mag[:, None]) / sigma

    x, P, r, it = _gauss_newton(fun, np.zeros(3))
    names = tuple(problem.param_map[sensor][f"bias_{a}"] for a in "xyz")
    return IndependentResult(names, x, P, float(np.sqrt(np.mean(r**2))), int(r.size), it)


def _unit_from_hv(h, v, s_h, s_v):
    a, b = s_h * h, s_v * v
    ca = np.cos(a)
    return np.column_stack([ca * np.cos(b), ca * np.sin(b), np.sin(a)])


def star_tracker_scales_from_separations(
    problem: Problem, sensor: str, *, values: Mapping[str, float] | None = None, max_gap_s: float = 30.0
) -> IndependentResult:
    """§2.2.2: S_H, S_V from angular separations of successive stars (module docstring).

    Pairs are consecutive frames of the tracker no more than ``max_gap_s`` apart that see
    different stars; the body's turn between them comes from the attitude provider (the
    gyros), of which only the relative rotation enters.
    """
    sd = problem.sensor(sensor)
    if sd.model.type_name != "star_tracker":
        raise EstimationError(f"{sensor} is not a star tracker")
    vals = dict(values or problem.state.values())
    params = problem.params_of(sensor, vals)
    M, _ = model_common.alignment_matrix(params)
    att = problem.attitude.evaluate(vals, sd.t)
    if att.C_BI is None:
        raise EstimationError("star-tracker separations need a three-axis attitude")
    star = sd.geom.star_I
    if star is None:
        raise EstimationError(f"{sensor}: no catalog star vectors in the geometry")
    i = np.arange(sd.n - 1)
    j = i + 1
    sep_cat = np.arccos(np.clip(np.sum(star[i] * star[j], axis=1), -1.0, 1.0))
    keep = (
        (sd.t[j] - sd.t[i] <= max_gap_s)
        & (sep_cat > 1e-4)
        & np.all(np.isfinite(sd.y[i]), 1)
        & np.all(np.isfinite(sd.y[j]), 1)
    )
    i, j, sep_cat = i[keep], j[keep], sep_cat[keep]
    if i.size < 3:
        raise EstimationError(f"{sensor}: too few star pairs for scale factors from separations")
    # sensor-frame rotation from frame i to frame j: M C_j C_iᵀ Mᵀ, applied as its transpose
    R = M @ att.C_BI[j] @ np.swapaxes(att.C_BI[i], 1, 2) @ M.T
    h, v = sd.y[:, 0], sd.y[:, 1]
    sigma_theta = float(np.sqrt(2.0) * np.mean(sd.sigma))
    eps = 1e-7

    def sep(x):
        Fi = _unit_from_hv(h[i], v[i], x[0], x[1])
        Fj = _unit_from_hv(h[j], v[j], x[0], x[1])
        Fj_in_i = np.einsum("nji,nj->ni", R, Fj)
        return np.arccos(np.clip(np.sum(Fi * Fj_in_i, axis=1), -1.0, 1.0))

    def fun(x):
        r = (sep(x) - sep_cat) / sigma_theta
        J = np.column_stack(
            [(sep(x + d) - sep(x - d)) / (2 * eps) / sigma_theta for d in (np.array([eps, 0.0]), np.array([0.0, eps]))]
        )
        return r, J

    x0 = np.array([params["scale_h"], params["scale_v"]])
    x, P, r, it = _gauss_newton(fun, x0)
    names = (problem.param_map[sensor]["scale_h"], problem.param_map[sensor]["scale_v"])
    return IndependentResult(names, x, P, float(np.sqrt(np.mean(r**2))), int(r.size), it)
