"""Analytic orbits for simulation and prediction, where no ephemeris file exists.

Two models, both with ``state(t) -> (r_I_km, v_I_km_s)`` for seconds ``t`` since the
orbit's ``epoch`` (a UTC datetime):

- :class:`KeplerOrbit`: two-body motion from classical elements, optionally with the
  secular J2 drift of the node, perigee and mean anomaly (first order in J2):

      p = a (1 − e²),  n = √(μ/a³),  k = (3/2) J2 (R_E/p)²
      Ω̇ = −k n cos i
      ω̇ =  k n (2 − (5/2) sin² i)
      Ṁ  = n [1 + k √(1 − e²) (1 − (3/2) sin² i)]

  The velocity is the exact time derivative of the position so produced:
  ``v = v₂(Ṁ/n) + Ω̇ ẑ × r + ω̇ ĥ × r`` (``v₂`` the two-body velocity, ``ĥ`` the orbit
  normal), so that Hermite interpolation of a tabulated orbit stays exact.

- :class:`TleOrbit`: SGP4 from a two-line element set (``sgp4`` package, WGS-72
  constants as the TLE theory requires). SGP4 produces coordinates in TEME (true
  equator, mean equinox of date). GCS treats TEME as its GCI frame. That matches the
  ICD §2 Earth rotation (``R3(GMST)`` with no precession or nutation) exactly. It
  differs from J2000 by precession (~0.33° in 2024) and nutation (< 20 arcsec).

:func:`build_ephemeris` tabulates either orbit together with the analytic Sun of
:mod:`gcs_core.ephem.sun` into an :class:`~gcs_core.ephem.ephemeris.Ephemeris`.

References
----------
Vallado, D. A., *Fundamentals of Astrodynamics and Applications*, 4th ed., Microcosm
2013: Algorithm 2 (KepEqtnE), Algorithm 10 (COE2RV) and ch. 9 (secular J2 rates).
Vallado, D. A., Crawford, P., Hujsak, R., Kelso, T. S., "Revisiting Spacetrack Report #3",
AIAA 2006-6753 (SGP4 and TEME).
"""

from __future__ import annotations

from datetime import datetime

import numpy as np

from gcs_core import units
from gcs_core.ephem import timescale
from gcs_core.ephem.ephemeris import Ephemeris
from gcs_core.ephem.sun import sun_position_km
from gcs_core.errors import InputError

__all__ = ["J2_EARTH", "KeplerOrbit", "TleOrbit", "build_ephemeris", "solve_kepler"]

#: Earth's second zonal harmonic (EGM-96, unnormalized).
J2_EARTH = 1.08262668e-3


def solve_kepler(M, e, *, tol: float = 1e-14, max_iter: int = 50) -> np.ndarray:
    """Eccentric anomaly ``E`` [rad] from ``M = E − e sin E`` (elliptic, ``0 ≤ e < 1``).

    Newton's method from ``E₀ = M + e sin M`` (``E₀ = π`` for ``e > 0.8``), vectorized.
    """
    M = np.asarray(M, dtype=float)
    Mw = np.mod(M + np.pi, 2.0 * np.pi) - np.pi
    E = np.where(e > 0.8, np.pi * np.sign(Mw + 1e-300), Mw + e * np.sin(Mw))
    for _ in range(max_iter):
        f = E - e * np.sin(E) - Mw
        dE = f / (1.0 - e * np.cos(E))
        E = E - dE
        if np.all(np.abs(dE) < tol):
            break
    return E + (M - Mw)


class KeplerOrbit:
    """Two-body orbit from classical elements at ``epoch``, with optional secular J2.

    Parameters
    ----------
    a_km : semi-major axis [km].
    e : eccentricity, ``0 ≤ e < 1``.
    i_deg, raan_deg, argp_deg, mean_anom_deg : inclination, right ascension of the
        ascending node, argument of perigee, mean anomaly at ``epoch`` [deg].
    epoch : UTC instant of the elements (datetime or ISO-8601 text); ``t = 0``.
    j2 : apply the secular J2 drift of Ω, ω and M.
    mu, r_earth_km, j2_value : constants (WGS-84 μ, equatorial radius, EGM-96 J2).
    """

    def __init__(
        self,
        a_km,
        e,
        i_deg,
        raan_deg,
        argp_deg,
        mean_anom_deg,
        epoch,
        j2=True,
        *,
        mu: float = units.MU_EARTH,
        r_earth_km: float = units.R_EARTH_KM,
        j2_value: float = J2_EARTH,
    ):
        if not a_km > 0.0:
            raise InputError(f"semi-major axis must be positive, got {a_km}", key="orbit.a_km")
        if not 0.0 <= e < 1.0:
            raise InputError(f"eccentricity must be in [0, 1), got {e}", key="orbit.e")
        self.a_km, self.e = float(a_km), float(e)
        self.i = np.radians(i_deg)
        self.raan0 = np.radians(raan_deg)
        self.argp0 = np.radians(argp_deg)
        self.M0 = np.radians(mean_anom_deg)
        self.epoch: datetime = timescale.parse_epoch(epoch)
        self.mu = float(mu)
        self.n = np.sqrt(self.mu / self.a_km**3)
        p = self.a_km * (1.0 - self.e**2)
        k = 1.5 * j2_value * (r_earth_km / p) ** 2 if j2 else 0.0
        si2 = np.sin(self.i) ** 2
        self.raan_dot = -k * self.n * np.cos(self.i)
        self.argp_dot = k * self.n * (2.0 - 2.5 * si2)
        self.M_dot = self.n * (1.0 + k * np.sqrt(1.0 - self.e**2) * (1.0 - 1.5 * si2))

    @property
    def period_s(self) -> float:
        """Anomalistic period ``2π/Ṁ`` [s]."""
        return float(2.0 * np.pi / self.M_dot)

    def state(self, t) -> tuple[np.ndarray, np.ndarray]:
        """Position [km] and velocity [km/s] in GCI at ``t`` seconds since ``epoch``. (N, 3) each."""
        t = np.atleast_1d(np.asarray(t, dtype=float))
        e, a = self.e, self.a_km
        M = self.M0 + self.M_dot * t
        raan = self.raan0 + self.raan_dot * t
        argp = self.argp0 + self.argp_dot * t
        E = solve_kepler(M, e)
        cE, sE = np.cos(E), np.sin(E)
        b = a * np.sqrt(1.0 - e * e)
        # perifocal position and two-body velocity (Edot = n / (1 - e cos E))
        x_p, y_p = a * (cE - e), b * sE
        Edot = self.n / (1.0 - e * cE)
        vx_p, vy_p = -a * sE * Edot, b * cE * Edot
        # perifocal -> GCI: R3(-Ω) R1(-i) R3(-ω)
        cO, sO = np.cos(raan), np.sin(raan)
        cw, sw = np.cos(argp), np.sin(argp)
        ci, si = np.cos(self.i), np.sin(self.i)
        # P: unit vector to perigee, Q: 90 deg ahead in the orbit plane (both in GCI)
        P = np.stack([cO * cw - sO * sw * ci, sO * cw + cO * sw * ci, sw * si], -1)
        Q = np.stack([-cO * sw - sO * cw * ci, -sO * sw + cO * cw * ci, cw * si], -1)
        r = x_p[:, None] * P + y_p[:, None] * Q
        v2 = vx_p[:, None] * P + vy_p[:, None] * Q
        # exact derivative with the secular drift: v = v2 Mdot/n + Ωdot z x r + ωdot h x r
        h_hat = np.stack([sO * si * np.ones_like(cw), -cO * si * np.ones_like(cw), np.full_like(cw, ci)], -1)
        z_hat = np.array([0.0, 0.0, 1.0])
        v = v2 * (self.M_dot / self.n) + self.raan_dot * np.cross(z_hat, r) + self.argp_dot * np.cross(h_hat, r)
        return r, v


class TleOrbit:
    """SGP4 orbit from a two-line element set; TEME is used as GCI (module docstring).

    Parameters
    ----------
    line1, line2 : the TLE lines.
    epoch : UTC instant for ``t = 0`` of :meth:`state` (usually the mission epoch; it
        need not equal the TLE's own epoch, which is :attr:`tle_epoch`).
    """

    def __init__(self, line1: str, line2: str, epoch):
        from sgp4.api import Satrec

        try:
            self._sat = Satrec.twoline2rv(line1.strip(), line2.strip())
        except Exception as exc:  # noqa: BLE001 — whatever sgp4 raises, in its own wording, becomes one line
            raise InputError(f"cannot read the two-line elements: {exc}", key="orbit.tle") from None
        if self._sat.error != 0:
            raise InputError(f"SGP4 rejects the two-line elements (error {self._sat.error})", key="orbit.tle")
        self.epoch: datetime = timescale.parse_epoch(epoch)
        self.line1, self.line2 = line1, line2

    @property
    def tle_epoch_jd(self) -> float:
        """Julian date (UTC) of the element set's own epoch."""
        return float(self._sat.jdsatepoch + self._sat.jdsatepochF)

    def state(self, t) -> tuple[np.ndarray, np.ndarray]:
        """Position [km] and velocity [km/s] in TEME (= GCI) at ``t`` seconds since ``epoch``."""
        from sgp4.api import SGP4_ERRORS

        t = np.atleast_1d(np.asarray(t, dtype=float))
        jd, fr = timescale.julian_date_parts(self.epoch, t)
        err, r, v = self._sat.sgp4_array(np.ascontiguousarray(jd), np.ascontiguousarray(fr))
        if np.any(err != 0):
            i = int(np.argmax(err != 0))
            raise InputError(
                f"SGP4 fails at t = {t[i]:.3f} s: {SGP4_ERRORS.get(int(err[i]), 'error ' + str(int(err[i])))}",
                key="orbit.tle",
            )
        return np.asarray(r, dtype=float), np.asarray(v, dtype=float)


def build_ephemeris(
    orbit, epoch, t_start: float, t_end: float, step: float = 30.0, *, source: str | None = None
) -> Ephemeris:
    """Tabulate ``orbit`` and the analytic Sun at ``step`` seconds over ``[t_start, t_end]``.

    Parameters
    ----------
    orbit : :class:`KeplerOrbit`, :class:`TleOrbit`, or any object with ``state(t)`` and
        ``epoch``.
    epoch : mission epoch; ``t_start``/``t_end`` are mission seconds. The orbit is
        evaluated at ``t + (epoch − orbit.epoch)``.
    step : tabulation step [s] (the ICD asks for 60 s or finer); the last row is at
        ``t_end`` exactly.

    Returns
    -------
    :class:`Ephemeris` whose Sun is :func:`gcs_core.ephem.sun.sun_position_km`.
    """
    if not step > 0.0 or not t_end > t_start:
        raise InputError(f"need t_end > t_start and step > 0 (got {t_start}, {t_end}, {step})", key="ephemeris.step")
    epoch = timescale.parse_epoch(epoch)
    n = int(np.ceil((t_end - t_start) / step - 1e-9))
    t = t_start + step * np.arange(n + 1)
    t[-1] = t_end
    orbit_epoch = getattr(orbit, "epoch", epoch)
    shift = (epoch - timescale.parse_epoch(orbit_epoch)).total_seconds()
    r, v = orbit.state(t + shift)
    sun = sun_position_km(timescale.julian_date(epoch, t))
    return Ephemeris(t, r, v, sun, source=source or f"analytic {type(orbit).__name__}")
