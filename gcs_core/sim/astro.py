"""Time, Earth rotation, Sun and shadow for the truth simulator (ICD §2, §4).

Independent of :mod:`gcs_core.ephem`: a shared bug must not hide.

Time
----
Mission time ``t`` [s] counts from the UTC epoch of mission.toml; UT1 = UTC (ICD §2).
``JD(t) = JD_epoch + t / 86400`` with ``JD_epoch = 2440587.5 + unix_seconds / 86400``.

GMST (IAU 1982, Aoki et al. 1982), ``T_u = (JD_UT1 − 2451545.0) / 36525``::

    GMST [s] = 67310.54841 + (876600 h + 8640184.812866) T_u + 0.093104 T_u² − 6.2e-6 T_u³

taken modulo one day and turned into an angle; Earth-fixed is ``r_E = T3(GMST) r_GCI``.

Sun (low-precision formulae of the Astronomical Almanac, section C, ~0.01° 1950-2050),
``n = JD − 2451545.0``, angles in degrees::

    L = 280.460 + 0.9856474 n          (mean longitude, aberration included)
    g = 357.528 + 0.9856003 n          (mean anomaly)
    λ = L + 1.915 sin g + 0.020 sin 2g (apparent ecliptic longitude)
    ε = 23.439 − 0.0000004 n           (obliquity)
    R = 1.00014 − 0.01671 cos g − 0.00014 cos 2g   [AU]
    s = R (cos λ, cos ε sin λ, sin ε sin λ)

The Earth's heliocentric velocity (stellar aberration) is ``v_E = −ds/dt``.

Shadow: conical Earth shadow; the Sun counts as eclipsed as soon as any of its disk
is hidden (penumbra included), i.e. when the angle between the Sun and the Earth centre
seen from the spacecraft is below ``asin(R_sun/|s−r|) + asin(R_E/|r|)``.

References
----------
Aoki, S. et al., "The new definition of universal time", A&A 105, 359 (1982).
The Astronomical Almanac, "Low precision formulas for the Sun", section C.
Wertz (ed.), *Spacecraft Attitude Determination and Control*, Reidel 1978, §3.3 (eclipses).
"""

from __future__ import annotations

from datetime import UTC, datetime

import numpy as np

from gcs_core.errors import InputError

AU_KM = 149597870.7
R_EARTH_KM = 6378.137
R_SUN_KM = 695700.0
C_KM_S = 299792.458
J2000_JD = 2451545.0

__all__ = [
    "parse_epoch",
    "epoch_jd",
    "gmst_rad",
    "sun_position_km",
    "earth_velocity_km_s",
    "sun_eclipsed",
    "AU_KM",
    "R_EARTH_KM",
    "C_KM_S",
]


def parse_epoch(text: str) -> datetime:
    """UTC datetime from an ISO string such as ``2024-03-20T06:00:00Z``."""
    try:
        dt = datetime.fromisoformat(text.replace("Z", "+00:00"))
    except ValueError as exc:
        raise InputError(f"bad epoch '{text}': {exc}", key="mission.epoch") from None
    if dt.tzinfo is None:
        dt = dt.replace(tzinfo=UTC)
    return dt.astimezone(UTC)


def epoch_jd(epoch: datetime) -> float:
    """Julian date (UTC) of the epoch."""
    return 2440587.5 + epoch.timestamp() / 86400.0


def _days_since_j2000(jd0: float, t) -> np.ndarray:
    # Subtract the big numbers first to keep sub-millisecond resolution.
    return (jd0 - J2000_JD) + np.asarray(t, dtype=float) / 86400.0


def gmst_rad(jd0: float, t) -> np.ndarray:
    """IAU 1982 GMST [rad] at mission times ``t`` (N,), UT1 = UTC."""
    d = _days_since_j2000(jd0, t)
    T = d / 36525.0
    # Split the day fraction out so the big linear term does not eat precision:
    # 876600 h * T = 86400 s * d exactly (one sidereal turn per solar day term).
    secs = 67310.54841 + 8640184.812866 * T + 0.093104 * T**2 - 6.2e-6 * T**3
    secs = secs + 86400.0 * np.mod(d, 1.0)
    return np.mod(secs, 86400.0) * (2.0 * np.pi / 86400.0)


def sun_position_km(jd0: float, t) -> np.ndarray:
    """Apparent geocentric Sun position in GCI [km], shape (N, 3)."""
    n = _days_since_j2000(jd0, t)
    rad = np.pi / 180.0
    L = 280.460 + 0.9856474 * n
    g = (357.528 + 0.9856003 * n) * rad
    lam = (L + 1.915 * np.sin(g) + 0.020 * np.sin(2 * g)) * rad
    eps = (23.439 - 0.0000004 * n) * rad
    R = (1.00014 - 0.01671 * np.cos(g) - 0.00014 * np.cos(2 * g)) * AU_KM
    return np.stack([R * np.cos(lam), R * np.cos(eps) * np.sin(lam), R * np.sin(eps) * np.sin(lam)], axis=-1)


def earth_velocity_km_s(jd0: float, t) -> np.ndarray:
    """Heliocentric velocity of the Earth in GCI [km/s], ``−ds/dt`` by central difference."""
    t = np.asarray(t, dtype=float)
    h = 60.0
    return -(sun_position_km(jd0, t + h) - sun_position_km(jd0, t - h)) / (2 * h)


def sun_eclipsed(r_I_km, s_I_km) -> np.ndarray:
    """True where any part of the solar disk is hidden by the Earth (conical shadow)."""
    r = np.asarray(r_I_km, dtype=float)
    s_rel = np.asarray(s_I_km, dtype=float) - r
    d_sun = np.linalg.norm(s_rel, axis=-1)
    d_earth = np.linalg.norm(r, axis=-1)
    cos_sep = np.einsum("ij,ij->i", s_rel, -r) / (d_sun * d_earth)
    sep = np.arccos(np.clip(cos_sep, -1.0, 1.0))
    return sep < np.arcsin(R_SUN_KM / d_sun) + np.arcsin(np.clip(R_EARTH_KM / d_earth, 0, 1))
