"""Mission time: the epoch, Julian dates, sidereal time and decimal years (ICD §2, §3).

GCS counts time as seconds ``t`` since the mission epoch, a UTC instant. Everything
here turns ``(epoch, t)`` into the time arguments that the ephemeris, Sun and
geomagnetic models need.

Precision. A Julian date near 2.46e6 held in one float64 resolves about 40 µs, which
is too coarse for the Earth's rotation at the arcsecond level over long spans. Internally
we therefore carry *seconds since J2000.0* (2000-01-01 12:00:00 UTC), computed exactly
from the epoch with integer ``timedelta`` arithmetic and then adding ``t``; a float64
second count since J2000 resolves ~0.1 µs for the coming centuries. Julian dates are
offered both as one float (for display and low-precision series such as the Sun) and
as a two-part ``(whole, fraction)`` pair (for SGP4).

UT1 is taken equal to UTC (ICD §2): |UT1 − UTC| < 0.9 s, i.e. < 14 arcsec of Earth
rotation, which the geomagnetic field (the only user of the Earth-fixed frame) does not
feel at the nT level. TDB/TT are likewise approximated by UTC in the low-precision Sun
series (69 s of time moves the Sun by 3 arcsec, far inside that series' 0.01°).

References
----------
Aoki, S. et al., "The new definition of Universal Time", Astron. Astrophys. 105, 359 (1982):
the IAU 1982 GMST expression.
Vallado, D. A., *Fundamentals of Astrodynamics and Applications*, 4th ed., Microcosm 2013,
Eq 3-45/3-47 and Example 3-5 (GMST).
"""

from __future__ import annotations

import re
from datetime import UTC, datetime, timedelta

import numpy as np

from gcs_core.errors import InputError

__all__ = [
    "J2000",
    "JD_J2000",
    "parse_epoch",
    "parse_utc",
    "seconds_since_j2000",
    "days_since_j2000",
    "julian_date",
    "julian_date_parts",
    "julian_centuries",
    "gmst_rad",
    "decimal_year",
]

#: J2000.0 as a UTC instant (the UT1=UTC convention of ICD §2 makes it the GMST origin).
J2000 = datetime(2000, 1, 1, 12, 0, 0, tzinfo=UTC)
#: Julian date of J2000.0.
JD_J2000 = 2451545.0
_DAYS_PER_CENTURY = 36525.0
_SECONDS_PER_DAY = 86400.0

_ISO_UTC = re.compile(
    r"(\d{4})-(\d{2})-(\d{2})"
    r"(?:[Tt ](\d{2}):(\d{2})(?::(\d{2})(?:\.(\d{1,12}))?)?)?"
    r"\s*(Z|z|UTC|[+-]\d{2}:?\d{2})?"
)


def parse_utc(text: str) -> datetime:
    """ISO-8601 date-time -> timezone-aware UTC datetime.

    Accepts ``YYYY-MM-DD[THH:MM[:SS[.fff]]][Z|UTC|+HH:MM]``; no zone means UTC
    (ICD §3), an offset is converted to UTC. Fractions beyond a microsecond are
    rounded. Raises ``ValueError`` with a plain message when the text is not one.
    """
    m = _ISO_UTC.fullmatch(text.strip())
    if not m:
        raise ValueError(f'not an ISO-8601 UTC time: {text!r} (e.g. "2024-03-20T06:00:00Z")')
    y, mo, d, hh, mm, ss, frac, zone = m.groups()
    if ss == "60":
        raise ValueError(f"leap second in {text!r}: choose an epoch off the leap second")
    try:
        dt = datetime(int(y), int(mo), int(d), int(hh or 0), int(mm or 0), int(ss or 0), tzinfo=UTC)
    except ValueError as err:
        raise ValueError(f"not a valid date-time: {text!r} ({err})") from None
    try:
        if frac:
            dt += timedelta(microseconds=round(float("0." + frac) * 1e6))
        if zone and zone not in ("Z", "z", "UTC"):
            sign = 1 if zone[0] == "+" else -1
            digits = zone[1:].replace(":", "")
            hours, minutes = int(digits[:2]), int(digits[2:])
            if hours > 23 or minutes > 59:
                raise ValueError(f"bad UTC offset in {text!r}")
            dt -= sign * timedelta(hours=hours, minutes=minutes)
    except OverflowError:
        raise ValueError(f"date-time out of range: {text!r}") from None
    return dt


def parse_epoch(text, *, key: str | None = None) -> datetime:
    """Read an ISO-8601 UTC instant such as ``"2024-03-20T06:00:00Z"``.

    Accepts ``YYYY-MM-DD[THH:MM[:SS[.fff]]]`` followed by ``Z``, ``UTC`` or a numeric
    offset (``+02:00``), which is converted to UTC. Text without a zone is taken as UTC,
    the time scale ICD §3 prescribes. A ``datetime`` (what TOML's native datetime gives)
    is accepted too; a naive one is taken as UTC.

    Parameters
    ----------
    text : str or datetime
    key : the configuration key the text came from, named in the error message.

    Returns
    -------
    datetime, timezone-aware, in UTC.

    Raises
    ------
    InputError naming ``key`` if the text is not a valid ISO-8601 instant.
    """
    if isinstance(text, datetime):
        dt = text
    else:
        if not isinstance(text, str):
            raise InputError(f"epoch must be an ISO-8601 UTC text like '2024-03-20T06:00:00Z', got {text!r}", key=key)
        try:
            return parse_utc(text)
        except ValueError as exc:
            raise InputError(str(exc), key=key) from None
    if dt.tzinfo is None:
        dt = dt.replace(tzinfo=UTC)
    return dt.astimezone(UTC)


def _epoch_seconds_since_j2000(epoch: datetime) -> float:
    """Exact seconds from J2000.0 to ``epoch`` (integer arithmetic, then one float)."""
    epoch = parse_epoch(epoch)
    d = epoch - J2000
    return d.days * _SECONDS_PER_DAY + d.seconds + d.microseconds * 1e-6


def seconds_since_j2000(epoch, t) -> np.ndarray:
    """Seconds of UTC since J2000.0 for mission times ``t`` [s] (shape of ``t``)."""
    return _epoch_seconds_since_j2000(epoch) + np.asarray(t, dtype=float)


def days_since_j2000(epoch, t) -> np.ndarray:
    """Days of UTC since J2000.0: ``d = JD − 2451545.0`` (shape of ``t``)."""
    return seconds_since_j2000(epoch, t) / _SECONDS_PER_DAY


def julian_centuries(epoch, t) -> np.ndarray:
    """Julian centuries since J2000.0: ``T = (JD − 2451545.0) / 36525``."""
    return days_since_j2000(epoch, t) / _DAYS_PER_CENTURY


def julian_date_parts(epoch, t) -> tuple[np.ndarray, np.ndarray]:
    """Two-part Julian date ``(whole, fraction)`` of mission times ``t``.

    ``whole`` is a half-integer day number (JD at 0h UTC) and ``fraction`` lies in
    ``[0, 1)``, so that no precision is lost in the sum. Shapes of ``t``.
    """
    s = seconds_since_j2000(epoch, t)
    # JD = 2451545.0 + s/86400; shift by half a day so 'whole' lands on 0h UTC.
    days_from_midnight = s / _SECONDS_PER_DAY + 0.5
    whole = np.floor(days_from_midnight)
    frac = days_from_midnight - whole
    return JD_J2000 - 0.5 + whole, frac


def julian_date(epoch, t) -> np.ndarray:
    """Julian date (UTC) of mission times ``t`` [s]: ``JD = 2451545.0 + d``.

    One float64 per time (resolution ~40 µs). Use :func:`days_since_j2000` or
    :func:`julian_date_parts` where precision matters.
    """
    return JD_J2000 + days_since_j2000(epoch, t)


def gmst_rad(epoch, t) -> np.ndarray:
    """Greenwich mean sidereal time [rad] by the IAU 1982 expression, UT1 = UTC (ICD §2).

    ``GMST = 67310.54841 s + (876600 h + 8640184.812866 s) T + 0.093104 s T² − 6.2e−6 s T³``
    with ``T`` in Julian centuries of UT1 since J2000.0 (Aoki et al. 1982; Vallado Eq 3-47).
    Since ``876600 h / 36525 = 86400 s`` per day, the large term is the seconds elapsed
    since J2000, which we reduce modulo one day before adding the small terms.

    Parameters
    ----------
    epoch : mission epoch (datetime or ISO text).
    t : (N,) seconds since the epoch.

    Returns
    -------
    (N,) GMST in ``[0, 2π)``.
    """
    s = seconds_since_j2000(epoch, t)
    T = s / (_SECONDS_PER_DAY * _DAYS_PER_CENTURY)
    sec = np.mod(s, _SECONDS_PER_DAY) + 67310.54841 + T * (8640184.812866 + T * (0.093104 - 6.2e-6 * T))
    return np.mod(sec, _SECONDS_PER_DAY) * (2.0 * np.pi / _SECONDS_PER_DAY)


def decimal_year(epoch, t) -> np.ndarray:
    """Decimal year (UTC) of mission times ``t``: ``year + (time since Jan 1) / (year length)``.

    The convention of IGRF coefficient tables (e.g. 2024-07-02 00:00 = 2024.5: 183 days
    of a 366-day year). Shape of ``t``; spans crossing new year are handled.
    """
    epoch = parse_epoch(epoch)
    t = np.asarray(t, dtype=float)
    if t.size == 0:
        return np.zeros_like(t)
    t0 = _epoch_seconds_since_j2000(epoch)
    years = range(
        epoch.year + int(np.floor(np.min(t) / (366 * 86400.0))) - 1,
        epoch.year + int(np.ceil(np.max(t) / (365 * 86400.0))) + 2,
    )
    starts = (
        np.array([_epoch_seconds_since_j2000(datetime(y, 1, 1, tzinfo=UTC)) for y in years]) - t0
    )  # mission seconds at each Jan 1
    k = np.clip(np.searchsorted(starts, t, side="right") - 1, 0, len(starts) - 2)
    frac = (t - starts[k]) / (starts[k + 1] - starts[k])
    return years[0] + k + frac
