"""Time, ephemeris, Sun, geomagnetic field and light corrections (ICD §2, §4).

- :mod:`.timescale` — epoch parsing, Julian dates, GMST (IAU 1982), decimal years.
- :mod:`.ephemeris` — :class:`Ephemeris`, Hermite interpolation of ephemeris.csv.
- :mod:`.geomag` — :class:`GeomagField`, IGRF-13/14 in GCI.
- :mod:`.sun` — analytic Sun, Earth shadow, Earth occultation of a line of sight.
- :mod:`.orbit` — :class:`KeplerOrbit`, :class:`TleOrbit`, :func:`build_ephemeris`.
- :mod:`.corrections` — aberration and parallax.
"""
