"""Importing a whole mission directory, checked (ICD §1-§6; the seed's SIDP input side).

:func:`load_mission` reads ``mission.toml`` (:mod:`~gcs_core.io.mission`), then every
CSV file it names (:mod:`~gcs_core.io.csvio`) and checks, beyond the CSV rules:

* the telemetry columns of each sensor type (ICD §5) and the ephemeris, onboard
  attitude columns (ICD §4, §6);
* the ephemeris cadence (60 s or finer) and that the ephemeris covers every telemetry
  span, up to a margin: the models read the orbit a little past a row's time (a horizon
  crossing up to a spin period after the Sun sighting, a time-tag shift being estimated),
  so the ephemeris may be extrapolated by :func:`ephemeris_margin` (a spin period plus
  :data:`TIME_TAG_BOUND_S`), with a one-line warning saying by how much. Rows that would
  need more are trimmed, and counted; telemetry lying outside the ephemeris by more than
  the margin is refused, naming how many rows and which span;
* physical ranges that catch unit mistakes: magnetometer components within 1e6 nT,
  |r| between the Earth's surface and 1e6 km, the Sun distance near 1 AU, onboard
  quaternions of unit norm (within 1e-3), gyro rates under 1 rad/s, star right
  ascension in [0, 360] deg and declination in [-90, 90] deg, a non-zero spin rate,
  and no time more than ten years from the epoch.

Every refusal is one :class:`~gcs_core.errors.InputError` naming the file, the line and
the column. What was repaired (rows with empty/NaN fields, duplicate packets dropped)
is counted per file in :class:`ImportReport`.
"""

from __future__ import annotations

import logging
import os
from collections.abc import Mapping
from dataclasses import dataclass, field, replace
from pathlib import Path

import numpy as np

from gcs_core.errors import InputError
from gcs_core.io.csvio import read_table
from gcs_core.io.mission import read_mission_spec
from gcs_core.io.tle_table import mission_tle_table
from gcs_core.io.types import MissionSpec, Table

log = logging.getLogger(__name__)

#: telemetry columns per sensor type (ICD §5), ``t`` first.
TELEMETRY_COLUMNS: dict[str, tuple[str, ...]] = {
    "magnetometer": ("t", "bx", "by", "bz"),
    "gyro": ("t", "wx", "wy", "wz"),
    "star_tracker": ("t", "h", "v", "ra", "dec", "mag"),
    "fine_sun": ("t", "n_alpha", "n_beta"),
    "coarse_sun": ("t", "n_alpha", "n_beta"),
    "plane_field_sun": ("t", "beta"),
    "horizon": ("t", "spin_rate", "dt_in", "dt_out"),
    "attitude_reference": ("t", "q1", "q2", "q3", "q4"),
}
#: units of the telemetry columns (ICD §5); extra columns have no stated unit.
COLUMN_UNITS: dict[str, str] = {
    "t": "s",
    "bx": "nT",
    "by": "nT",
    "bz": "nT",
    "wx": "rad/s",
    "wy": "rad/s",
    "wz": "rad/s",
    "h": "rad",
    "v": "rad",
    "ra": "deg",
    "dec": "deg",
    "mag": "mag",
    "n_alpha": "counts",
    "n_beta": "counts",
    "beta": "rad",
    "spin_rate": "rad/s",
    "dt_in": "s",
    "dt_out": "s",
}
EPHEMERIS_COLUMNS = ("t", "rx", "ry", "rz", "vx", "vy", "vz", "sx", "sy", "sz")
ONBOARD_COLUMNS = ("t", "q1", "q2", "q3", "q4")

#: an optional telemetry column: a non-zero value marks a sample kept in the file but
#: not used (a start-up transient, say), counted in the import report
FLAG_COLUMN = "flag"
MAX_EPHEMERIS_STEP_S = 60.0  # ICD §4: a cadence of 60 s or finer
MAX_FIELD_COMPONENT_NT = 1e6  # the geomagnetic field is < 7e4 nT
R_MIN_KM = 6378.0  # below the Earth's surface
R_MAX_KM = 1e6  # beyond the Moon's orbit (km given as m?)
SUN_DISTANCE_AU = (0.9, 1.1)  # the geocentric Sun is 0.983 to 1.017 AU away
AU_KM = 149597870.7
QUATERNION_NORM_TOL = 1e-3
MAX_RATE_RAD_S = 1.0  # deg/s given as rad/s otherwise
MAX_RATE_GROUND_RAD_S = 40.0  # a unit moved by hand: MEMS full scale is 35 rad/s
#: a ground mission's ephemeris rows are this far outside the telemetry span [s]
GROUND_MARGIN_S = 1.0
FAR_FUTURE_S = 10 * 365.25 * 86400.0  # ten years
#: how far from a row's time the models may read the orbit besides the scan [s]: a time-tag
#: shift or in-track time error at 5σ of its 1 s a priori, plus the horizon model's ±1 s
#: difference for the Sun's rate, rounded up
TIME_TAG_BOUND_S = 10.0


@dataclass(frozen=True)
class FileCount:
    """What one CSV file gave: rows kept and rows dropped (ICD §1).

    Attributes
    ----------
    file : path of the file.
    what : its role ("telemetry TAM1", "ephemeris", "aux", "onboard attitude").
    rows : rows kept.
    dropped_nan : rows dropped for an empty or ``nan`` field.
    dropped_duplicates : exact duplicate rows dropped.
    """

    file: Path
    what: str
    rows: int
    dropped_nan: int
    dropped_duplicates: int


@dataclass(frozen=True)
class ImportReport:
    """Counts, unknown keys and repairs of one import.

    Attributes
    ----------
    files : one :class:`FileCount` per file read, in reading order.
    unknown_keys : keys of mission.toml kept but not used, dotted
        (``mission.foo``, ``sensor[TAM1].gain``).
    repairs : one line per repair made (rows dropped, with file and count).
    warnings : one line per thing accepted with a caveat (the ephemeris extrapolated).
    trimmed : sensor -> rows trimmed because they need the orbit past the margin.
    """

    files: tuple[FileCount, ...]
    unknown_keys: tuple[str, ...] = ()
    repairs: tuple[str, ...] = ()
    warnings: tuple[str, ...] = ()
    trimmed: Mapping[str, int] = field(default_factory=dict)

    def file(self, what: str) -> FileCount:
        """The count of the file whose role is ``what`` (e.g. ``"telemetry TAM1"``)."""
        for f in self.files:
            if f.what == what:
                return f
        raise KeyError(what)

    @property
    def dropped_nan(self) -> int:
        return sum(f.dropped_nan for f in self.files)

    @property
    def dropped_duplicates(self) -> int:
        return sum(f.dropped_duplicates for f in self.files)

    def lines(self) -> list[str]:
        """Human summary, one line per file then the unknown keys and repairs."""
        out = [
            f"{f.what}: {f.rows} rows kept, {f.dropped_nan} dropped (empty/NaN), "
            f"{f.dropped_duplicates} duplicates dropped ({f.file})"
            for f in self.files
        ]
        out += [f"unknown key kept but not used: {k}" for k in self.unknown_keys]
        out += [f"repair: {r}" for r in self.repairs]
        out += [f"warning: {w}" for w in self.warnings]
        return out

    def to_dict(self) -> dict:
        return {
            "files": [
                {
                    "file": str(f.file),
                    "what": f.what,
                    "rows": f.rows,
                    "dropped_nan": f.dropped_nan,
                    "dropped_duplicates": f.dropped_duplicates,
                }
                for f in self.files
            ],
            "unknown_keys": list(self.unknown_keys),
            "repairs": list(self.repairs),
            "warnings": list(self.warnings),
            "trimmed_rows": dict(self.trimmed),
        }


@dataclass(frozen=True)
class ImportedMission:
    """A mission directory, read and checked.

    Attributes
    ----------
    spec : mission.toml as read.
    ephemeris_table : ephemeris.csv (columns :data:`EPHEMERIS_COLUMNS`, km and km/s, GCI).
    telemetry : sensor name -> its telemetry Table, in mission order.
    aux : aux.csv, or None.
    onboard : onboard_attitude.csv (``t, q1..q4``), or None.
    report : per-file counts, unknown keys and repairs.
    ephemeris_margin_s : how far the ephemeris may be extrapolated past its ends [s]
        (:func:`ephemeris_margin`).
    """

    spec: MissionSpec
    ephemeris_table: Table
    telemetry: Mapping[str, Table]
    aux: Table | None = None
    onboard: Table | None = None
    report: ImportReport = field(default_factory=lambda: ImportReport(files=()))
    ephemeris_margin_s: float = 0.0

    @property
    def name(self) -> str:
        return self.spec.name

    def span(self) -> tuple[float, float]:
        """(first, last) telemetry time over all sensors [s since epoch]."""
        t0 = min(float(tab.t[0]) for tab in self.telemetry.values())
        t1 = max(float(tab.t[-1]) for tab in self.telemetry.values())
        return t0, t1


# --- checks ---------------------------------------------------------------------------


def _col(table: Table, name: str) -> int:
    """1-based column number of ``name`` in the file."""
    return list(table.columns).index(name) + 1


def _refuse(table: Table, row: int, name: str, message: str) -> InputError:
    return InputError(
        f"{message} in column {_col(table, name)} '{name}'",
        file=table.path,
        line=int(table.lines[row]),
        column=_col(table, name),
    )


def _first(mask: np.ndarray) -> int | None:
    idx = np.flatnonzero(mask)
    return int(idx[0]) if idx.size else None


def _check_times(table: Table, spec: MissionSpec) -> None:
    i = _first(np.abs(table.t) > FAR_FUTURE_S)
    if i is not None:
        when = "after" if table.t[i] > 0 else "before"
        raise _refuse(
            table,
            i,
            "t",
            f"time t = {table.t[i]:.6g} s is more than 10 years "
            f"{when} the epoch {spec.epoch:%Y-%m-%dT%H:%M:%SZ} (times in the far "
            "future: seconds since the epoch expected)",
        )


def _check_not_empty(table: Table, what: str, minimum: int = 1) -> None:
    if len(table) < minimum:
        dropped = f" after dropping {table.dropped_nan} rows with empty/NaN fields" if table.dropped_nan else ""
        raise InputError(f"{what} has {len(table)} data rows{dropped}; at least {minimum} needed", file=table.path)


def _check_vector_norm(table: Table, names: tuple[str, ...], lo: float, hi: float, message: str) -> None:
    v = table.stack(names)
    with np.errstate(over="ignore"):  # |v| of 1e300 overflows to inf: out of range anyway
        norm = np.sqrt(np.sum(v * v, axis=1))
    i = _first((norm < lo) | (norm > hi))
    if i is not None:
        k = int(np.argmax(np.abs(v[i])))
        raise _refuse(table, i, names[k], message.format(norm=norm[i]))


def _check_sensor(table: Table, stype: str, ground: bool = False) -> None:
    c = table.columns
    if stype == "magnetometer":
        for name in ("bx", "by", "bz"):
            i = _first(np.abs(c[name]) > MAX_FIELD_COMPONENT_NT)
            if i is not None:
                raise _refuse(
                    table,
                    i,
                    name,
                    f"magnetic field component {c[name][i]:.6g} nT "
                    f"exceeds {MAX_FIELD_COMPONENT_NT:g} nT (telemetry in nT?)",
                )
    elif stype == "gyro":
        top = MAX_RATE_GROUND_RAD_S if ground else MAX_RATE_RAD_S
        _check_vector_norm(
            table, ("wx", "wy", "wz"), 0.0, top, f"|omega| = {{norm:.6g}} rad/s exceeds {top:g} rad/s (rates in rad/s?)"
        )
    elif stype == "attitude_reference":
        _check_onboard(table)
    elif stype == "star_tracker":
        i = _first((c["ra"] < 0.0) | (c["ra"] > 360.0))
        if i is not None:
            raise _refuse(table, i, "ra", f"star right ascension {c['ra'][i]:.6g} deg is outside [0, 360] deg")
        i = _first(np.abs(c["dec"]) > 90.0)
        if i is not None:
            raise _refuse(table, i, "dec", f"star declination {c['dec'][i]:.6g} deg is outside [-90, 90] deg")
    elif stype == "horizon":
        i = _first(c["spin_rate"] == 0.0)
        if i is not None:
            raise _refuse(table, i, "spin_rate", "spin rate is 0 rad/s")


def _check_ephemeris(table: Table) -> None:
    _check_not_empty(table, "ephemeris", 2)
    dt = np.diff(table.t)
    i = _first(dt > MAX_EPHEMERIS_STEP_S * (1 + 1e-9))
    if i is not None:
        raise _refuse(
            table,
            i + 1,
            "t",
            f"ephemeris rows {dt[i]:.6g} s apart (lines "
            f"{table.lines[i]} and {table.lines[i + 1]}); ICD §4 needs a cadence "
            f"of {MAX_EPHEMERIS_STEP_S:g} s or finer",
        )
    _check_vector_norm(
        table, ("rx", "ry", "rz"), R_MIN_KM, R_MAX_KM, "|r| = {norm:.6g} km is outside [6378, 1e6] km (position in km?)"
    )
    lo, hi = SUN_DISTANCE_AU
    _check_vector_norm(
        table,
        ("sx", "sy", "sz"),
        lo * AU_KM,
        hi * AU_KM,
        f"|s| = {{norm:.6g}} km is not a geocentric Sun distance ({lo:g} to {hi:g} AU; Sun position in km?)",
    )


def _check_onboard(table: Table) -> None:
    _check_vector_norm(
        table,
        ("q1", "q2", "q3", "q4"),
        1.0 - QUATERNION_NORM_TOL,
        1.0 + QUATERNION_NORM_TOL,
        "quaternion norm {norm:.6g} is not 1 (within 1e-3)",
    )


def ephemeris_margin(telemetry: Mapping[str, Table], types: Mapping[str, str]) -> float:
    """How far past its ends the ephemeris may be extrapolated [s]: the longest spin period
    of the horizon telemetry (a crossing is read up to one spin after the Sun sighting)
    plus :data:`TIME_TAG_BOUND_S`."""
    period = 0.0
    for name, table in telemetry.items():
        if types.get(name) == "horizon" and len(table):
            w = np.abs(np.asarray(table.columns["spin_rate"], dtype=float))
            period = max(period, float(2.0 * np.pi / np.min(w)))
    return period + TIME_TAG_BOUND_S


#: the horizon model reads the Sun ±1 s around each crossing for its rate [s]
_SUN_RATE_STEP_S = 1.0


def _reach(table: Table, stype: str) -> tuple[np.ndarray, np.ndarray]:
    """Per row, the earliest and latest time the models read the orbit at, with every
    time-tag parameter at its a-priori value [s]: the row's time, or for a horizon scanner
    its crossings (``t + dt_in``, ``t + dt_out``) ± the Sun-rate step."""
    t = np.asarray(table.t, dtype=float)
    if stype != "horizon":
        return t, t
    c = table.columns
    late = t + np.maximum(np.asarray(c["dt_in"], dtype=float), np.asarray(c["dt_out"], dtype=float))
    return t + np.minimum(np.asarray(c["dt_in"], dtype=float), 0.0) - _SUN_RATE_STEP_S, late + _SUN_RATE_STEP_S


def _check_covered(table: Table, eph: Table, sensor: str, margin: float) -> None:
    """Refuse telemetry lying outside the ephemeris by more than ``margin`` [s]: one line
    naming how many rows and which span."""
    e0, e1 = float(eph.t[0]), float(eph.t[-1])
    t = np.asarray(table.t, dtype=float)
    out = (t < e0 - margin) | (t > e1 + margin)
    if not np.any(out):
        return
    i = _first(out)
    assert i is not None  # some row is out
    lo, hi = float(np.min(t[out])), float(np.max(t[out]))
    spans = [f"t = {a:.6g} to {b:.6g} s" for a, b, on in ((lo, e0, lo < e0), (e1, hi, hi > e1)) if on]
    uncovered = " and ".join(spans)
    raise _refuse(
        table,
        i,
        "t",
        f"{int(np.count_nonzero(out))} rows of {sensor} (t = {lo:.6g} to "
        f"{hi:.6g} s) lie more than {margin:.3g} s (the models' extrapolation margin) outside "
        f"the ephemeris {eph.path}, which covers t = {e0:.6g} to {e1:.6g} s: {uncovered} is not covered",
    )


def _fit_to_ephemeris(
    telemetry: dict, types: Mapping[str, str], eph: Table, margin: float, root: Path, repairs: list, warnings: list
) -> dict[str, int]:
    """Trim the rows that would need the orbit more than ``margin`` past the ephemeris with
    their time tags moved by :data:`TIME_TAG_BOUND_S`, and say (one line) how far the rest
    extrapolate it. Returns sensor -> rows trimmed."""
    e0, e1 = float(eph.t[0]), float(eph.t[-1])
    trimmed: dict[str, int] = {}
    before = after = 0.0
    users = []
    for name, table in list(telemetry.items()):
        early, late = _reach(table, types[name])
        keep = (early - TIME_TAG_BOUND_S >= e0 - margin) & (late + TIME_TAG_BOUND_S <= e1 + margin)
        if not np.all(keep):
            trimmed[name] = int(np.count_nonzero(~keep))
            telemetry[name] = replace(
                table,
                t=table.t[keep],
                lines=np.asarray(table.lines)[keep],
                columns={k: np.asarray(v)[keep] for k, v in table.columns.items()},
            )
            repairs.append(
                f"{_rel(table.path, root)}: trimmed {trimmed[name]} rows that would need the "
                f"orbit more than {margin:.3g} s past the ephemeris's ends"
            )
            early, late = early[keep], late[keep]
        if early.size and (early.min() < e0 or late.max() > e1):
            before = max(before, e0 - float(early.min()))
            after = max(after, float(late.max()) - e1)
            users.append(name)
    if users:
        ends = []
        if before > 0:
            ends.append(f"{before:.3g} s before its first row (t = {e0:.6g} s)")
        if after > 0:
            ends.append(f"{after:.3g} s past its last row (t = {e1:.6g} s)")
        by = " and ".join(ends)
        warnings.append(
            f"ephemeris {Path(eph.path).name} extrapolated (cubic Hermite) by up to {by} for {', '.join(users)}"
        )
    return trimmed


def _rel(path: Path, root: Path) -> str:
    try:
        return os.path.relpath(path, root)
    except ValueError:
        return str(path)


def _drop_flagged(table: Table) -> tuple[Table, int]:
    """Rows whose ``flag`` column is non-zero left out (kept in the file, counted)."""
    flag = table.columns.get(FLAG_COLUMN)
    if flag is None or not np.any(flag != 0.0):
        return table, 0
    keep = flag == 0.0
    cols = {k: np.ascontiguousarray(v[keep]) for k, v in table.columns.items()}
    return Table(
        path=table.path,
        t=cols["t"],
        columns=cols,
        lines=table.lines[keep],
        dropped_nan=table.dropped_nan,
        dropped_duplicates=table.dropped_duplicates,
    ), int(np.count_nonzero(~keep))


def load_mission(mission_dir: str | os.PathLike) -> ImportedMission:
    """Read and check a mission directory (ICD §1-§6).

    Parameters
    ----------
    mission_dir : directory holding mission.toml (or the mission.toml path).

    Returns
    -------
    ImportedMission with every table read, checked and counted.

    Raises
    ------
    InputError naming the file, line and column (or key) of the first problem found.
    """
    spec = read_mission_spec(mission_dir)
    counts: list[FileCount] = []
    repairs: list[str] = []

    def read(path: Path, required: tuple[str, ...], what: str) -> Table:
        table = read_table(path, required=required, what=what)
        table, flagged = _drop_flagged(table) if what.startswith("telemetry") else (table, 0)
        if flagged:
            repairs.append(
                f"{_rel(path, spec.root)}: {flagged} rows flagged (column "
                f"'{FLAG_COLUMN}' ≠ 0) kept in the file, not used"
            )
        counts.append(FileCount(path, what, len(table), table.dropped_nan, table.dropped_duplicates))
        rel = _rel(path, spec.root)
        if table.dropped_nan:
            repairs.append(f"{rel}: dropped {table.dropped_nan} rows with an empty or NaN field")
        if table.dropped_duplicates:
            repairs.append(f"{rel}: dropped {table.dropped_duplicates} exact duplicate rows")
        _check_times(table, spec)
        return table

    ground = spec.ground_position_km is not None
    eph = None
    if spec.ephemeris_file is not None:
        from gcs_core.io.ccsds import is_oem, read_oem_table  # a CCSDS OEM as the ephemeris (docs/fleet.md)

        if is_oem(spec.ephemeris_file):
            eph = read_oem_table(spec.ephemeris_file, spec.epoch)
            counts.append(FileCount(eph.path, "ephemeris (CCSDS OEM)", len(eph), 0, 0))
            _check_times(eph, spec)
        else:
            eph = read(spec.ephemeris_file, EPHEMERIS_COLUMNS, "ephemeris")
        _check_ephemeris(eph)
    telemetry: dict[str, Table] = {}
    empty: list[str] = []
    for s in spec.sensors:
        what = f"telemetry {s.name}"
        table = read(s.telemetry, TELEMETRY_COLUMNS[s.type], what)
        if len(table) == 0 and s.type != "gyro":
            # a sensor that never saw its target (a Sun sensor always in eclipse, say) is
            # left out of the mission and reported, rather than refusing the whole mission
            empty.append(s.name)
            repairs.append(f"{_rel(s.telemetry, spec.root)}: no data rows; sensor {s.name} left out")
            continue
        _check_not_empty(table, f"{what} ({s.type})")
        _check_sensor(table, s.type, ground)
        telemetry[s.name] = table
    aux = read(spec.aux_file, ("t",), "aux") if spec.aux_file else None
    onboard = None
    if spec.onboard_file:
        onboard = read(spec.onboard_file, ONBOARD_COLUMNS, "onboard attitude")
        _check_onboard(onboard)
    if ground and telemetry:
        eph = ground_ephemeris(spec, telemetry)
    elif eph is None:
        eph = mission_tle_table(spec, [*telemetry.values(), aux, onboard])
        counts.append(FileCount(eph.path, "orbit (TLE)", len(eph), 0, 0))
    types = {s.name: s.type for s in spec.sensors}
    margin = ephemeris_margin(telemetry, types)
    warnings: list[str] = []
    trimmed: dict = {}
    if not ground:
        for name, table in telemetry.items():
            _check_covered(table, eph, name, margin)
        trimmed = _fit_to_ephemeris(telemetry, types, eph, margin, spec.root, repairs, warnings)
    for name, table in telemetry.items():
        if trimmed.get(name) and len(table) == 0:
            raise InputError(
                f"telemetry of {name}: every row needs the orbit past the ephemeris "
                f"(t = {float(eph.t[0]):.6g} to {float(eph.t[-1]):.6g} s)",
                file=table.path,
            )
    if empty:
        from dataclasses import replace as _replace

        spec = _replace(spec, sensors=tuple(x for x in spec.sensors if x.name not in empty))
        if not spec.sensors:
            raise InputError("no sensor has any telemetry rows", file=spec.root / "mission.toml")
    unknown = list(spec.unknown_keys)
    unknown += [f"sensor[{s.name}].{k}" for s in spec.sensors for k in s.unknown_keys]
    for r in repairs:
        log.info("%s", r)
    for w in warnings:
        log.warning("%s", w)
    report = ImportReport(
        files=tuple(counts),
        unknown_keys=tuple(unknown),
        repairs=tuple(repairs),
        warnings=tuple(warnings),
        trimmed=trimmed,
    )
    return ImportedMission(
        spec=spec,
        ephemeris_table=eph,
        telemetry=telemetry,
        aux=aux,
        onboard=onboard,
        report=report,
        ephemeris_margin_s=margin,
    )


def ground_ephemeris(spec: MissionSpec, telemetry: Mapping[str, Table]) -> Table:
    """The ephemeris table of a ground mission (docs/ground.md): the fixed position
    ``ground_position_km`` at rest, on rows every 60 s (ICD §4 cadence) from
    :data:`GROUND_MARGIN_S` before the first telemetry sample to as far after the last.

    The laboratory frame stands where GCI stands in flight. A ground mission has no Sun
    (sensors that need one are refused by the mission reader); the Sun columns hold a
    fixed placeholder 1 AU along +x that no model reads.
    """
    t0 = min(float(tab.t[0]) for tab in telemetry.values()) - GROUND_MARGIN_S
    t1 = max(float(tab.t[-1]) for tab in telemetry.values()) + GROUND_MARGIN_S
    n = max(2, int(np.ceil((t1 - t0) / MAX_EPHEMERIS_STEP_S)) + 1)
    t = np.linspace(t0, t1, n)
    cols = {"t": t}
    pos = spec.ground_position_km
    assert pos is not None  # called for a ground mission
    for k, name in enumerate(("rx", "ry", "rz")):
        cols[name] = np.full(n, float(pos[k]))
    for name in ("vx", "vy", "vz", "sy", "sz"):
        cols[name] = np.zeros(n)
    cols["sx"] = np.full(n, AU_KM)
    cols = {k: cols[k] for k in EPHEMERIS_COLUMNS}
    return Table(path=spec.root / "mission.toml", t=t, columns=cols, lines=np.zeros(n, dtype=np.int64))
