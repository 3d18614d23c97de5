"""Plane-field Sun sensor on a spinner, seed §4.2.2, Eq 4-14 and 4-15; ICD §5 ``plane_field_sun``.

Observation model (the Sun angle at the time of the Sun sighting)::

    β_m = acos((Â·Ŝ) / cos ε_S) + Δβ                                  (Eq 4-14)

with ``Â`` the spin axis and ``Ŝ`` the unit Sun vector (GCI), ``ε_S`` the tilt of the
sensor's field plane (``tilt``, data-book ``tilt_deg``) and ``Δβ`` the Sun-angle bias
(``bias``). State (Eq 4-15): ``(α, δ, Δβ, ε_S)``; this model holds the two sensor
parameters, the attitude being the spin axis.

Attitude partials are with respect to the three components of ``Â`` (base.py). The
model normalizes ``Â`` before use, so the gradient is tangent to the unit sphere
(its radial component is zero) and chains to (α, δ) through Eq 4-2 unchanged::

    u = (Â·Ŝ)/cos ε_S,   X = 1/sqrt(1 − u²) = cos ε_S / sqrt(cos²ε_S − (Â·Ŝ)²)
    ∂β_m/∂Â  = −X (I − ÂÂᵀ) Ŝ / (|a| cos ε_S)            (a: the unnormalized input)
    ∂β_m/∂ε_S = −X (Â·Ŝ) sin ε_S / cos² ε_S,    ∂β_m/∂Δβ = 1

A frame is valid when ``|u| < 1``.
"""

from __future__ import annotations

from collections.abc import Mapping

import numpy as np

from gcs_core import units
from gcs_core.models import common
from gcs_core.models.base import Geometry, ObservationModel, ParamSpec, Prediction


class PlaneFieldSunModel(ObservationModel):
    """Plane-field Sun sensor, Eq 4-14: ``β_m = acos((Â·Ŝ)/cos ε_S) + Δβ``."""

    type_name = "plane_field_sun"
    columns = ("beta",)
    components = ("beta",)
    unit = "rad"
    attitude_kind = "spinning"
    book_keys = ("tilt_deg", "bias")

    def parameters(self) -> tuple[ParamSpec, ...]:
        tilt = common.book_scalar(self.sensor, "tilt_deg", 0.0) * units.DEG
        bias = common.book_scalar(self.sensor, "bias", 0.0)
        return (
            ParamSpec(
                "tilt",
                "rad",
                tilt,
                0.5 * units.DEG,
                seed=True,
                effect="tilt",
                description="Sun sensor field-plane tilt ε_S (Eq 4-14)",
            ),
            ParamSpec(
                "bias",
                "rad",
                bias,
                0.5 * units.DEG,
                seed=True,
                effect="bias",
                description="Sun angle bias Δβ (Eq 4-14)",
            ),
        )

    def sigma(self) -> np.ndarray:
        return np.full(1, common.noise_value(self.sensor))

    def predict(self, geom: Geometry, params: Mapping[str, float]) -> Prediction:
        """Eq 4-14 at N frames: y (N, 1) [rad], d_att (N, 1, 3) wrt Â, d_par (N, 1)."""
        specs = self.parameters()
        p = common.merged_params(specs, params)
        if geom.sun_I is None:
            raise ValueError("plane-field Sun sensor model needs sun_I in the geometry")
        eps, bias = p["tilt"], p["bias"]
        with np.errstate(all="ignore"):
            A, P = common.spin_axis_unit(geom)
            S = np.asarray(geom.sun_I, dtype=float)
            c = np.einsum("ni,ni->n", A, S)
            u = c / np.cos(eps)
            valid = np.abs(u) < 1.0
            dbeta_du = -1.0 / np.sqrt(1.0 - u**2)
            y = (np.arccos(np.clip(u, -1.0, 1.0)) + bias)[:, None]
            d_att = (dbeta_du / np.cos(eps))[:, None, None] * np.einsum("nij,nj->ni", P, S)[:, None, :]
            d_par = {"tilt": (dbeta_du * c * np.sin(eps) / np.cos(eps) ** 2)[:, None], "bias": np.ones((geom.n, 1))}
        return common.finish(y, d_att, d_par, valid, specs)
