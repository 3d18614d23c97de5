"""Aberration and parallax: from catalog or geocentric directions to what a sensor sees.

An observer moving with velocity ``v`` (``β = v/c``, ``γ = 1/√(1 − β²)``) sees a source
of true unit direction ``u`` displaced toward its motion (special relativity):

    u' = [u/γ + β + (γ/(1+γ)) (u·β) β] / (1 + u·β)                      (exact)
    u' ≈ normalize(u + β − (u·β) u)                                       (first order)

The displacement is ``|β| sin θ`` ≈ 20.5 arcsec for the Earth's orbital motion (annual
aberration) and up to 5.3 arcsec for a low-Earth-orbit spacecraft's velocity relative to
the geocentre. The first-order form errs by ``~β²`` ≈ 1e-8 rad (0.002 arcsec); GCS uses
the exact form by default.

Who needs what (ICD §4, §5):

- **Stars** (star trackers): catalog J2000 directions are barycentric; the observer moves
  with the Earth's heliocentric velocity (from the ephemeris: ``−ds/dt``; the barycentric
  velocity differs by ~0.013 km/s, 0.01 arcsec) plus the spacecraft's geocentric velocity.
  Stellar parallax (< 1 arcsec) is ignored.
- **Sun** (Sun sensors): the ephemeris gives the *apparent* geocentric Sun, which already
  holds annual aberration and light time for an observer at the geocentre. From the
  spacecraft, add the parallax (``s − r``, up to ~10 arcsec in LEO) and the aberration due
  to the spacecraft's geocentric velocity.

References
----------
Seidelmann, P. K. (ed.), *Explanatory Supplement to the Astronomical Almanac*,
University Science Books 1992, §3.25 (aberration, relativistic formula).
Shuster, M. D., "Stellar aberration and parallax: a tutorial", J. Astronautical
Sciences 51(4), 477–494 (2003).
"""

from __future__ import annotations

import numpy as np

from gcs_core import units

__all__ = [
    "aberrate",
    "apparent_star_direction",
    "sun_from_spacecraft",
    "apparent_sun_from_spacecraft",
    "angle_between",
]


def _unit(v):
    v = np.asarray(v, dtype=float)
    return v / np.linalg.norm(v, axis=-1, keepdims=True)


def aberrate(u_I, v_obs_km_s, *, first_order: bool = False) -> np.ndarray:
    """Apparent unit directions seen by an observer moving at ``v_obs`` (module docstring).

    ``u' = [u/γ + β + (γ/(1+γ))(u·β)β] / (1 + u·β)``, ``β = v/c``.

    Parameters
    ----------
    u_I : (N, 3) or (3,) true directions (normalized here).
    v_obs_km_s : (N, 3) or (3,) observer velocity [km/s] in the same frame.
    first_order : use ``normalize(u + β − (u·β)u)`` instead of the exact form.

    Returns
    -------
    Unit vectors, broadcast shape of the inputs.
    """
    u = _unit(u_I)
    beta = np.asarray(v_obs_km_s, dtype=float) / units.C_KM_S
    ub = np.sum(u * beta, axis=-1, keepdims=True)
    if first_order:
        return _unit(u + beta - ub * u)
    b2 = np.sum(beta * beta, axis=-1, keepdims=True)
    gamma = 1.0 / np.sqrt(1.0 - b2)
    up = (u / gamma + beta + (gamma / (1.0 + gamma)) * ub * beta) / (1.0 + ub)
    return _unit(up)  # exact formula is already unit; normalize against round-off


def apparent_star_direction(u_catalog_I, v_earth_km_s, v_sc_km_s, *, first_order: bool = False) -> np.ndarray:
    """Stellar aberration: a catalog direction as seen from the spacecraft.

    The observer's velocity is the Earth's heliocentric velocity plus the spacecraft's
    geocentric velocity (annual + orbital aberration; their composition differs from a
    plain sum by ``β_E β_sc`` ≈ 3e-9 rad). Shapes (N, 3) → (N, 3).
    """
    v = np.asarray(v_earth_km_s, dtype=float) + np.asarray(v_sc_km_s, dtype=float)
    return aberrate(u_catalog_I, v, first_order=first_order)


def sun_from_spacecraft(sun_I_km, r_I_km) -> np.ndarray:
    """Solar parallax: unit vector from the spacecraft to the Sun, ``(s − r)/|s − r|``. (N, 3)."""
    return _unit(np.asarray(sun_I_km, dtype=float) - np.asarray(r_I_km, dtype=float))


def apparent_sun_from_spacecraft(sun_I_km, r_I_km, v_I_km_s, *, first_order: bool = False) -> np.ndarray:
    """Apparent Sun direction at the spacecraft: parallax, then orbital aberration.

    ``sun_I_km`` is the *apparent geocentric* Sun of the ephemeris (annual aberration
    and light time included, ICD §4), so only the spacecraft's geocentric velocity
    ``v_I_km_s`` is applied here. For a geometric Sun, first aberrate it with the Earth's
    velocity (:func:`aberrate`). Shapes (N, 3) → (N, 3).
    """
    return aberrate(sun_from_spacecraft(sun_I_km, r_I_km), v_I_km_s, first_order=first_order)


def angle_between(u, w) -> np.ndarray:
    """Angle [rad] between direction arrays (robust at small angles: atan2 of |u×w|, u·w)."""
    u, w = _unit(u), _unit(w)
    return np.arctan2(np.linalg.norm(np.cross(u, w), axis=-1), np.sum(u * w, axis=-1))
