"""CCSDS Navigation Data Messages read as mission files, through the ``ccsds-ndm`` library.

:func:`read_oem_table` reads an Orbit Ephemeris Message (OEM 2.0 or 3.0, CCSDS 502.0-B; KVN
or XML) as a mission's ephemeris table (ICD §4 columns): the hook of
:func:`gcs_core.io.importer.load_mission` for an ``[ephemeris] file`` that is an OEM
(:func:`is_oem`). The time conversions :func:`utc_text` and :func:`seconds_since` are
shared with the AEM export (:mod:`gcs_core.fleet.ccsds`). Conventions: docs/fleet.md.

An OEM is read with ``CENTER_NAME = EARTH``, ``REF_FRAME`` one of :data:`OEM_FRAMES`
(GCI, J2000 axes), ``TIME_SYSTEM = UTC``, km and km/s. An OEM has no Sun: the Sun
columns come from the analytic series GCS uses for a TLE orbit
(:func:`gcs_core.ephem.sun.sun_position_at`, 0.01°).

The library is an optional dependency (``pip install 'gcs[ccsds]'``): it is imported only
when a message is read or written.
"""

from __future__ import annotations

import re
from datetime import UTC, datetime, timedelta
from decimal import Decimal
from pathlib import Path

import numpy as np

from gcs_core.errors import InputError
from gcs_core.io.types import Table

__all__ = ["read_oem_table", "is_oem", "OEM_FRAMES", "utc_text", "seconds_since", "ndm_library"]

#: OEM reference frames taken as GCS's GCI (J2000 axes; GCRF/ICRF differ by < 0.1 arcsec)
OEM_FRAMES = ("EME2000", "J2000", "GCRF", "ICRF")
#: decimals of a second in the epochs written
DECIMALS = 12
_EPOCH = re.compile(r"^(\d{4})-(?:(\d{2})-(\d{2})|(\d{3}))T(\d{2}):(\d{2}):(\d{2})(?:\.(\d+))?Z?$")


def ndm_library():
    """(NdmIo, NDMFileFormats) of the ccsds-ndm library; one line when it is not installed."""
    try:
        from ccsds_ndm.mapping import NDMFileFormats
        from ccsds_ndm.ndm_io import NdmIo
    except ImportError:  # pragma: no cover - an optional extra
        raise InputError("CCSDS messages need the ccsds-ndm library (pip install 'gcs[ccsds]')") from None
    return NdmIo, NDMFileFormats


def utc_text(epoch: datetime, t: float) -> str:
    """``epoch + t`` as ``YYYY-MM-DDTHH:MM:SS.ffffffffffff`` (UTC, :data:`DECIMALS` decimals)."""
    d = Decimal(float(t)).quantize(Decimal(1).scaleb(-DECIMALS))
    whole = int(d.to_integral_value(rounding="ROUND_FLOOR"))
    frac = d - whole
    when = epoch.astimezone(UTC) + timedelta(seconds=whole)
    digits = f"{frac:.{DECIMALS}f}".split(".")[1]
    return when.strftime("%Y-%m-%dT%H:%M:%S") + "." + digits


def seconds_since(epoch: datetime, text: str, *, file=None, line: int | None = None) -> float:
    """Seconds from ``epoch`` to the CCSDS epoch ``text`` (calendar or day-of-year form)."""
    m = _EPOCH.match(text.strip())
    if not m:
        raise InputError(f"not a CCSDS UTC epoch: {text!r}", file=file, line=line)
    y, mo, d, doy, hh, mm, ss, frac = m.groups()
    try:
        if doy:
            day = datetime(int(y), 1, 1, tzinfo=UTC) + timedelta(days=int(doy) - 1)
        else:
            day = datetime(int(y), int(mo), int(d), tzinfo=UTC)
        whole = day + timedelta(hours=int(hh), minutes=int(mm), seconds=int(ss))
    except ValueError as err:
        raise InputError(f"not a valid epoch {text!r} ({err})", file=file, line=line) from None
    delta = whole - epoch.astimezone(UTC)
    secs = delta.days * 86400 + delta.seconds  # exact integer seconds
    return float(secs + Decimal("0." + frac)) if frac else float(secs)


# ---------------------------------------------------------------------------- OEM in
def is_oem(path: str | Path) -> bool:
    """True when ``path`` holds a CCSDS OEM (KVN or XML) rather than an ICD §4 CSV."""
    p = Path(path)
    if p.suffix.lower() == ".oem":
        return True
    try:
        with open(p, "rb") as f:
            head = f.read(512).decode("utf-8", "replace")
    except OSError:
        return False
    return "CCSDS_OEM_VERS" in head or "<oem" in head


def _value(x, what: str, unit: str, path) -> float:
    units = getattr(x, "units", None)
    u = getattr(units, "value", units)
    if u not in (None, unit):
        raise InputError(f"{what} in {u}: GCS reads an OEM in km and km/s", file=path)
    return float(x.value)


def _line_numbers(text: str, epochs: list[str]) -> np.ndarray:
    """1-based line of each epoch in the file, in order (0 where not found)."""
    lines = text.splitlines()
    out, i = [], 0
    for e in epochs:
        j = i
        while j < len(lines) and e not in lines[j]:
            j += 1
        out.append(j + 1 if j < len(lines) else 0)
        i = j + 1 if j < len(lines) else i
    return np.array(out, dtype=np.int64)


def _check_meta(md, path) -> None:
    if str(md.center_name).upper() != "EARTH":
        raise InputError(f"CENTER_NAME = {md.center_name}: GCS reads a geocentric OEM (EARTH)", file=path)
    if str(md.ref_frame).upper() not in OEM_FRAMES:
        raise InputError(f"REF_FRAME = {md.ref_frame}: GCS reads one of {', '.join(OEM_FRAMES)}", file=path)
    if str(md.time_system).upper() != "UTC":
        raise InputError(f"TIME_SYSTEM = {md.time_system}: GCS reads UTC", file=path)


def read_oem_table(path: str | Path, epoch: datetime) -> Table:
    """An OEM as the ephemeris table of a mission whose epoch is ``epoch`` (module
    docstring); one-line :class:`InputError` naming the file for what it cannot take."""
    from gcs_core.ephem.sun import sun_position_at

    path = Path(path)
    NdmIo, _ = ndm_library()
    try:
        text = path.read_text(encoding="utf-8")
        msg = NdmIo().from_string(text)
    except OSError as err:
        raise InputError(f"cannot read the OEM ({err.strerror or err})", file=path) from None
    except Exception as err:  # noqa: BLE001 — the library's parse errors vary; one line naming the file
        raise InputError(
            f"not a readable CCSDS OEM ({type(err).__name__}: {' '.join(str(err).split())})", file=path
        ) from None
    if type(msg).__name__.lower() != "oem":
        raise InputError(f"a CCSDS {type(msg).__name__.upper()}, not an OEM", file=path)
    epochs, rows = [], []
    for seg in msg.body.segment:
        _check_meta(seg.metadata, path)
        for sv in seg.data.state_vector:
            epochs.append(sv.epoch)
            r = [_value(getattr(sv, k), "position", "km", path) for k in ("x", "y", "z")]
            v = [_value(getattr(sv, k), "velocity", "km/s", path) for k in ("x_dot", "y_dot", "z_dot")]
            rows.append(r + v)
    lines = _line_numbers(text, epochs)
    if not rows:
        raise InputError("the OEM holds no state vector", file=path)
    t = np.array([seconds_since(epoch, e, file=path, line=int(ln) or None) for e, ln in zip(epochs, lines)])
    bad = np.flatnonzero(np.diff(t) <= 0)
    if bad.size:
        k = int(bad[0]) + 1
        raise InputError("epochs not strictly increasing (segments overlap?)", file=path, line=int(lines[k]) or None)
    rv = np.array(rows, dtype=float)
    sun = sun_position_at(epoch, t)
    names = ("rx", "ry", "rz", "vx", "vy", "vz")
    cols = {"t": t, **{n: rv[:, i] for i, n in enumerate(names)}}
    cols.update({n: sun[:, i] for i, n in enumerate(("sx", "sy", "sz"))})
    return Table(path=path, t=t, columns=cols, lines=lines)
