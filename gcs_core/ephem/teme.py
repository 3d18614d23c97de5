"""TEME, the frame of SGP4, and its relation to GCS's GCI and to J2000 (ICD §2 extension).

SGP4 returns positions in TEME, "true equator, mean equinox" of date. Vallado et al.
(2006, §"Coordinate systems") define it by its Earth rotation: the pseudo-Earth-fixed
frame is ``r_PEF = R3(GMST) r_TEME`` with GMST by the IAU 1982 expression. ICD §2 defines
GCS's GCI the same way: Earth-fixed coordinates are ``R3(GMST) r_GCI`` (IAU 1982, UT1 = UTC,
no precession or nutation). The two definitions coincide, so **a TEME state is a GCI state
without any rotation**; the only approximations are the ICD's own (UT1 = UTC, |ΔUT1| < 0.9 s,
≤ 14 arcsec of Earth rotation, and no polar motion, ≤ 0.5 arcsec, 15 m at the surface).
:func:`teme_to_pef` applies that Earth rotation; ``tests/reference/test_tle_orbit.py`` checks it
against the PEF vector Vallado et al. publish.

A mission whose GCI must be the frame of a J2000 star catalog can ask for J2000 instead
(``[orbit] frame = "j2000"``). The chain, in Vallado's notation (``R3 = T3`` of Eq 4-4)::

    r_TOD  = R3(−E_q) r_TEME,          E_q = Δψ cos ε̄          (equation of the equinoxes,
                                                               geometric term only)
    r_MOD  = R1(−ε̄) R3(Δψ) R1(ε) r_TOD,    ε = ε̄ + Δε         (IAU 1980 nutation)
    r_J2000 = R3(ζ) R2(−θ) R3(z) r_MOD                          (IAU 1976 precession)

``ζ, θ, z`` and ``ε̄`` are Lieske's (1977) polynomials in TT centuries; ``Δψ, Δε`` the
IAU 1980 series (Seidelmann 1982) truncated to its 40 largest terms: the 66 terms left out
are each below 0.6 mas, ≈ 3 mas root-sum-square (0.1 m at 8000 km); the EOP corrections
``δΔψ, δΔε`` (≈ 0.05 arcsec, the celestial-pole offsets) are inputs, zero by default
(J2000 "of FK5" rather than GCRF). TT is UTC + ΔAT + 32.184 s from a leap-second table
from 1999 (before, the 1999 value: a few seconds of TT move precession by < 1e-4 arcsec).

Choosing J2000 puts the spacecraft, in the ICD's Earth rotation, where precession says
it is not: the geomagnetic field is then evaluated 0.31° of longitude away in 2022
(22 years of precession), 53 nT RMS per LVLH component along the ISS orbit (180 nT at
most). That is why GCS keeps TEME unless told.

References
----------
Vallado, D. A., Crawford, P., Hujsak, R., Kelso, T. S., "Revisiting Spacetrack Report #3",
AIAA 2006-6753 (2006), §"Coordinate systems" and Appendix C (the example of the tests).
Vallado, D. A., *Fundamentals of Astrodynamics and Applications*, 4th ed., Microcosm 2013,
§3.7 (IAU-76/FK5 reduction, Eq 3-84..3-90, and TEME, Eq 3-91, 3-92).
Lieske, J. H. et al., "Expressions for the precession quantities based upon the IAU (1976)
system of astronomical constants", Astron. Astrophys. 58, 1–16 (1977).
Seidelmann, P. K., "1980 IAU theory of nutation: the final report of the IAU working group
on nutation", Celestial Mechanics 27, 79–106 (1982).
"""

from __future__ import annotations

from datetime import UTC, datetime

import numpy as np

from gcs_core.ephem import timescale
from gcs_core.frames.rotations import T1, T2, T3
from gcs_core.units import ARCSEC

__all__ = [
    "ORBIT_FRAMES",
    "tt_minus_utc",
    "precession_angles",
    "nutation_angles",
    "teme_to_j2000_matrix",
    "mod_to_teme_matrix",
    "mod_to_j2000_matrix",
    "teme_to_pef",
    "rotate_state",
]

#: GCI frames a TLE orbit can be expressed in (``[orbit] frame``).
ORBIT_FRAMES = ("teme", "j2000")

#: (UTC date from which it holds, TAI − UTC [s]) since 1999.
_LEAP_SECONDS = (
    (datetime(1999, 1, 1, tzinfo=UTC), 32.0),
    (datetime(2006, 1, 1, tzinfo=UTC), 33.0),
    (datetime(2009, 1, 1, tzinfo=UTC), 34.0),
    (datetime(2012, 7, 1, tzinfo=UTC), 35.0),
    (datetime(2015, 7, 1, tzinfo=UTC), 36.0),
    (datetime(2017, 1, 1, tzinfo=UTC), 37.0),
)
_TT_MINUS_TAI = 32.184
_REV = 1296000.0  # arcsec in a revolution

# IAU 1980 nutation, the 40 largest terms (Seidelmann 1982, Table 1): multipliers of the
# Delaunay arguments (l, l', F, D, Ω); Δψ = Σ (A + A'T) sin(arg), Δε = Σ (B + B'T) cos(arg),
# A, B in 0.1 mas.
_NUT80 = np.array(
    [
        # l  l'  F   D  Ω        A       A'       B      B'
        (0, 0, 0, 0, 1, -171996.0, -174.2, 92025.0, 8.9),
        (0, 0, 2, -2, 2, -13187.0, -1.6, 5736.0, -3.1),
        (0, 0, 2, 0, 2, -2274.0, -0.2, 977.0, -0.5),
        (0, 0, 0, 0, 2, 2062.0, 0.2, -895.0, 0.5),
        (0, 1, 0, 0, 0, 1426.0, -3.4, 54.0, -0.1),
        (1, 0, 0, 0, 0, 712.0, 0.1, -7.0, 0.0),
        (0, 1, 2, -2, 2, -517.0, 1.2, 224.0, -0.6),
        (0, 0, 2, 0, 1, -386.0, -0.4, 200.0, 0.0),
        (1, 0, 2, 0, 2, -301.0, 0.0, 129.0, -0.1),
        (0, -1, 2, -2, 2, 217.0, -0.5, -95.0, 0.3),
        (1, 0, 0, -2, 0, -158.0, 0.0, -1.0, 0.0),
        (0, 0, 2, -2, 1, 129.0, 0.1, -70.0, 0.0),
        (-1, 0, 2, 0, 2, 123.0, 0.0, -53.0, 0.0),
        (1, 0, 0, 0, 1, 63.0, 0.1, -33.0, 0.0),
        (0, 0, 0, 2, 0, 63.0, 0.0, -2.0, 0.0),
        (-1, 0, 2, 2, 2, -59.0, 0.0, 26.0, 0.0),
        (-1, 0, 0, 0, 1, -58.0, -0.1, 32.0, 0.0),
        (1, 0, 2, 0, 1, -51.0, 0.0, 27.0, 0.0),
        (2, 0, 0, -2, 0, 48.0, 0.0, 1.0, 0.0),
        (-2, 0, 2, 0, 1, 46.0, 0.0, -24.0, 0.0),
        (0, 0, 2, 2, 2, -38.0, 0.0, 16.0, 0.0),
        (2, 0, 2, 0, 2, -31.0, 0.0, 13.0, 0.0),
        (2, 0, 0, 0, 0, 29.0, 0.0, -1.0, 0.0),
        (1, 0, 2, -2, 2, 29.0, 0.0, -12.0, 0.0),
        (0, 0, 2, 0, 0, 26.0, 0.0, -1.0, 0.0),
        (0, 0, 2, -2, 0, -22.0, 0.0, 0.0, 0.0),
        (-1, 0, 2, 0, 1, 21.0, 0.0, -10.0, 0.0),
        (0, 2, 0, 0, 0, 17.0, -0.1, 0.0, 0.0),
        (0, 2, 2, -2, 2, -16.0, 0.1, 7.0, 0.0),
        (-1, 0, 0, 2, 1, 16.0, 0.0, -8.0, 0.0),
        (0, 1, 0, 0, 1, -15.0, 0.0, 9.0, 0.0),
        (1, 0, 0, -2, 1, -13.0, 0.0, 7.0, 0.0),
        (0, -1, 0, 0, 1, -12.0, 0.0, 6.0, 0.0),
        (2, 0, -2, 0, 0, 11.0, 0.0, 0.0, 0.0),
        (-1, 0, 2, 2, 1, -10.0, 0.0, 5.0, 0.0),
        (1, 0, 2, 2, 2, -8.0, 0.0, 3.0, 0.0),
        (0, -1, 2, 0, 2, -7.0, 0.0, 3.0, 0.0),
        (0, 0, 2, 2, 1, -7.0, 0.0, 3.0, 0.0),
        (1, 1, 0, -2, 0, -7.0, 0.0, 0.0, 0.0),
        (0, 1, 2, 0, 2, 7.0, 0.0, -3.0, 0.0),
    ]
)


def tt_minus_utc(epoch) -> float:
    """TT − UTC [s] at a UTC instant: ΔAT (leap-second table from 1999) + 32.184 s."""
    epoch = timescale.parse_epoch(epoch)
    dat = _LEAP_SECONDS[0][1]
    for since, value in _LEAP_SECONDS:
        if epoch >= since:
            dat = value
    return dat + _TT_MINUS_TAI


def _tt_centuries(epoch, t) -> np.ndarray:
    """Julian centuries of TT since J2000.0 at mission times ``t`` (shape of ``t``)."""
    return (timescale.seconds_since_j2000(epoch, t) + tt_minus_utc(epoch)) / (86400.0 * 36525.0)


def precession_angles(T) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """IAU 1976 precession ``ζ, θ, z`` [rad] at TT centuries ``T`` (Lieske 1977; Vallado Eq 3-87)::

    ζ = 2306.2181″T + 0.30188″T² + 0.017998″T³
    θ = 2004.3109″T − 0.42665″T² − 0.041833″T³
    z = 2306.2181″T + 1.09468″T² + 0.018203″T³
    """
    T = np.asarray(T, dtype=float)
    zeta = (2306.2181 + (0.30188 + 0.017998 * T) * T) * T * ARCSEC
    theta = (2004.3109 - (0.42665 + 0.041833 * T) * T) * T * ARCSEC
    z = (2306.2181 + (1.09468 + 0.018203 * T) * T) * T * ARCSEC
    return zeta, theta, z


def nutation_angles(T, ddpsi: float = 0.0, ddeps: float = 0.0) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """IAU 1980 nutation at TT centuries ``T``: ``(Δψ, Δε, ε̄)`` [rad].

    ``ε̄ = 84381.448″ − 46.8150″T − 0.00059″T² + 0.001813″T³`` (mean obliquity); the
    Delaunay arguments are those of the 1980 theory (Seidelmann 1982), e.g.
    ``Ω = 450160.280″ − (5 rev + 482890.539″)T + 7.455″T² + 0.008″T³``. ``ddpsi, ddeps``
    [rad] are the EOP corrections added to ``Δψ, Δε``. Shapes of ``T``.
    """
    T = np.asarray(T, dtype=float)
    arcsec = np.stack(
        [
            485866.733 + (1325.0 * _REV + 715922.633) * T + (31.310 + 0.064 * T) * T * T,  # l
            1287099.804 + (99.0 * _REV + 1292581.224) * T - (0.577 + 0.012 * T) * T * T,  # l'
            335778.877 + (1342.0 * _REV + 295263.137) * T - (13.257 - 0.011 * T) * T * T,  # F
            1072261.307 + (1236.0 * _REV + 1105601.328) * T - (6.891 - 0.019 * T) * T * T,  # D
            450160.280 - (5.0 * _REV + 482890.539) * T + (7.455 + 0.008 * T) * T * T,  # Ω
        ],
        axis=-1,
    )
    fund = np.mod(arcsec, _REV) * ARCSEC  # (..., 5) rad
    arg = fund @ _NUT80[:, :5].T  # (..., 40)
    unit = 1e-4 * ARCSEC
    Tn = T[..., None]
    dpsi = np.sum((_NUT80[:, 5] + _NUT80[:, 6] * Tn) * np.sin(arg), axis=-1) * unit + ddpsi
    deps = np.sum((_NUT80[:, 7] + _NUT80[:, 8] * Tn) * np.cos(arg), axis=-1) * unit + ddeps
    eps_mean = (84381.448 - (46.8150 + (0.00059 - 0.001813 * T) * T) * T) * ARCSEC
    return dpsi, deps, eps_mean


def _mod_to_tod(T, ddpsi, ddeps):
    """(…, 3, 3) nutation ``N``: ``r_TOD = R1(−ε) R3(−Δψ) R1(ε̄) r_MOD``; also ``E_q``."""
    dpsi, deps, eps_mean = nutation_angles(T, ddpsi, ddeps)
    N = T1(-(eps_mean + deps)) @ T3(-dpsi) @ T1(eps_mean)
    return N, dpsi * np.cos(eps_mean)


def teme_to_j2000_matrix(epoch, t, *, ddpsi: float = 0.0, ddeps: float = 0.0) -> np.ndarray:
    """(N, 3, 3) ``Q`` with ``r_J2000 = Q r_TEME`` at mission times ``t`` (module docstring)::

    Q = Pᵀ Nᵀ R3(−E_q),   P = R3(−z) R2(θ) R3(−ζ)   (J2000 → MOD),   N (MOD → TOD)
    """
    T = np.atleast_1d(_tt_centuries(epoch, t))
    zeta, theta, z = precession_angles(T)
    P = T3(-z) @ T2(theta) @ T3(-zeta)
    N, eq = _mod_to_tod(T, ddpsi, ddeps)
    return np.swapaxes(P, -1, -2) @ np.swapaxes(N, -1, -2) @ T3(-eq)


def mod_to_teme_matrix(epoch, t) -> np.ndarray:
    """(N, 3, 3) ``r_TEME = R3(E_q) N r_MOD``: the analytic Sun (mean of date) into TEME."""
    T = np.atleast_1d(_tt_centuries(epoch, t))
    N, eq = _mod_to_tod(T, 0.0, 0.0)
    return T3(eq) @ N


def mod_to_j2000_matrix(epoch, t) -> np.ndarray:
    """(N, 3, 3) ``r_J2000 = Pᵀ r_MOD`` (IAU 1976 precession undone)."""
    T = np.atleast_1d(_tt_centuries(epoch, t))
    zeta, theta, z = precession_angles(T)
    return np.swapaxes(T3(-z) @ T2(theta) @ T3(-zeta), -1, -2)


def teme_to_pef(epoch, t, r_teme_km, v_teme_km_s=None):
    """The ICD §2 Earth rotation of a TEME state: ``r_PEF = R3(GMST) r_TEME``,
    ``v_PEF = R3(GMST) v_TEME − ω_E × r_PEF`` (GMST IAU 1982, UT1 = UTC, ω_E = 7.292115e-5 rad/s).

    Returns ``r_PEF`` (N, 3), and ``v_PEF`` too when ``v_teme_km_s`` is given.
    """
    R = T3(np.atleast_1d(timescale.gmst_rad(epoch, t)))
    r = np.einsum("nij,nj->ni", R, np.atleast_2d(r_teme_km))
    if v_teme_km_s is None:
        return r
    omega = np.array([0.0, 0.0, 7.292115146706979e-5])
    v = np.einsum("nij,nj->ni", R, np.atleast_2d(v_teme_km_s)) - np.cross(omega, r)
    return r, v


def rotate_state(Q, r, v=None):
    """Apply (N, 3, 3) rotations to (N, 3) vectors (an inertial rotation: ``v`` rotates alike)."""
    r2 = np.einsum("nij,nj->ni", Q, np.atleast_2d(r))
    return r2 if v is None else (r2, np.einsum("nij,nj->ni", Q, np.atleast_2d(v)))
