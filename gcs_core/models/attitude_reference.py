"""Attitude reference: an attitude quaternion measured by another instrument; ICD extension
``attitude_reference`` (docs/attitude_reference.md).

A star tracker that outputs its own attitude quaternion, or optical motion capture on
the ground, measures the attitude of *its* frame S against the reference frame I. The
body attitude ``C = C_BI`` (gyro-carried or referenced, as for every sensor) maps to it
through the instrument's alignment ``M = T3(a3) T2(a2) T1(a1)`` (ICD §2) and a time-tag
offset ``Δt`` (the sample is of time ``t + Δt``)::

    C_SI = M R(Δt) C,     R(Δt) = exp(−[ω_B Δt ×])                  (measurement equation)

with ``ω_B`` the body rate (the same shift as :func:`gcs_core.models.common.body_vector`).

Measurement and residual. A telemetry row is the unit quaternion ``(q1, q2, q3, q4)``
(scalar last, Eq 4-8) of ``C_SI``; :meth:`AttitudeReferenceModel.measurements` keeps it
as its rotation vector ``φ_m`` (``C_SI = exp(−[φ_m×])``), the prediction is the rotation
vector ``φ̂`` of ``M R C``, and the residual is not their difference but the small
rotation ``e`` between the two attitudes, in the instrument frame::

    C_SI,measured = exp(−[e×]) C_SI,predicted,     e = rotvec(C_m Ĉᵀ)      (residual, rad)

so the three components are small angles about the instrument's x, y, z axes, at any
attitude (no wrap at 180°). Partials of ``e`` with a minus sign (``r = y − h``), in the
error convention of :mod:`gcs_core.models.base` (``C ← (I − [δθ×]) C``)::

    ∂h/∂δθ = M R                                      (N, 3, 3)
    ∂h/∂a_k = −vee(∂M/∂a_k Mᵀ)                       (the same for every frame)
    ∂h/∂Δt = M ω_B

State: ``align_1..3`` (effect ``alignment``, held by default as every alignment is: the
body frame needs a reference) and ``time_offset`` (extended, held, a catalogue effect).
Noise: ``noise`` [rad], the 1-σ of each small angle.

References
----------
Markley, F. L., Crassidis, J. L., *Fundamentals of Spacecraft Attitude Determination and
Control*, Springer 2014, §2.9 (rotation vector) and §6.2 (attitude error
representations).
"""

from __future__ import annotations

from collections.abc import Mapping

import numpy as np

from gcs_core.frames.rotations import dcm_to_rotvec, quat_normalize, quat_to_dcm, rotvec_to_dcm
from gcs_core.io.types import Table
from gcs_core.models import common
from gcs_core.models.base import Geometry, ObservationModel, ParamSpec, Prediction

QUATERNION_COLUMNS = ("q1", "q2", "q3", "q4")


def _vee(S: np.ndarray) -> np.ndarray:
    """Vector of a skew matrix ``[a×]`` (..., 3, 3) -> (..., 3)."""
    return np.stack([S[..., 2, 1], S[..., 0, 2], S[..., 1, 0]], -1)


def attitude_error(phi_a: np.ndarray, phi_b: np.ndarray) -> np.ndarray:
    """``e`` with ``exp(−[e×]) = exp(−[φ_a×]) exp(−[φ_b×])ᵀ`` (N, 3) [rad]: the small
    rotation taking attitude b to attitude a, in a's frame."""
    Ca = rotvec_to_dcm(np.asarray(phi_a, dtype=float))
    Cb = rotvec_to_dcm(np.asarray(phi_b, dtype=float))
    return dcm_to_rotvec(Ca @ np.swapaxes(Cb, -1, -2))


class AttitudeReferenceModel(ObservationModel):
    """An attitude measured by another instrument: ``C_SI = M R(Δt) C_BI`` (module docstring)."""

    type_name = "attitude_reference"
    columns = QUATERNION_COLUMNS
    components = ("ex", "ey", "ez")
    unit = "rad"
    attitude_kind = "three_axis"
    book_keys = ()

    def parameters(self) -> tuple[ParamSpec, ...]:
        return common.cached_parameters(self, self._parameters)

    def _parameters(self) -> tuple[ParamSpec, ...]:
        specs = list(common.alignment_specs(self.sensor, seed=True, sigma=0.01))
        specs.append(common.time_offset_spec("the attitude sample"))
        return tuple(specs)

    def sigma(self) -> np.ndarray:
        return np.full(3, common.noise_value(self.sensor))

    def measurements(self, table: Table) -> tuple[np.ndarray, np.ndarray]:
        """``(t, φ_m)``: the rotation vector (N, 3) [rad] of each measured quaternion."""
        q = quat_normalize(table.stack(QUATERNION_COLUMNS))
        return table.t, dcm_to_rotvec(quat_to_dcm(q))

    def residual(self, y_meas: np.ndarray, y_pred: np.ndarray, geom: Geometry | None = None) -> np.ndarray:
        """The small rotation from the predicted to the measured attitude (N, 3) [rad]."""
        return attitude_error(y_meas, y_pred)

    def predict(self, geom: Geometry, params: Mapping[str, float]) -> Prediction:
        """``φ̂ = rotvec(M R C)`` at N frames: y (N, 3), d_att (N, 3, 3), d_par (N, 3)."""
        specs = self.parameters()
        p = common.merged_params(specs, params)
        if geom.C_BI is None:
            raise ValueError("the attitude reference model needs the attitude C_BI")
        n = geom.n
        M, dM = common.alignment_matrix(p)
        C = np.asarray(geom.C_BI, dtype=float)
        dt = p["time_offset"]
        omega = None
        if geom.omega_B is not None:
            omega = np.broadcast_to(np.asarray(geom.omega_B, dtype=float), (n, 3))
        if omega is not None and dt != 0.0:
            MR = M @ rotvec_to_dcm(omega * dt)  # M R(Δt), (N, 3, 3)
        else:
            MR = np.broadcast_to(M, (n, 3, 3))
        y = dcm_to_rotvec(MR @ C)
        d_par: dict[str, common.PartialSource] = {}
        for k, name in enumerate(common.ALIGN_NAMES):
            w = -_vee(dM[k] @ M.T)
            d_par[name] = np.broadcast_to(w, (n, 3))
        d_par["time_offset"] = (lambda: omega @ M.T) if omega is not None else np.zeros((n, 3))
        return common.finish(y, MR, d_par, np.ones(n, dtype=bool), specs)
