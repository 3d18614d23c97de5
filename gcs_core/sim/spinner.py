"""Spinner sensors: plane-field Sun sensor and Earth horizon scanner (Eq 4-12 to 4-15).

Solved on the true geometry by root finding in time, not with the ICD closed form
(which the tests use as an independent cross-check).

Body frame of a spinner (truth.py): ``z_B = Â``, the body turns right-handed about ``Â``
at ``ω``; a body direction at azimuth ψ (from ``x_B``) has GCI azimuth ``ψ + φ(t)``.

Plane-field Sun sensor ("slit" plane through the spacecraft). Its plane contains the
radial direction ``u = x_B`` and the axis ``w = cos ε_S ẑ − sin ε_S (ẑ × u)``, tilted by
``ε_S`` about ``u``; normal ``n = u × w = (0, −cos ε_S, −sin ε_S)``. The Sun sighting is the
root of ``f(t) = n · C_BI(t) Ŝ(t)`` (going − to +, with ``Ŝ_B · u > 0``), ``Ŝ`` the apparent
unit Sun vector at the spacecraft (parallax and aberration per the mission physics). In that plane
``Ŝ = a u + b w`` and ``Â·Ŝ = b cos ε_S``, so the
angle the sensor reads from ``w`` is ``acos(Ŝ·w) = acos((Â·Ŝ)/cos ε_S)`` (Eq 4-14)::

    β_m = acos(Ŝ_B · w) + Δβ + N(0, noise²)

At the sighting the Sun's body azimuth is ``−asin(cot β tan ε_S) = −ΔΦ_S`` (Eq 4-12d).

Horizon scanner: a pencil beam on the cone of half angle ``γ' = γ + Δγ`` about ``Â``, at
the intersection of that cone with a detector plane through ``u_H`` (body azimuth
``Φ_H + ΔΦ``) tilted by ``ε_H`` like the Sun sensor's: ``w_H = cos ε_H ẑ − sin ε_H (ẑ × u_H)``.
The line of sight is ``d = a u_H + b w_H`` with ``b = cos γ' / cos ε_H``, ``a = sqrt(1 − b²)``;
its azimuth is ``Φ_H + ΔΦ − asin(cot γ' tan ε_H) = Φ_H + ΔΦ − ΔΦ_H`` (Eq 4-12e).

The horizon is the ellipsoid ``(x² + y²)/a_H² + z²/b_H² = 1`` (GCI, the true-of-date pole
taken as the GCI z axis), ``a_H = R_E + h_H``, ``b_H = R_E (1 − f) + h_H``: the WGS-84
flattening ``f`` when the mission physics ``earth_oblateness`` is on (the default, the real
Earth), 0 when off (the ICD's sphere), plus ``m f`` for the hidden ``oblateness`` effect.
The crossings are the roots in time of the beam's angle from the limb, measured in the
vertical plane of the beam (the plane through the spacecraft, the nadir and ``d``)::

    g(t) = ∠(d, Ê) − ρ_T − Δρ

where ``ρ_T`` is the exact nadir angle of the ray in that plane that is tangent to the
ellipsoid. The plane passes through the Earth's centre, so it cuts the ellipsoid in an
ellipse, and the tangent from the spacecraft to it is closed-form: with ``e₁ = r̂``,
``e₂`` the unit vector of ``d`` orthogonal to ``r̂``, ``M = diag(1/a_H², 1/a_H², 1/b_H²)``,
``m_ij = e_iᵀ M e_j``, ``det = m₁₁ m₂₂ − m₁₂²`` and ``K = m₁₁ |r|² − 1``, a ray of nadir angle
θ (towards ``e₂``) touches the ellipse when its quadratic has a double root, i.e. when
``(m₂₂ − |r|² det) tan²θ − 2 m₁₂ tan θ + m₁₁ = 0``, whose positive root is
``tan ρ_T = (m₁₂ − sqrt(det K)) / (m₂₂ − |r|² det)``. The beam misses the Earth exactly when
``g > 0``. No tangent-point or first-order approximation is made (the estimator's model,
``gcs_core.models.horizon``, uses one; this is what checks it). Horizon-in: ``g`` goes + to −;
horizon-out: − to +; both are the first such events within one spin after the sighting.
Rows: ``t = t_s − τ`` (τ the time-tag offset), ``spin_rate = ω(t_s)``,
``dt_in/out = t_in/out − t_s + N(0, noise²)``. Sightings in eclipse, with the Sun within
``beta_limits_deg`` of the spin axis, or when the beam misses the Earth, give no row.

References
----------
Wertz (ed.), *Spacecraft Attitude Determination and Control*, Reidel 1978, §7.1
(slit Sun sensors), §7.2 and §9.4 (horizon scanners, Earth-width and mid-scan).
"""

from __future__ import annotations

import numpy as np

from gcs_core.sim import astro
from gcs_core.sim.config import SensorConfig
from gcs_core.sim.sensors import sun_unit_from_sc

__all__ = ["SunSightings", "PlaneFieldSim", "HorizonSim", "bisect_roots"]

WGS84_F = 1.0 / 298.257223563


def bisect_roots(fun, a, b, fa=None, *, iterations: int = 60):
    """Vectorized bisection: ``fun(t)`` (N,) changes sign on every ``[a, b]``; returns (N,) roots."""
    a = np.asarray(a, dtype=float).copy()
    b = np.asarray(b, dtype=float).copy()
    fa = fun(a) if fa is None else np.asarray(fa, dtype=float).copy()
    for _ in range(iterations):
        m = 0.5 * (a + b)
        fm = fun(m)
        left = np.sign(fm) == np.sign(fa)
        a = np.where(left, m, a)
        fa = np.where(left, fm, fa)
        b = np.where(left, b, m)
        if np.max(b - a, initial=0.0) < 1e-10:
            break
    return 0.5 * (a + b)


class SunSightings:
    """Times when the Sun crosses the plane-field sensor's slit (see module docstring)."""

    def __init__(self, world, sun_sensor: SensorConfig, beta_limits_deg=(5.0, 175.0)):
        self.world = world
        eps = np.radians(float(sun_sensor.value("tilt_deg", 0.0)))
        self.eps = eps
        self.n_B = np.array([0.0, -np.cos(eps), -np.sin(eps)])
        self.w_B = np.array([0.0, -np.sin(eps), np.cos(eps)])
        self.beta_lim = np.radians(np.asarray(beta_limits_deg, dtype=float))
        self._cache: tuple | None = None

    def sun_I(self, t):
        """Apparent unit Sun vector at the spacecraft (mission physics switches), (N, 3)."""
        w = self.world
        r, v = w.orbit(t)
        ph = w.cfg.physics
        return sun_unit_from_sc(
            r,
            v,
            w.sun(t),
            parallax=bool(ph.get("sun_parallax", True)),
            aberration=bool(ph.get("solar_aberration", True)),
        )

    def sun_B(self, t):
        return np.einsum("nij,nj->ni", self.world.attitude(t), self.sun_I(t))

    def _psi_target(self, t):
        """φ(t) at which the sighting happens: Sun spin-frame azimuth minus body azimuth."""
        S = self.sun_I(t) @ self.world.A_spin.T
        psi_I = np.arctan2(S[:, 1], S[:, 0])
        beta = np.arccos(np.clip(S[:, 2], -1, 1))
        x = np.clip(np.tan(self.eps) / np.tan(np.clip(beta, 1e-6, np.pi - 1e-6)), -1, 1)
        return psi_I + np.arcsin(x)  # body azimuth of the Sun = −asin(tan ε cot β)

    def between(self, t0: float, t1: float, t_max: float) -> np.ndarray:
        """Sun-sighting times in ``[t0, min(t1, t_max))``, sorted (cached for the last call)."""
        if self._cache is not None and self._cache[0] == (t0, t1, t_max):
            return self._cache[1]
        w = self.world
        hi = min(t1, t_max)
        if hi <= t0:
            out = np.zeros(0)
        else:
            ph0, ph1 = w.spin_phase(np.array([t0, hi])) - self._psi_target(np.array([t0, hi]))
            k = np.arange(np.floor(ph0 / (2 * np.pi)) - 1, np.ceil(ph1 / (2 * np.pi)) + 2)
            w0 = float(w.spin_rate(np.array([t0]))[0])
            t = t0 + (2 * np.pi * k - ph0) / w0
            for _ in range(4):  # Newton on φ(t) − target(t) ≡ 0 (mod 2π)
                g = w.spin_phase(t) - self._psi_target(t)
                t = t - np.angle(np.exp(1j * g)) / w.spin_rate(t)
            t = np.unique(np.round(t, 6))
            t = t[(t >= t0) & (t < hi)]
            half = 0.02 * 2 * np.pi / w.spin_rate(t)
            f = lambda x: self.sun_B(x) @ self.n_B
            fa, fb = f(t - half), f(t + half)
            good = (fa < 0) & (fb > 0)
            t, half, fa = t[good], half[good], fa[good]
            t = bisect_roots(f, t - half, t + half, fa)
            S_B = self.sun_B(t)
            beta = np.arccos(np.clip(S_B[:, 2], -1, 1))
            r, _ = w.orbit(t)
            keep = (
                (S_B[:, 0] > 0)
                & (beta > self.beta_lim[0])
                & (beta < self.beta_lim[1])
                & ~astro.sun_eclipsed(r, w.sun(t))
            )
            out = t[keep]
        self._cache = ((t0, t1, t_max), out)
        return out


class PlaneFieldSim:
    """Plane-field Sun sensor rows ``t, beta`` [rad] (Eq 4-14), one per spin."""

    columns = ("t", "beta")
    formats = ("%.9f", "%.12g")

    def __init__(self, sensor: SensorConfig, world, rng: np.random.Generator, sightings: SunSightings):
        self.s, self.world, self.rng, self.sightings = sensor, world, rng, sightings
        self.bias = float(sensor.value("bias", 0.0))
        self.noise = float(sensor.value("noise"))
        self.tau = float(sensor.value("time_offset_s", 0.0))

    def run_span(self, t0: float, t1: float, t_max: float) -> dict[str, np.ndarray]:
        ts = self.sightings.between(t0, t1, t_max)
        S_B = self.sightings.sun_B(ts) if ts.size else np.zeros((0, 3))
        beta = np.arccos(np.clip(S_B @ self.sightings.w_B, -1, 1)) + self.bias
        beta = beta + self.rng.standard_normal(beta.shape) * self.noise
        return {"t": ts - self.tau, "beta": beta}


class HorizonSim:
    """Horizon scanner rows ``t, spin_rate, dt_in, dt_out`` (Eq 4-12)."""

    columns = ("t", "spin_rate", "dt_in", "dt_out")
    formats = ("%.9f", "%.12e", "%.9f", "%.9f")
    grid = 240  # samples per spin when looking for crossings (1.5 deg)

    def __init__(self, sensor: SensorConfig, world, rng: np.random.Generator, sightings: SunSightings):
        self.s, self.world, self.rng, self.sightings = sensor, world, rng, sightings
        gamma = np.radians(float(sensor.value("gamma_deg"))) + float(sensor.value("d_gamma", 0.0))
        psi = np.radians(float(sensor.value("phi_h_deg"))) + float(sensor.value("d_phi", 0.0))
        eps_h = float(sensor.value("eps_H", 0.0))
        u = np.array([np.cos(psi), np.sin(psi), 0.0])
        wv = np.cos(eps_h) * np.array([0.0, 0.0, 1.0]) - np.sin(eps_h) * np.cross([0.0, 0.0, 1.0], u)
        b = np.cos(gamma) / np.cos(eps_h)
        self.d_B = np.sqrt(1.0 - b * b) * u + b * wv
        h = float(sensor.value("horizon_height_km"))
        f = WGS84_F if bool(world.cfg.physics.get("earth_oblateness", True)) else 0.0
        f += float(sensor.value("flattening_excess", 0.0)) * WGS84_F
        self.axes = np.array([astro.R_EARTH_KM + h, astro.R_EARTH_KM + h, astro.R_EARTH_KM * (1 - f) + h])
        self._M = 1.0 / self.axes**2
        self.d_rho = float(sensor.value("d_rho", 0.0))
        self.noise = float(sensor.value("noise"))
        self.tau = float(sensor.value("time_offset_s", 0.0))
        self.n_missed = 0

    def los_I(self, t):
        """Scanner line of sight in GCI at times ``t`` (N,): ``C_BIᵀ d_B``, (N, 3)."""
        ph = self.world.spin_phase(t)
        c, s = np.cos(ph), np.sin(ph)
        d = self.d_B
        x = np.stack([c * d[0] - s * d[1], s * d[0] + c * d[1], np.full_like(c, d[2])], -1)
        return x @ self.world.A_spin

    def limb_distance(self, t):
        """``g(t)``: angle of the beam from the Earth limb [rad], negative on the Earth."""
        t = np.asarray(t, dtype=float)
        shape = t.shape
        t = t.ravel()
        r, _ = self.world.orbit(t)
        d = self.los_I(t)
        rn = np.linalg.norm(r, axis=-1)
        e1 = r / rn[:, None]
        c = -np.einsum("ij,ij->i", d, e1)  # cos ∠(d, Ê)
        e2 = d + c[:, None] * e1
        e2 /= np.maximum(np.linalg.norm(e2, axis=-1), 1e-300)[:, None]
        M = self._M
        m11 = np.einsum("ij,j,ij->i", e1, M, e1)
        m12 = np.einsum("ij,j,ij->i", e1, M, e2)
        m22 = np.einsum("ij,j,ij->i", e2, M, e2)
        det = m11 * m22 - m12**2
        K = m11 * rn**2 - 1.0
        rho_t = np.arctan((m12 - np.sqrt(det * np.maximum(K, 0.0))) / (m22 - rn**2 * det))
        g = np.arccos(np.clip(c, -1, 1)) - rho_t - self.d_rho
        return g.reshape(shape)

    def run_span(self, t0: float, t1: float, t_max: float) -> dict[str, np.ndarray]:
        ts = self.sightings.between(t0, t1, t_max)
        out_t, out_w, out_in, out_out = [], [], [], []
        for lo in range(0, ts.size, 400):  # bounded memory
            tb = ts[lo : lo + 400]
            P = 2 * np.pi / self.world.spin_rate(tb)
            frac = np.arange(self.grid + 1) / self.grid
            T = tb[:, None] + P[:, None] * frac[None, :]
            G = self.limb_distance(T)
            neg = G < 0
            enter = ~neg[:, :-1] & neg[:, 1:]
            leave = neg[:, :-1] & ~neg[:, 1:]
            ok = enter.any(axis=1) & leave.any(axis=1)
            self.n_missed += int(np.sum(~ok))
            if not np.any(ok):
                continue
            rows = np.flatnonzero(ok)
            j_in = np.argmax(enter[rows], axis=1)
            j_out = np.argmax(leave[rows], axis=1)
            t_in = bisect_roots(self.limb_distance, T[rows, j_in], T[rows, j_in + 1], G[rows, j_in])
            t_out = bisect_roots(self.limb_distance, T[rows, j_out], T[rows, j_out + 1], G[rows, j_out])
            out_t.append(tb[rows])
            out_w.append(self.world.spin_rate(tb[rows]))
            out_in.append(t_in - tb[rows])
            out_out.append(t_out - tb[rows])
        if not out_t:
            return {c: np.zeros(0) for c in self.columns}
        t_s = np.concatenate(out_t)
        e = self.rng.standard_normal((t_s.size, 2)) * self.noise
        dt_in = np.concatenate(out_in) + e[:, 0]
        dt_out = np.concatenate(out_out) + e[:, 1]
        return {"t": t_s - self.tau, "spin_rate": np.concatenate(out_w), "dt_in": dt_in, "dt_out": dt_out}
