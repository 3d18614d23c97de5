"""Named physical amounts and unit conversions.

The engine works in SI angles (rad), km for positions, nT for magnetic fields and
seconds of mission time. Conversions happen at the edges (readers, reports, screens).
Tests use these names as tolerances (``one_arcsecond``) so that a tolerance reads as
a physical amount.
"""

from __future__ import annotations

import math

DEG = math.pi / 180.0
ARCMIN = DEG / 60.0
ARCSEC = DEG / 3600.0
one_arcsecond = ARCSEC
one_degree = DEG

R_EARTH_KM = 6378.137  # ICD §5 horizon: spherical Earth radius [km]
MU_EARTH = 398600.4418  # km^3/s^2, WGS-84
OMEGA_EARTH = 7.292115e-5  # rad/s
AU_KM = 149597870.7  # IAU 2012
C_KM_S = 299792.458  # speed of light [km/s]
SECONDS_PER_DAY = 86400.0

UNIT_SCALE = {
    # display unit -> multiply internal value by this to display it
    "rad": 1.0,
    "deg": 1.0 / DEG,
    "arcsec": 1.0 / ARCSEC,
    "rad/s": 1.0,
    "deg/h": 3600.0 / DEG,
    "arcsec/s": 1.0 / ARCSEC,
    "nT": 1.0,
    "1": 1.0,
    "s": 1.0,
    "km": 1.0,
    "counts": 1.0,
    "1/count": 1.0,
    "rad/count": 1.0,
    "nT/aux": 1.0,
}


def display_scale(unit: str) -> float:
    """Factor from an internal unit to its display unit (1 for units shown as they are)."""
    return UNIT_SCALE.get(unit, 1.0)
