"""An orbit from two-line elements instead of an ephemeris file (extension of ICD §3, §4).

A mission may write, instead of ``[ephemeris] file``::

    [orbit]
    tle = "orbit.tle"        # two-line elements (an optional name line before them)
    frame = "teme"           # optional: teme (the default) | j2000, see below
    step_s = 10.0            # optional: tabulation step [s], at most 60 (ICD §4)

GCS then builds the ephemeris itself, over the span of every telemetry file, auxiliary
and onboard-attitude file of the mission plus :data:`MARGIN_S` on each side:

1. **Orbit.** SGP4 (the ``sgp4`` package, WGS-72 constants as the TLE theory requires)
   at every ``step_s`` seconds. Between rows the ephemeris is Hermite-interpolated as any
   ephemeris.csv is (:mod:`gcs_core.ephem.ephemeris`). At 10 s it stays within 2 cm and
   3 cm/s of SGP4 itself (``tests/reference/test_tle_orbit.py``): the curvature term
   ``h⁴ n⁴ |r| / 384`` is only 0.3 mm, but SGP4's velocity differs from the derivative of
   its position by a few cm/s, and the interpolation uses both. Either is far below SGP4's
   own error (≈ 1 km at the TLE epoch, growing by 1–3 km a day for a low orbit; Vallado
   et al. 2006), which is the accuracy of the orbit: ≈ 0.13 s of along-track time per km.
2. **Frame.** ``frame = "teme"``: SGP4's TEME states are used unrotated, because ICD §2
   defines GCI by the same Earth rotation as TEME (:mod:`gcs_core.ephem.teme`).
   ``frame = "j2000"``: rotated to J2000 (IAU 1976/1980, 0.4 m), for missions whose star
   catalog is J2000; the geomagnetic field is then evaluated ≈ 0.3° of Earth rotation off
   (ICD §2 has no precession: 53 nT RMS at the ISS in 2022), so magnetometer-only
   missions keep TEME.
3. **Sun.** GCS's analytic Sun (Vallado Algorithm 29, mean equator and equinox of date,
   0.01°), rotated into the chosen frame (nutation and the equation of the equinoxes for
   TEME, precession undone for J2000). It is the geometric, not the apparent, Sun: annual
   aberration (20 arcsec) and light time are inside the series' 0.01° error.

Tabulated as an ephemeris table by :func:`gcs_core.io.tle_table.tle_ephemeris_table`.
"""

from __future__ import annotations

import logging
import os
from pathlib import Path

import numpy as np

from gcs_core.ephem import teme, timescale
from gcs_core.ephem.orbit import TleOrbit
from gcs_core.ephem.sun import sun_position_km
from gcs_core.errors import InputError
from gcs_core.inputs import refuse_unreadable

log = logging.getLogger(__name__)

__all__ = ["MARGIN_S", "DEFAULT_STEP_S", "STALE_DAYS", "read_tle", "tle_states"]

#: span added before the first and after the last telemetry time [s] (time-offset
#: candidates and horizon crossings look a little past the samples)
MARGIN_S = 120.0
#: default tabulation step [s]
DEFAULT_STEP_S = 10.0
#: data further than this from the elements' epoch [days] get a warning
STALE_DAYS = 3.0


def _checksum_ok(line: str) -> bool:
    digits = sum(int(c) for c in line[:68] if c.isdigit()) + line[:68].count("-")
    return line[68].isdigit() and digits % 10 == int(line[68])


def read_tle(path: str | os.PathLike) -> tuple[str, str]:
    """The two element lines of a TLE file (an optional name line first; blank lines ignored).

    Raises
    ------
    InputError naming the file and line: not two lines starting "1 " and "2 ", a line
    shorter than 69 characters, a bad checksum (column 69), or lines of two satellites.
    """
    path = Path(path)
    refuse_unreadable(path, "two-line element file")  # a FIFO would block
    try:
        text = path.read_text(encoding="ascii", errors="strict")
    except (OSError, UnicodeDecodeError) as err:
        raise InputError(f"cannot read the two-line elements ({err})", file=path) from None
    rows = [(i, ln.rstrip()) for i, ln in enumerate(text.splitlines(), start=1) if ln.strip()]
    one = [(i, ln) for i, ln in rows if ln.startswith("1 ")]
    two = [(i, ln) for i, ln in rows if ln.startswith("2 ")]
    if len(one) != 1 or len(two) != 1:
        raise InputError(
            f"expected one element set: a line starting '1 ' and one starting '2 ' (found {len(one)} and {len(two)})",
            file=path,
        )
    for i, ln in (one[0], two[0]):
        if len(ln) < 69:
            raise InputError(f"an element line has 69 characters, this one {len(ln)}", file=path, line=i)
        if not _checksum_ok(ln):
            raise InputError("checksum (column 69) does not match the line", file=path, line=i, column=69)
    if one[0][1][2:7] != two[0][1][2:7]:
        raise InputError(
            f"lines 1 and 2 are of different satellites ({one[0][1][2:7]} and {two[0][1][2:7]})",
            file=path,
            line=two[0][0],
            column=3,
        )
    return one[0][1], two[0][1]


def tle_states(orbit: TleOrbit, epoch, t, frame: str = "teme") -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Position [km], velocity [km/s] and analytic Sun [km] in the ``frame`` chosen, (N, 3) each.

    ``t`` are mission seconds since ``epoch``; ``orbit`` is evaluated at the same instants.
    """
    if frame not in teme.ORBIT_FRAMES:
        raise InputError(f"orbit frame must be one of {', '.join(teme.ORBIT_FRAMES)}, not {frame!r}", key="orbit.frame")
    t = np.atleast_1d(np.asarray(t, dtype=float))
    shift = (timescale.parse_epoch(epoch) - orbit.epoch).total_seconds()
    r, v = orbit.state(t + shift)
    sun_mod = sun_position_km(timescale.julian_date(epoch, t))
    if frame == "teme":
        sun = teme.rotate_state(teme.mod_to_teme_matrix(epoch, t), sun_mod)
        return r, v, sun
    Q = teme.teme_to_j2000_matrix(epoch, t)
    r, v = teme.rotate_state(Q, r, v)
    sun = teme.rotate_state(teme.mod_to_j2000_matrix(epoch, t), sun_mod)
    return r, v, sun
