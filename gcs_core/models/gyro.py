"""Inertial reference gyro (IRU), seed §4.2.7, Eq 4-32 to 4-38; ICD §5 ``gyro``.

Observation side (gyro calibration, §4.2.7.1)::

    y = G (M ω_B + b),   G = I + ΔG                                 (Eq 4-32, ICD)

``ω_B`` is the body rate averaged over the sample interval, ``M`` the alignment
(``align_1..3``, extended, nominal from ``alignment_deg``), ``b`` the drift-rate bias
(``bias_x/y/z``, data-book ``bias``) and ``ΔG`` the nine deviations ``G_11..G_33`` of the
scale-factor/misalignment matrix from identity (nominal 0). State Eq 4-37:
``(G_ij, b_i)``. Extended: a bias instability ``bias_rate_*`` [rad/s²], the bias drifting
linearly about the middle of the span, ``b(t) = b + ḃ (t − t_mid)``. Partials (after Eq 4-37)::

    ∂y_i/∂G_jk = δ_ij (M ω + b)_k,   ∂y/∂b = G,   ∂y/∂ω = G M,   ∂y/∂a_k = G ∂M/∂a_k ω

``Prediction.d_att`` of this model is ``∂y/∂ω`` (N, 3, 3), hence ``attitude_kind = "rate"``.
The alignment is redundant with the antisymmetric part of ``ΔG``; it is offered only as
an alternative candidate, never together with ``scale_misalignment``.

Noise (:meth:`GyroModel.sigma`): a rate averaged over ``Δt`` carries the angle random
walk ``σ_v/sqrt(Δt)``, the electronic (angle read-out) noise at both ends
``sqrt(2) σ_e/Δt`` and, averaged over the interval, the rate random walk
``σ_u sqrt(Δt/3)``; ``Δt`` defaults to 1 s and the caller passes the median sample
interval when it knows it.

Transition side (§4.2.7.1 and §4.2.7.2), used by the Kalman filter:
:func:`corrected_rate` (Eq 4-32 inverted), :func:`rate_from_quaternions` (Eq 4-33) and
:func:`propagate_quaternion` (Eq 4-38).

References
----------
Wertz (ed.) 1978, §7.8 and §17.1 (gyro models); Farrenkopf, R. L., "Analytic steady-state
accuracy solutions for two common spacecraft attitude estimators", J. Guidance & Control
1(4), 1978 (σ_v, σ_u noise model).
"""

from __future__ import annotations

from collections.abc import Mapping

import numpy as np

from gcs_core.frames.rotations import quat_conjugate, quat_multiply
from gcs_core.models import common
from gcs_core.models.base import Geometry, ObservationModel, ParamSpec, Prediction
from gcs_core.models.gyro_noise import gyro_noise

AXES = ("x", "y", "z")
G_NAMES = tuple(f"G_{i}{j}" for i in range(1, 4) for j in range(1, 4))


def g_matrix(params: Mapping[str, float]) -> np.ndarray:
    """``G = I + ΔG`` (3, 3) from the deviations ``G_11..G_33``."""
    return np.eye(3) + np.array([params[n] for n in G_NAMES], dtype=float).reshape(3, 3)


def corrected_rate(y, params: Mapping[str, float], M=None) -> np.ndarray:
    """Body rate from gyro output, Eq 4-32 inverted: ``ω_B = Mᵀ (G⁻¹ y − b)``.

    Parameters
    ----------
    y : (N, 3) or (3,) gyro output [rad/s].
    params : ``G_11..G_33`` deviations and ``bias_x/y/z`` [rad/s] (missing G_ij are 0).
    M : (3, 3) alignment matrix (orthogonal), or None for identity.

    Returns
    -------
    (N, 3) or (3,) ω_B [rad/s]. G is solved for, not inverted.
    """
    y = np.asarray(y, dtype=float)
    G = np.eye(3) + np.array([params.get(n, 0.0) for n in G_NAMES], dtype=float).reshape(3, 3)
    b = np.array([params.get(f"bias_{ax}", 0.0) for ax in AXES])
    w_S = np.linalg.solve(G, y.reshape(-1, 3).T).T - b  # G⁻¹ y − b
    if M is not None:
        w_S = w_S @ np.asarray(M, dtype=float)  # Mᵀ (·), row form
    return w_S.reshape(y.shape)


def rate_from_quaternions(q_prev, q_next, dt) -> np.ndarray:
    """Average body rate between two attitudes, Eq 4-33.

    ``δq = q(t) ⊗ q*(t − Δt)`` (Eq 4-33a, so that ``C(δq) = C(q_next) C(q_prev)ᵀ``), then
    with ``θ = 2 acos(δq4)`` the rotation angle, ``ω = θ e_δ / (Δt sin(θ/2))`` (Eq 4-33b/c).
    The angle is taken as ``2 atan2(|e_δ|, δq4)`` with ``δq4 ≥ 0`` (robust near θ = 0).

    Shapes: quaternions (N, 4) or (4,), ``dt`` scalar or (N,); returns (N, 3) or (3,) [rad/s].
    """
    dq = quat_multiply(np.asarray(q_next, dtype=float), quat_conjugate(q_prev))
    dq = np.where(dq[..., 3:4] < 0.0, -dq, dq)
    e, q4 = dq[..., :3], dq[..., 3]
    s = np.linalg.norm(e, axis=-1)
    theta = 2.0 * np.arctan2(s, q4)
    small = s < 1e-12
    factor = np.where(small, 2.0, theta / np.where(small, 1.0, s))  # θ/sin(θ/2) → 2 as θ → 0
    return e * (factor / np.asarray(dt, dtype=float))[..., None]


def propagate_quaternion(q, omega, dt) -> np.ndarray:
    """Attitude transition over ``Δt`` at constant body rate, Eq 4-38a/b.

    ``q(t+Δt) = {cos(wΔt/2) I + sin(wΔt/2)/w Ω(ω)} q(t)``, w = |ω|, with
    ``Ω(ω) = [[0, ωz, −ωy, ωx], [−ωz, 0, ωx, ωy], [ωy, −ωx, 0, ωz], [−ωx, −ωy, −ωz, 0]]``
    (Eq 4-38b); computed as the product with the rotation quaternion
    ``(sin(wΔt/2) ω/w, cos(wΔt/2))`` and renormalized against round-off.

    Shapes: ``q`` (N, 4) or (4,), ``omega`` (N, 3) or (3,) [rad/s], ``dt`` scalar or (N,).
    """
    omega = np.asarray(omega, dtype=float)
    half = 0.5 * np.linalg.norm(omega, axis=-1) * np.asarray(dt, dtype=float)
    w = np.linalg.norm(omega, axis=-1)
    small = w < 1e-15
    # sin(wΔt/2)/w, with its limit Δt/2 as w → 0
    sinc = np.where(small, 0.5 * np.asarray(dt, dtype=float), np.sin(half) / np.where(small, 1.0, w))
    dq = np.concatenate([omega * sinc[..., None], np.cos(half)[..., None]], axis=-1)
    out = quat_multiply(dq, np.asarray(q, dtype=float))
    return out / np.linalg.norm(out, axis=-1, keepdims=True)


class GyroModel(ObservationModel):
    """Gyro observation model, Eq 4-32: ``y = G (M ω_B + b)``."""

    type_name = "gyro"
    columns = ("wx", "wy", "wz")
    components = ("wx", "wy", "wz")
    unit = "rad/s"
    attitude_kind = "rate"
    book_keys = ("bias", "arw", "rrw", "electronic")

    def parameters(self) -> tuple[ParamSpec, ...]:
        bias = common.book_vector(self.sensor, "bias", 3, default=(0.0, 0.0, 0.0))
        specs = [
            ParamSpec(
                n,
                "1",
                0.0,
                1e-3,
                seed=True,
                effect="scale_misalignment",
                description=f"deviation of G_{n[2:]} from identity (Eq 4-32)",
            )
            for n in G_NAMES
        ]
        specs += [
            ParamSpec(
                f"bias_{ax}",
                "rad/s",
                float(bias[i]),
                1e-5,
                seed=True,
                effect="bias",
                description=f"drift-rate bias about sensor {ax} (Eq 4-32)",
            )
            for i, ax in enumerate(AXES)
        ]
        specs += common.alignment_specs(self.sensor, seed=False, sigma=1e-3)
        specs += [
            ParamSpec(
                f"bias_rate_{ax}",
                "rad/s2",
                0.0,
                1e-9,
                seed=False,
                effect="bias_instability",
                description=f"bias instability: drift of the {ax} bias per second over the "
                "span (used by the gyro-propagated attitude)",
            )
            for ax in AXES
        ]
        return tuple(specs)

    def sigma(self, dt: float = 1.0) -> np.ndarray:
        """(3,) 1-sigma of a rate averaged over ``dt`` [s] (module docstring; the noise is
        :func:`~gcs_core.models.gyro_noise.gyro_noise`, with its rule for missing keys)."""
        g = gyro_noise(self.sensor, dt)
        var = g.sigma_v**2 / dt + 2.0 * g.sigma_e**2 / dt**2 + g.sigma_u**2 * dt / 3.0
        return np.full(3, np.sqrt(var))

    def predict(self, geom: Geometry, params: Mapping[str, float]) -> Prediction:
        """Eq 4-32 at N frames: y (N, 3) [rad/s], d_att = ∂y/∂ω (N, 3, 3), d_par (N, 3)."""
        specs = self.parameters()
        p = common.merged_params(specs, params)
        if geom.omega_B is None:
            raise ValueError("gyro observation model needs omega_B in the geometry")
        n = geom.n
        omega = (
            common.frames_of(geom.omega_B, n) if np.ndim(geom.omega_B) == 1 else np.asarray(geom.omega_B, dtype=float)
        )
        G = g_matrix(p)
        M, dM = common.alignment_matrix(p)
        b = np.array([p[f"bias_{ax}"] for ax in AXES])
        bdot = np.array([p[f"bias_rate_{ax}"] for ax in AXES])
        t = np.asarray(geom.t, dtype=float)
        tau = t - 0.5 * (t.min() + t.max()) if n else t  # about the middle of the span
        u = omega @ M.T + b + tau[:, None] * bdot  # M ω + b(t)
        y = u @ G.T
        d_par: dict[str, np.ndarray] = {}
        for idx, name in enumerate(G_NAMES):
            i, k = divmod(idx, 3)
            d = np.zeros((n, 3))
            d[:, i] = u[:, k]  # δ_ij (Mω + b)_k
            d_par[name] = d
        for j, ax in enumerate(AXES):
            d_par[f"bias_{ax}"] = np.broadcast_to(G[:, j], (n, 3))
            d_par[f"bias_rate_{ax}"] = G[:, j][None, :] * tau[:, None]
        for k, name in enumerate(common.ALIGN_NAMES):
            d_par[name] = omega @ (G @ dM[k]).T
        d_att = np.broadcast_to(G @ M, (n, 3, 3))
        return common.finish(y, d_att, d_par, np.ones(n, dtype=bool), specs)
