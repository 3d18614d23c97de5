"""A TLE file tabulated as an ephemeris table (ICD §4 columns).

The orbit is SGP4 from the two-line elements (:mod:`gcs_core.ephem.tle`, frames and the
Sun as described there). The table is an ordinary ephemeris :class:`~gcs_core.io.types.Table`
whose ``path`` is the TLE file, so everything downstream (SDF, fit, diagnosis) treats it
as one.
"""

from __future__ import annotations

import logging
import os
from pathlib import Path

import numpy as np

from gcs_core.ephem import timescale
from gcs_core.ephem.ephemeris import EPHEMERIS_COLUMNS
from gcs_core.ephem.orbit import TleOrbit
from gcs_core.ephem.tle import DEFAULT_STEP_S, MARGIN_S, STALE_DAYS, read_tle, tle_states
from gcs_core.errors import InputError
from gcs_core.io.types import MissionSpec, Table

log = logging.getLogger(__name__)


def tle_ephemeris_table(
    tle_file: str | os.PathLike,
    epoch,
    t_start: float,
    t_end: float,
    *,
    frame: str = "teme",
    step_s: float = DEFAULT_STEP_S,
    margin_s: float = MARGIN_S,
) -> Table:
    """An ephemeris table (ICD §4 columns) propagated from a TLE over ``[t_start, t_end]``
    widened by ``margin_s``, every ``step_s`` seconds (the last row on the end exactly)."""
    line1, line2 = read_tle(tle_file)
    return tle_lines_table(
        line1, line2, epoch, t_start, t_end, frame=frame, step_s=step_s, margin_s=margin_s, tle_file=tle_file
    )


def tle_lines_table(
    line1: str,
    line2: str,
    epoch,
    t_start: float,
    t_end: float,
    *,
    frame: str = "teme",
    step_s: float = DEFAULT_STEP_S,
    margin_s: float = MARGIN_S,
    tle_file: str | os.PathLike = "TLE",
) -> Table:
    """:func:`tle_ephemeris_table` of two element lines already read (a plan ships them to
    the workers of a cluster instead of the file's path)."""
    if not 0.0 < step_s <= 60.0:
        raise InputError(f"step_s must be in (0, 60] s (ICD §4), not {step_s:g}", key="orbit.step_s")
    orbit = TleOrbit(line1, line2, epoch)
    lo, hi = float(t_start) - margin_s, float(t_end) + margin_s
    jd_lo, jd_hi = timescale.julian_date(epoch, np.array([lo, hi]))
    far = max(abs(jd_lo - orbit.tle_epoch_jd), abs(jd_hi - orbit.tle_epoch_jd))
    if far > STALE_DAYS:
        log.warning(
            "%s: the data reach %.1f days from the elements' epoch; SGP4's error grows "
            "by 1-3 km a day in low orbit (use elements of the data's days)",
            tle_file,
            far,
        )
    n = max(int(np.ceil((hi - lo) / step_s - 1e-9)), 1)
    t = lo + step_s * np.arange(n + 1)
    t[-1] = hi
    try:
        r, v, sun = tle_states(orbit, epoch, t, frame)
    except InputError as err:
        raise InputError(err.message, file=tle_file, key=err.key) from None
    cols = dict(zip(EPHEMERIS_COLUMNS, [t, *r.T, *v.T, *sun.T]))
    cols = {k: np.ascontiguousarray(c, dtype=float) for k, c in cols.items()}
    return Table(path=Path(tle_file), t=cols["t"], columns=cols, lines=np.zeros(t.size, dtype=int))


def mission_tle_table(spec: MissionSpec, tables) -> Table:
    """The ephemeris of a mission that gives ``[orbit] tle``: propagated over every
    telemetry table's span (:func:`tle_ephemeris_table`)."""
    spans = [(float(tb.t[0]), float(tb.t[-1])) for tb in tables if tb is not None and len(tb)]
    if spec.orbit_tle is None:  # a ground mission whose every sensor was left out (no rows)
        raise InputError("no sensor has any telemetry rows", file=spec.root / "mission.toml")
    if not spans:
        raise InputError("no telemetry rows to propagate the orbit over", file=spec.orbit_tle)
    return tle_ephemeris_table(
        spec.orbit_tle,
        spec.epoch,
        min(a for a, _ in spans),
        max(b for _, b in spans),
        frame=spec.orbit_frame,
        step_s=spec.orbit_step_s,
    )
