"""True orbit, attitude, body rates, gyro and onboard attitude of a simulated mission.

Three-axis attitude (Eq 4-4, 4-6, 4-7; ICD §2)::

    C_BI(t) = T3(ψ(t)) T2(θ(t)) T1(φ(t)) A(t)

with ``A`` the GCI-to-reference matrix whose rows are the reference axes:
``inertial`` ``A = I``; ``earth_pointing`` ``z_R = −r̂, y_R = −(r×v)/|r×v|, x_R = y_R×z_R``;
``sun_pointing`` ``x_R = ŝ, y_R = (ẑ×x_R)/|ẑ×x_R|, z_R = x_R×y_R`` (ŝ geocentric).
Roll, pitch, yaw follow :class:`~gcs_core.sim.config.ThreeAxisProfile` (initial values,
drift, slow sinusoids, and constant-rate slews, Eq 4-36, with raised-cosine ramps so
that body rates are continuous).

Spinner: ``C_BI(t) = T3(φ(t)) A_s`` with ``z`` of ``A_s`` the spin axis ``Â`` (Eq 4-2).

Body rates: ``dC/dt = −[ω_B×] C``. The rate averaged over ``[t − Δ, t]`` is taken from
the attitude change itself (Eq 4-33)::

    C(t) C(t − Δ)ᵀ = exp(−[φ×]),   ω̄ = φ / Δ,   |φ| = 2 acos(q4)

Gyro (Eq 4-32, ICD §5 gyro) with the Farrenkopf noise model, per row ``k`` covering
``[t_{k−1}, t_k]`` of length ``Δ``::

    b_k = b_{k−1} + σ_u sqrt(Δ) N(0, I)                      (rate random walk)
    y_k = G (M ω̄_k + (b_{k−1} + b_k)/2) + sqrt(σ_v²/Δ + σ_u² Δ/12) N(0, I)
          + (e_k − e_{k−1}) / Δ,   e ~ N(0, σ_e² I)          (optional electronic noise)

plus, with a heater (``heater_step``, :mod:`gcs_core.sim.drifts`), ``G Δb h_k`` with ``h_k``
the heater's state over the row's interval (it switches on the 1 s aux grid).

Onboard attitude: ``C_ob = exp(−[δ×]) exp(−[n×]) C_true``, δ the injected constant error,
``n`` white noise.

References
----------
Farrenkopf, R. L., "Analytic steady-state accuracy solutions for two common spacecraft
attitude estimators", J. Guidance & Control 1(4), 1978.
Crassidis, J. L. and Junkins, J. L., *Optimal Estimation of Dynamic Systems*, 2nd ed.,
§7.2.5 (discrete gyro simulation).
"""

from __future__ import annotations

import numpy as np

from gcs_core.sim import astro, drifts, orbit
from gcs_core.sim._rot import dcm_to_quat, dcm_to_rotvec, rot3, rotvec_to_dcm, rpy_to_dcm, unit
from gcs_core.sim.config import MissionConfig, SensorConfig, SpinProfile, ThreeAxisProfile

__all__ = ["World", "slew_angle", "GyroSim", "onboard_quaternions"]

_AXIS = {"roll": 0, "pitch": 1, "yaw": 2}


def slew_angle(tau, duration: float, ramp: float) -> np.ndarray:
    """∫ of the unit rate profile over ``[0, τ]`` (raised-cosine ramps of length ``ramp``).

    Ramp-up integral ``τ/2 − (R/2π) sin(πτ/R)``; plateau adds ``τ − R``; the ramp-down
    mirrors the ramp-up; the total is ``D − R``.
    """
    tau = np.clip(np.asarray(tau, dtype=float), 0.0, duration)
    R = min(ramp, 0.5 * duration)
    if R <= 0:
        return tau

    def up(x):
        return x / 2.0 - (R / (2 * np.pi)) * np.sin(np.pi * x / R)

    total = duration - R
    return np.where(tau <= R, up(tau), np.where(tau <= duration - R, R / 2.0 + (tau - R), total - up(duration - tau)))


class World:
    """Truth environment of one mission: orbit, Sun, attitude, at any times.

    All methods take mission times ``t`` (N,) and return arrays with a leading N axis.
    """

    def __init__(self, cfg: MissionConfig):
        self.cfg = cfg
        self.epoch = astro.parse_epoch(cfg.epoch)
        self.jd0 = astro.epoch_jd(self.epoch)
        if cfg.spinning:
            sp = cfg.attitude
            assert isinstance(sp, SpinProfile)
            ra, dec = np.radians(sp.ra_deg), np.radians(sp.dec_deg)
            self.spin_axis_I = np.array([np.cos(ra) * np.cos(dec), np.sin(ra) * np.cos(dec), np.sin(dec)])
            x0 = np.cross([0.0, 0.0, 1.0], self.spin_axis_I)
            if np.linalg.norm(x0) < 1e-6:
                x0 = np.array([1.0, 0.0, 0.0])
            x0 = unit(x0)
            self.A_spin = np.stack([x0, np.cross(self.spin_axis_I, x0), self.spin_axis_I])

    # --- environment -------------------------------------------------------------
    def orbit(self, t):
        """``(r_I_km, v_I_km_s)``, each (N, 3)."""
        return orbit.propagate(self.cfg.orbit, t)

    def sun(self, t):
        """Apparent geocentric Sun position [km], (N, 3)."""
        return astro.sun_position_km(self.jd0, t)

    def reference(self, t, r=None, v=None, s=None) -> np.ndarray:
        """GCI-to-reference matrix ``A(t)`` (Eq 4-7), (N, 3, 3)."""
        t = np.atleast_1d(np.asarray(t, dtype=float))
        mode = self.cfg.attitude_mode
        if mode == "inertial":
            return np.broadcast_to(np.eye(3), (t.size, 3, 3)).copy()
        if mode == "earth_pointing":
            if r is None or v is None:
                r, v = self.orbit(t)
            z = -unit(r)
            y = -unit(np.cross(r, v))
            x = np.cross(y, z)
            return np.stack([x, y, z], axis=-2)
        if mode == "sun_pointing":
            if s is None:
                s = self.sun(t)
            x = unit(s)
            y = unit(np.cross(np.array([0.0, 0.0, 1.0]), x))
            z = np.cross(x, y)
            return np.stack([x, y, z], axis=-2)
        raise ValueError(f"no reference frame for mode {mode}")

    # --- attitude --------------------------------------------------------------------
    def rpy(self, t) -> np.ndarray:
        """Roll, pitch, yaw [rad] of the three-axis profile, (N, 3)."""
        p = self.cfg.attitude
        assert isinstance(p, ThreeAxisProfile)
        t = np.atleast_1d(np.asarray(t, dtype=float))
        out = (
            np.radians(np.asarray(p.rpy0_deg, dtype=float))[None, :]
            + np.radians(np.asarray(p.drift_deg_s, dtype=float))[None, :] * t[:, None]
        )
        amp = np.radians(np.asarray(p.wobble_amp_deg, dtype=float))
        per = np.asarray(p.wobble_period_s, dtype=float)
        ph = np.asarray(p.wobble_phase_rad, dtype=float)
        out = out + amp[None, :] * np.sin(2 * np.pi * t[:, None] / per[None, :] + ph[None, :])
        for sl in p.slews:
            k = _AXIS[sl.axis]
            out[:, k] += np.radians(sl.rate_deg_s) * slew_angle(t - sl.t_start, sl.duration_s, sl.ramp_s)
        return out

    def spin_phase(self, t) -> np.ndarray:
        """Spin phase ``φ(t) = φ0 + ω t + ω̇ t²/2`` [rad], (N,)."""
        sp = self.cfg.attitude
        assert isinstance(sp, SpinProfile)
        t = np.asarray(t, dtype=float)
        w0 = sp.rate_rpm * 2 * np.pi / 60.0
        return np.radians(sp.phase0_deg) + w0 * t + 0.5 * sp.rate_dot_rad_s2 * t * t

    def spin_rate(self, t) -> np.ndarray:
        """Instantaneous spin rate ``ω(t)`` [rad/s], (N,)."""
        sp = self.cfg.attitude
        assert isinstance(sp, SpinProfile)
        return sp.rate_rpm * 2 * np.pi / 60.0 + sp.rate_dot_rad_s2 * np.asarray(t, dtype=float)

    def attitude(self, t, r=None, v=None, s=None) -> np.ndarray:
        """True ``C_BI(t)``, (N, 3, 3)."""
        t = np.atleast_1d(np.asarray(t, dtype=float))
        if self.cfg.spinning:
            return rot3(self.spin_phase(t)) @ self.A_spin
        a = self.rpy(t)
        return rpy_to_dcm(a[:, 0], a[:, 1], a[:, 2]) @ self.reference(t, r, v, s)

    def omega_avg(self, t_start, t_end) -> np.ndarray:
        """Body rate averaged over ``[t_start, t_end]`` from the attitude change (Eq 4-33), (N, 3)."""
        t_start = np.atleast_1d(np.asarray(t_start, dtype=float))
        t_end = np.atleast_1d(np.asarray(t_end, dtype=float))
        C0, C1 = self.attitude(t_start), self.attitude(t_end)
        phi = dcm_to_rotvec(C1 @ np.swapaxes(C0, -1, -2))
        return phi / (t_end - t_start)[:, None]

    def omega_body(self, t, h: float = 0.02) -> np.ndarray:
        """Instantaneous body rate ``ω_B(t)`` [rad/s] (central difference of Eq 4-33), (N, 3)."""
        t = np.atleast_1d(np.asarray(t, dtype=float))
        return self.omega_avg(t - h, t + h)


class GyroSim:
    """Gyro rows per ICD §5 ``gyro`` (see module docstring). Stateful across chunks."""

    columns = ("t", "wx", "wy", "wz")
    formats = ("%.12e",) * 4

    def __init__(self, sensor: SensorConfig, world: World, rng: np.random.Generator, aux=None):
        self.s, self.world, self.aux = sensor, world, aux
        # Separate streams for noise, bias walk and electronic noise: the files do not depend
        # on how the span is chunked.
        self.rng, self.rng_walk, self.rng_e = (np.random.default_rng(x) for x in rng.integers(2**62, size=3))
        a = np.radians(np.asarray(sensor.value("alignment_deg", (0.0, 0.0, 0.0)), dtype=float))
        self.M = rpy_to_dcm(a[0], a[1], a[2])
        self.G = np.asarray(sensor.value("G", np.eye(3)), dtype=float)
        self.arw = float(sensor.value("arw", 0.0))
        self.rrw = float(sensor.value("rrw", 0.0))
        self.sig_e = float(sensor.value("electronic", 0.0) or 0.0)
        self.tau = float(sensor.value("time_offset_s", 0.0))
        self.bias = np.asarray(sensor.value("bias", (0.0, 0.0, 0.0)), dtype=float).copy()
        # a deterministic linear drift of the bias (hidden effect ``bias_instability``)
        self.bias_rate = np.asarray(sensor.value("bias_rate", (0.0, 0.0, 0.0)), dtype=float)
        self.e_prev = self.rng_e.standard_normal(3) * self.sig_e
        self.bias_log: list[tuple[float, list[float]]] = [(0.0, self.bias.tolist())]

    def run(self, t_rows: np.ndarray) -> dict[str, np.ndarray]:
        """Measurements at rows ``t_rows`` (each covering the previous ``cadence_s``)."""
        n = t_rows.size
        if n == 0:
            return {c: np.zeros(0) for c in self.columns}
        dt = float(self.s.cadence_s)
        w_avg = self.world.omega_avg(t_rows - dt + self.tau, t_rows + self.tau)
        steps = self.rng_walk.standard_normal((n, 3)) * self.rrw * np.sqrt(dt)
        b_end = self.bias + np.cumsum(steps, axis=0)
        b_start = np.vstack([self.bias[None, :], b_end[:-1]])
        sig = np.sqrt(self.arw**2 / dt + self.rrw**2 * dt / 12.0)
        noise = self.rng.standard_normal((n, 3)) * sig
        if self.sig_e > 0:
            e = self.rng_e.standard_normal((n, 3)) * self.sig_e
            e_prev = np.vstack([self.e_prev[None, :], e[:-1]])
            noise = noise + (e - e_prev) / dt
            self.e_prev = e[-1]
        drift = self.bias_rate[None, :] * (t_rows - 0.5 * dt)[:, None]  # its interval mean
        step = drifts.heater_step(self.s, self.aux, t_rows - 0.5 * dt)  # held over the row's interval
        if step is not None:
            drift = drift + step
        y = (w_avg @ self.M.T + 0.5 * (b_start + b_end) + drift) @ self.G.T + noise
        self.bias = b_end[-1].copy()
        every = max(1, int(round(60.0 / dt)))  # the true bias once a minute
        for k in range(every - 1, n, every):
            self.bias_log.append((float(t_rows[k]), (b_end[k] + self.bias_rate * t_rows[k]).tolist()))
        return {"t": t_rows, "wx": y[:, 0], "wy": y[:, 1], "wz": y[:, 2]}


def onboard_quaternions(
    world: World, t: np.ndarray, error_deg, noise_arcsec: float, rng: np.random.Generator
) -> np.ndarray:
    """Onboard body-from-GCI quaternions (q4 ≥ 0) at times ``t``, (N, 4)."""
    C = world.attitude(t)
    n = rng.standard_normal((t.size, 3)) * np.radians(noise_arcsec / 3600.0)
    E = rotvec_to_dcm(np.radians(np.asarray(error_deg, dtype=float)))
    C_ob = E[None, :, :] @ rotvec_to_dcm(n) @ C
    return dcm_to_quat(C_ob)
