"""Analytic Sun, Earth shadow and Earth occultation of a line of sight.

Where no ephemeris file gives the Sun (simulation, prediction), GCS uses the
low-precision solar series of the *Astronomical Almanac* in the form of Vallado's
Algorithm 29 (SUN). With ``T`` Julian centuries since J2000.0 (UT1 ≈ TDB ≈ UTC here,
well inside the series' accuracy):

    λ_M = 280.460° + 36000.771° T                 mean longitude
    M   = 357.5291092° + 35999.05034° T           mean anomaly
    λ   = λ_M + 1.914666471° sin M + 0.019994643° sin 2M      ecliptic longitude
    r   = 1.000140612 − 0.016708617 cos M − 0.000139589 cos 2M   [AU]
    ε   = 23.439291° − 0.0130042° T               obliquity of the ecliptic
    r_☉ = r (cos λ, cos ε sin λ, sin ε sin λ)    mean equator and equinox of date

The stated accuracy is 0.01° in direction, valid 1950–2050. The frame is the mean
equator and equinox *of date*. GCS uses it as the GCI Sun only where no ephemeris file
exists (simulation, prediction). That frame is consistent with the ICD §2 Earth rotation
(``R3(GMST)`` with no precession or nutation) and with SGP4's TEME to within nutation
(< 20 arcsec). It is *not* J2000: in 2024 the equinoxes differ by about 0.33°. A
simulation that mixes this Sun with J2000 star catalogs is self-consistent (the
simulated ephemeris carries the same Sun the sensors see) but places the Sun 0.33° off
its J2000 position. Calibration always uses the ephemeris file's Sun.

References
----------
Vallado, D. A., *Fundamentals of Astrodynamics and Applications*, 4th ed., Microcosm
2013, §5.1.1, Algorithm 29 and Example 5-1.
*The Astronomical Almanac*, U.S. Naval Observatory / H.M. Nautical Almanac Office,
section C ("Low precision formulas for the Sun").
Montenbruck, O., Gill, E., *Satellite Orbits*, Springer 2000, §3.4.2 (conical shadow,
fraction of the solar disk visible).
"""

from __future__ import annotations

import numpy as np

from gcs_core import units
from gcs_core.ephem.timescale import julian_date

__all__ = [
    "SUN_RADIUS_KM",
    "sun_position_km",
    "sun_position_at",
    "in_shadow",
    "sunlit_fraction",
    "earth_occults",
    "earth_angular_radius",
]

#: Solar radius [km] (IAU 2015 nominal).
SUN_RADIUS_KM = 695700.0


def sun_position_km(jd) -> np.ndarray:
    """Geocentric Sun position [km], mean equator of date, by Vallado Algorithm 29.

    Parameters
    ----------
    jd : (N,) or scalar Julian date (UT1; UTC is within the series' accuracy).

    Returns
    -------
    (N, 3) array (``(3,)`` for a scalar ``jd``) in km, using the IAU 2012 astronomical unit.
    """
    jd = np.asarray(jd, dtype=float)
    T = (jd - 2451545.0) / 36525.0
    deg = units.DEG
    lam_m = np.mod(280.460 + 36000.771 * T, 360.0) * deg
    M = np.mod(357.5291092 + 35999.05034 * T, 360.0) * deg
    lam = lam_m + (1.914666471 * np.sin(M) + 0.019994643 * np.sin(2.0 * M)) * deg
    r_au = 1.000140612 - 0.016708617 * np.cos(M) - 0.000139589 * np.cos(2.0 * M)
    eps = (23.439291 - 0.0130042 * T) * deg
    r = r_au * units.AU_KM
    return np.stack([r * np.cos(lam), r * np.cos(eps) * np.sin(lam), r * np.sin(eps) * np.sin(lam)], axis=-1)


def sun_position_at(epoch, t) -> np.ndarray:
    """:func:`sun_position_km` at mission times ``t`` [s] since ``epoch``. (N, 3) km."""
    return sun_position_km(julian_date(epoch, t))


def _norm(v):
    return np.linalg.norm(v, axis=-1)


def earth_angular_radius(r_I_km, *, radius_km: float = units.R_EARTH_KM) -> np.ndarray:
    """Apparent angular radius of the Earth seen from ``r``: ``ρ = asin(R/|r|)`` [rad]. (N,)."""
    r = np.asarray(r_I_km, dtype=float)
    return np.arcsin(np.clip(radius_km / _norm(r), -1.0, 1.0))


def in_shadow(r_I_km, sun_I_km, *, model: str = "conical", radius_km: float = units.R_EARTH_KM) -> np.ndarray:
    """True where the spacecraft is in the Earth's shadow.

    ``"cylindrical"``: behind the Earth (``r·ŝ < 0``) and within ``R`` of the Earth–Sun
    line. ``"conical"``: the centre of the solar disk is hidden, i.e. the angle between
    the directions to the Earth's centre and to the Sun's centre, seen from the
    spacecraft, is less than the Earth's apparent radius ``asin(R/|r|)``. The conical
    test switches at mid-penumbra; :func:`sunlit_fraction` gives the penumbral fraction.

    Parameters
    ----------
    r_I_km : (N, 3) spacecraft position [km].
    sun_I_km : (N, 3) or (3,) geocentric Sun position [km].

    Returns
    -------
    (N,) bool.
    """
    r = np.asarray(r_I_km, dtype=float)
    s = np.asarray(sun_I_km, dtype=float)
    if model == "cylindrical":
        s_hat = s / _norm(s)[..., None]
        along = np.sum(r * s_hat, axis=-1)
        perp = _norm(r - along[..., None] * s_hat)
        return (along < 0.0) & (perp < radius_km)
    if model == "conical":
        to_sun = s - r
        cosang = np.sum(-r * to_sun, axis=-1) / (_norm(r) * _norm(to_sun))
        ang = np.arccos(np.clip(cosang, -1.0, 1.0))
        return ang < earth_angular_radius(r, radius_km=radius_km)
    raise ValueError(f"unknown shadow model {model!r} (use 'cylindrical' or 'conical')")


def sunlit_fraction(r_I_km, sun_I_km, *, radius_km: float = units.R_EARTH_KM) -> np.ndarray:
    """Fraction of the solar disk visible from the spacecraft (1 sunlit, 0 umbra). (N,).

    Both bodies are taken as disks of apparent radii ``a = asin(R_☉/|s − r|)`` and
    ``b = asin(R/|r|)`` whose centres are ``c`` apart; the hidden part is the area of the
    disks' overlap (Montenbruck & Gill 2000, §3.4.2):
    ``A = a² acos(x/a) + b² acos((c − x)/b) − c y``, ``x = (c² + a² − b²)/(2c)``,
    ``y = √(a² − x²)``, visible fraction ``1 − A/(π a²)``.
    """
    r = np.asarray(r_I_km, dtype=float)
    s = np.asarray(sun_I_km, dtype=float)
    to_sun = s - r
    d_sun = _norm(to_sun)
    a = np.arcsin(np.clip(SUN_RADIUS_KM / d_sun, -1.0, 1.0))
    b = np.arcsin(np.clip(radius_km / _norm(r), -1.0, 1.0))
    cosc = np.sum(-r * to_sun, axis=-1) / (_norm(r) * d_sun)
    c = np.arccos(np.clip(cosc, -1.0, 1.0))
    a, b, c = np.broadcast_arrays(a, b, c)
    frac = np.ones_like(c)
    full = c <= b - a  # Sun entirely behind the Earth disk
    frac[full] = 0.0
    annular = c <= a - b  # Earth disk smaller than and inside the Sun disk
    frac[annular] = 1.0 - (b[annular] / a[annular]) ** 2
    part = (c < a + b) & ~full & ~annular
    if np.any(part):
        ap, bp, cp = a[part], b[part], c[part]
        x = (cp**2 + ap**2 - bp**2) / (2.0 * cp)
        y = np.sqrt(np.clip(ap**2 - x**2, 0.0, None))
        area = (
            ap**2 * np.arccos(np.clip(x / ap, -1.0, 1.0))
            + bp**2 * np.arccos(np.clip((cp - x) / bp, -1.0, 1.0))
            - cp * y
        )
        frac[part] = 1.0 - area / (np.pi * ap**2)
    return np.clip(frac, 0.0, 1.0)


def earth_occults(r_I_km, los_I, margin_rad: float = 0.0, *, radius_km: float = units.R_EARTH_KM) -> np.ndarray:
    """True where the line of sight ``los`` from the spacecraft hits the Earth disk + margin.

    The Earth, a sphere of ``radius_km`` (raise it to include the atmosphere), subtends
    ``ρ = asin(R/|r|)`` about nadir ``−r/|r|``; the line of sight is blocked when its angle
    to nadir is below ``ρ + margin_rad``.

    Parameters
    ----------
    r_I_km : (N, 3) spacecraft position [km] (or (3,)).
    los_I : (N, 3) or (3,) line-of-sight vectors in GCI (need not be unit).
    margin_rad : exclusion margin around the limb [rad] (e.g. a star tracker's Earth
        exclusion angle).

    Returns
    -------
    (N,) bool.
    """
    r = np.asarray(r_I_km, dtype=float)
    los = np.asarray(los_I, dtype=float)
    nadir = -r / _norm(r)[..., None]
    cosang = np.sum(nadir * los, axis=-1) / _norm(los)
    ang = np.arccos(np.clip(cosang, -1.0, 1.0))
    return ang < earth_angular_radius(r, radius_km=radius_km) + margin_rad
