"""Time, ephemeris, Sun, geomagnetic field and light corrections (ICD §2, §4).

- :mod:`.timescale` — epoch parsing, Julian dates, GMST (IAU 1982), decimal years.
- :mod:`.ephemeris` — :class:`Ephemeris`, Hermite interpolation of ephemeris.csv.
- :mod:`.geomag` — :class:`GeomagField`, IGRF-13/14 in GCI.
- :mod:`.sun` — analytic Sun, Earth shadow, Earth occultation of a line of sight.
- :mod:`.orbit` — :class:`KeplerOrbit`, :class:`TleOrbit`, :func:`build_ephemeris`.
- :mod:`.corrections` — aberration and parallax.
"""

from gcs_core.ephem.ephemeris import EPHEMERIS_COLUMNS, Ephemeris
from gcs_core.ephem.geomag import GeomagField
from gcs_core.ephem.orbit import KeplerOrbit, TleOrbit, build_ephemeris
from gcs_core.ephem.sun import earth_occults, in_shadow, sun_position_km, sunlit_fraction
from gcs_core.ephem.timescale import decimal_year, gmst_rad, julian_date, parse_epoch

__all__ = [
    "EPHEMERIS_COLUMNS",
    "Ephemeris",
    "GeomagField",
    "KeplerOrbit",
    "TleOrbit",
    "build_ephemeris",
    "earth_occults",
    "in_shadow",
    "sun_position_km",
    "sunlit_fraction",
    "decimal_year",
    "gmst_rad",
    "julian_date",
    "parse_epoch",
]
