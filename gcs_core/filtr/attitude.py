"""Attitude as a function of state elements, with partials (seed §4.1, §4.2.7).

Three providers, one per kind of mission:

* :class:`ReferenceAttitude` — three-axis, constant roll/pitch/yaw relative to the
  reference frame (inertial, Earth- or Sun-pointing): ``C(t) = B(φ, θ, ψ) A(t)``
  (Eq 4-4, 4-6, 4-7). Elements ``att.roll``, ``att.pitch``, ``att.yaw``.
* :class:`GyroAttitude` — three-axis, attitude carried by the gyros from the
  roll/pitch/yaw at the reference time ``t_ref`` (Eq 4-32, 4-33, 4-38). Elements
  ``att.roll/pitch/yaw`` at ``t_ref`` plus the gyro's own parameters (Eq 4-37).
* :class:`SpinAttitude` — spin-axis right ascension and declination (Eq 4-2).
  Elements ``att.ra``, ``att.dec``.

Every provider answers :meth:`evaluate` with the attitude at the requested times and
the partials of the body-frame attitude error ``δθ`` (three-axis, the convention of
:mod:`gcs_core.models.base`) or of the spin axis ``Â`` (spinning) with respect to its
elements. The estimator chains them with the sensor models' ``d_att``.

Error propagation through the gyros (first order in ``δω Δt``)::

    δθ_k = Φ_k δθ_{k-1} + δω_k Δ_k,   Φ_k = C_k C_{k-1}ᵀ
    ⇒ C_kᵀ δθ_k = C_0ᵀ δθ_0 + Σ_{j≤k} C_jᵀ δω_j Δ_j              (a cumulative sum)

with ``δω = ∂ω/∂p δp`` from ``ω = Mᵀ (G⁻¹ y − b)`` (Eq 4-32 inverted).
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import Mapping

import numpy as np

from gcs_core.frames.reference import reference_dcm, spin_axis, spin_axis_partials
from gcs_core.frames.rotations import (dcm_to_euler123, euler123_partials, euler123_to_dcm,
                                       quat_from_dcm, quat_multiply, quat_normalize, quat_to_dcm)
from gcs_core.models import common as model_common
from gcs_core.models.base import ParamSpec
from gcs_core.models.gyro import G_NAMES, g_matrix
from gcs_core.units import DEG

RPY = ("att.roll", "att.pitch", "att.yaw")
#: gyro bias instability, modelled as a bias changing linearly over the span (rad/s²)
BIAS_RATE_NAMES = ("bias_rate_x", "bias_rate_y", "bias_rate_z")
RADEC = ("att.ra", "att.dec")


@dataclass(frozen=True)
class AttitudeEval:
    """Attitude at N times and its partials.

    Attributes
    ----------
    C_BI : (N, 3, 3) GCI-to-body (three-axis) or None.
    spin_axis_I : (3,) spin axis (spinning) or None.
    names : element names the partials refer to.
    J : (N, 3, k) ``∂δθ/∂x`` (three-axis) or ``∂Â/∂x`` (spinning), k = len(names).
    omega_B : (N, 3) body rate at the times (three-axis with gyros) or None.
    """

    C_BI: np.ndarray | None
    spin_axis_I: np.ndarray | None
    names: tuple[str, ...]
    J: np.ndarray
    omega_B: np.ndarray | None = None


def _vee(S):
    """Vector of a skew matrix ``[a×]`` (..., 3, 3) -> (..., 3)."""
    return np.stack([S[..., 2, 1], S[..., 0, 2], S[..., 1, 0]], -1)


def rpy_error_jacobian(roll, pitch, yaw) -> np.ndarray:
    """(3, 3) ``∂δθ/∂(φ, θ, ψ)`` for ``C = B(φ, θ, ψ) A`` (Eq 4-22 chained).

    ``δC = Σ ∂B/∂x_i A δx_i = −[δθ×] C`` gives ``[δθ×] = −Σ (∂B/∂x_i) Bᵀ δx_i``.
    """
    B = euler123_to_dcm(roll, pitch, yaw)
    dB = euler123_partials(roll, pitch, yaw)
    return np.stack([_vee(-(dB[i] @ B.T)) for i in range(3)], -1)


def rpy_specs(roll=0.0, pitch=0.0, yaw=0.0, sigma=1.0 * DEG) -> tuple[ParamSpec, ...]:
    return tuple(ParamSpec(n.split(".")[1], "rad", float(v), sigma, seed=True, effect="attitude",
                           description=f"{n.split('.')[1]} angle, Eq 4-4", element=n)
                 for n, v in zip(RPY, (roll, pitch, yaw)))


class ReferenceAttitude:
    """Constant roll/pitch/yaw relative to the reference frame (Eq 4-6)."""

    kind = "three_axis"

    def __init__(self, mode: str, ephemeris, builder=None):
        self.mode = mode
        self.ephemeris = ephemeris
        self.builder = builder

    @property
    def names(self) -> tuple[str, ...]:
        return RPY

    def reference(self, t) -> np.ndarray:
        t = np.atleast_1d(np.asarray(t, float))
        if self.mode == "inertial":
            return np.broadcast_to(np.eye(3), (t.size, 3, 3))
        r, v = self.ephemeris.state(t)
        return reference_dcm(self.mode, r, v, self.ephemeris.sun_geocentric(t))

    def evaluate(self, values: Mapping[str, float], t) -> AttitudeEval:
        rpy = [values[n] for n in RPY]
        B = euler123_to_dcm(*rpy)
        C = B @ self.reference(t)
        J = np.broadcast_to(rpy_error_jacobian(*rpy), (C.shape[0], 3, 3))
        return AttitudeEval(C, None, RPY, J)

    def rpy_from_dcm(self, C, t) -> tuple[float, float, float]:
        A = self.reference(np.atleast_1d(t))[0]
        return tuple(float(a) for a in dcm_to_euler123(C @ A.T))


class SpinAttitude:
    """Spin axis by right ascension and declination (Eq 4-2)."""

    kind = "spinning"
    names = RADEC

    def evaluate(self, values: Mapping[str, float], t) -> AttitudeEval:
        ra, dec = values["att.ra"], values["att.dec"]
        d_ra, d_dec = spin_axis_partials(ra, dec)
        n = np.atleast_1d(np.asarray(t)).size
        J = np.broadcast_to(np.stack([d_ra, d_dec], -1), (n, 3, 2))
        return AttitudeEval(None, spin_axis(ra, dec), RADEC, J)


def _quat_scan(q):
    """Cumulative composition ``Q_k = q_k ⊗ … ⊗ q_0`` by a parallel prefix (log2 N passes).

    Each pass composes every element with the one ``d`` places earlier; composition is
    associative, so after ``ceil(log2 N)`` passes ``Q_k`` is the product of all steps up
    to k. Vectorized; about 17 passes for a day of 1 Hz data.
    """
    Q = q.copy()
    d = 1
    n = Q.shape[0]
    while d < n:
        Q[d:] = quat_multiply(Q[d:], Q[:-d])
        d *= 2
    return quat_normalize(Q)


def _step_quaternions(omega, dt):
    """Quaternions of ``exp(−[ω Δt ×])`` (Eq 4-38), shape (N, 4)."""
    phi = omega * dt[:, None]
    ang = np.linalg.norm(phi, axis=-1)
    half = 0.5 * ang
    small = ang < 1e-12
    k = np.where(small, 0.5 - ang ** 2 / 48.0, np.sin(half) / np.where(small, 1.0, ang))
    return np.column_stack([phi * k[:, None], np.cos(half)])


class GyroAttitude:
    """Attitude carried by the gyros from roll/pitch/yaw at ``t_ref`` (module docstring).

    Parameters
    ----------
    mode : reference frame of the roll/pitch/yaw at ``t_ref``.
    ephemeris : for the reference frame at ``t_ref``.
    gyro_name : the gyro sensor's name (its parameters are ``<name>.G_ij``, ``.bias_*``,
        ``.align_*``).
    t_gyro : (K,) gyro row times; row k averages the rate over ``(t_{k-1}, t_k]``.
    y_gyro : (K, 3) gyro output [rad/s].
    """

    kind = "three_axis"

    def __init__(self, mode: str, ephemeris, gyro_name: str, t_gyro, y_gyro):
        self.ref = ReferenceAttitude(mode, ephemeris)
        self.gyro = gyro_name
        t_gyro = np.asarray(t_gyro, float)
        dt = np.diff(t_gyro)
        first = float(np.median(dt)) if dt.size else 1.0
        self.knots = np.concatenate([[t_gyro[0] - first], t_gyro])     # τ_0 .. τ_K
        self.dt = np.diff(self.knots)                                     # Δ_k, k=1..K
        self.y = np.asarray(y_gyro, float)
        self.t_ref = float(self.knots[0])
        self._cache_key = None
        self._cache = None

    @property
    def param_names(self) -> tuple[str, ...]:
        return tuple(f"{self.gyro}.{n}" for n in G_NAMES + ("bias_x", "bias_y", "bias_z")
                     + model_common.ALIGN_NAMES + BIAS_RATE_NAMES)

    @property
    def names(self) -> tuple[str, ...]:
        return RPY + self.param_names

    def covers(self, t) -> np.ndarray:
        t = np.asarray(t, float)
        return (t >= self.knots[0]) & (t <= self.knots[-1])

    def _gyro_params(self, values):
        return {n.split(".", 1)[1]: values[n] for n in self.param_names}

    def _rates(self, values):
        """Corrected body rates ω_k (K, 3) and ``∂ω_k/∂p`` (K, 3, 18) over param_names.

        ``ω = Mᵀ (G⁻¹ y − b − ḃ (t − t_mid))``: Eq 4-32 inverted, with the bias drifting
        linearly about the middle of the span when the bias-instability effect is in use.
        """
        p = self._gyro_params(values)
        G = g_matrix(p)
        Ginv = np.linalg.inv(G)
        M, dM = model_common.alignment_matrix(p)
        b = np.array([p["bias_x"], p["bias_y"], p["bias_z"]])
        bdot = np.array([p[n] for n in BIAS_RATE_NAMES])
        tau = self.knots[1:] - 0.5 * (self.knots[0] + self.knots[-1])
        u = self.y @ Ginv.T - b - tau[:, None] * bdot                 # G⁻¹ y − b(t)   (K, 3)
        omega = u @ M                                            # Mᵀ u
        K = self.y.shape[0]
        W = np.empty((K, 3, 18))
        Gy = self.y @ Ginv.T                                     # G⁻¹ y
        MtGinv = M.T @ Ginv
        for a in range(3):
            for c in range(3):
                # ∂(G⁻¹)/∂G_ac = −G⁻¹ E_ac G⁻¹  ->  ∂ω = −Mᵀ G⁻¹ e_a (G⁻¹ y)_c
                W[:, :, 3 * a + c] = -MtGinv[:, a][None, :] * Gy[:, c:c + 1]
        W[:, :, 9:12] = -M.T[None, :, :]
        for k in range(3):
            W[:, :, 12 + k] = u @ dM[k]                           # (∂M/∂a_k)ᵀ u
        W[:, :, 15:18] = -M.T[None, :, :] * tau[:, None, None]
        return omega, W

    def _propagate(self, values):
        key = tuple(values[n] for n in self.names)
        if key == self._cache_key:
            return self._cache
        rpy = [values[n] for n in RPY]
        C0 = euler123_to_dcm(*rpy) @ self.ref.reference(self.t_ref)[0]
        omega, W = self._rates(values)
        steps = _step_quaternions(omega, self.dt)
        q0 = quat_from_dcm(C0)
        Qk = quat_multiply(_quat_scan(steps), np.broadcast_to(q0, steps.shape))
        C_knots = np.concatenate([C0[None], quat_to_dcm(Qk)])            # (K+1, 3, 3)
        # E_k = Σ_{j≤k} C_jᵀ W_j Δ_j   (K+1, 3, 15), E_0 = 0
        incr = (np.swapaxes(C_knots[1:], 1, 2) @ W) * self.dt[:, None, None]
        E = np.concatenate([np.zeros((1, 3, W.shape[2])), np.cumsum(incr, axis=0)])
        J0 = rpy_error_jacobian(*rpy)
        self._cache_key, self._cache = key, (C_knots, omega, W, E, C0, J0)
        return self._cache

    def evaluate(self, values: Mapping[str, float], t) -> AttitudeEval:
        t = np.atleast_1d(np.asarray(t, float))
        C_knots, omega, W, E, C0, J0 = self._propagate(values)
        K = omega.shape[0]
        # interval k (1-based) holding t: τ_{k-1} < t ≤ τ_k; t = τ_0 maps to k = 1 with s = 0
        k = np.clip(np.searchsorted(self.knots, t, side="left"), 1, K)
        s = t - self.knots[k - 1]
        w = omega[k - 1]
        C = quat_to_dcm(_step_quaternions(w, s)) @ C_knots[k - 1]
        # C(t)ᵀ δθ(t) = C_0ᵀ δθ_0 + E_{k-1} + C(t)ᵀ W_k s δp
        Jp = C @ E[k - 1] + W[k - 1] * s[:, None, None]
        Ja = C @ (C0.T @ J0)
        return AttitudeEval(C, None, self.names, np.concatenate([Ja, Jp], -1), omega_B=w)
