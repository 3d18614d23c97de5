"""The magnitude-only magnetometer observable of a plan (the seed's CADS comparison).

SMM's attitude-independent magnetometer calibration (the seed's CADS) used the field
magnitude alone, ``y = |B_m|``, not the vector. Its linearization is the vector model's
projected on the predicted field direction ``u = B̂_m / |B̂_m|`` (sensor frame, bias
included)::

    ∂|B_m|/∂x = uᵀ ∂B_m/∂x,    σ_|B| = sqrt(Σ_i u_i² σ_i²)   (= σ for equal axis noise)

so the predictor's information of a magnitude-only sensor is ``Hᵀ u uᵀ H / σ²`` per
frame instead of ``Hᵀ H / σ²``: the components of the bias across the field are learnt
only as the field turns, and the attitude not at all (``uᵀ [B×] = 0`` without bias).
A plan chooses it per magnetometer (``observable = "magnitude"`` in a plan's
``[[sensor]]``, or the trade key ``NAME.observable``).
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

#: the data-book value that selects it (gcs_core.trade.space.OBSERVABLES)
MAGNITUDE = "magnitude"


@dataclass(frozen=True)
class MagnitudeRows:
    """The part of a :class:`~gcs_core.problem.linearization.Linearization` the predictor's
    information reads (:func:`gcs_core.predictor.information.weighted_rows`), for ``|B|``."""

    name: str
    H: np.ndarray  # (N, 1, k)
    sigma: np.ndarray  # (1,)
    valid: np.ndarray  # (N,)


def magnitude_rows(lin) -> MagnitudeRows:
    """The magnitude observable's rows of a magnetometer's linearization (module docstring)."""
    y = np.asarray(lin.y_pred, float)
    norm = np.linalg.norm(y, axis=1, keepdims=True)
    u = np.divide(y, norm, out=np.zeros_like(y), where=norm > 0)
    H = np.einsum("nm,nmk->nk", u, np.asarray(lin.H, float))[:, None, :]
    sigma = np.asarray(lin.sigma, float)
    s = np.sqrt(np.einsum("nm,m->n", u**2, sigma**2))
    # one σ for the sensor: the frames' (equal for equal axis noise), at its median
    return MagnitudeRows(lin.name, H, np.array([float(np.median(s)) if s.size else float(sigma[0])]), lin.valid)


def magnitude_sensors(spec) -> set[str]:
    """The plan's magnetometers that measure the magnitude alone."""
    return {s.name for s in spec.sensors if s.type == "magnetometer" and s.get("observable") == MAGNITUDE}
