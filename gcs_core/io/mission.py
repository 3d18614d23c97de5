"""mission.toml: the sensor inventory and data-book values (ICD §3, §5).

:func:`read_mission_spec` reads and checks the file and returns a
:class:`~gcs_core.io.types.MissionSpec`. Every refusal is an
:class:`~gcs_core.errors.InputError` naming ``mission.toml``, the line (found by a
light scan of the text, since ``tomllib`` keeps no positions) and the dotted key, e.g.
``sensor[2].noise`` (sensors counted from 1 in file order).

The data-book keys each sensor type knows, their shapes, units and ranges are the
table :data:`BOOK_KEYS` (:mod:`gcs_core.io.mission_sensor`, which reads each
``[[sensor]]``); optional keys that are absent get their nominal value there.
Keys a table does not know are kept (in ``SensorSpec.book`` and
``SensorSpec.unknown_keys``, or ``MissionSpec.unknown_keys``) and reported through
``logging.warning``, never silently ignored.
"""

from __future__ import annotations

import logging
import os
from dataclasses import dataclass
from datetime import UTC, datetime
from pathlib import Path

from gcs_core import toml_values
from gcs_core.ephem.timescale import parse_utc
from gcs_core.errors import InputError
from gcs_core.inputs import check_directory_readable, refuse_unreadable
from gcs_core.io.mission_sensor import (
    BOOK_KEYS,
    COMMON_KEYS,
    HORIZON_OBSERVABLES,
    NOISE_CORRELATION_KEYS,
    RESERVED_NAMES,
    SPINNER_TYPES,
    BookKey,
    read_sensor,
)
from gcs_core.io.orbit_spec import GROUND_KEYS, ORBIT_KEYS, earth_rate, ephemeris_or_orbit, ground_position
from gcs_core.io.toml_fields import Ctx, Locator, numbers, optional_file, show, string
from gcs_core.io.types import ATTITUDE_MODES, MissionSpec, SensorSpec
from gcs_core.suggest import did_you_mean, did_you_mean_path

log = logging.getLogger(__name__)

MISSION_FILE = "mission.toml"
#: sensor types that need the Sun, which a ground mission has none of (docs/ground.md).
SUN_TYPES = ("fine_sun", "coarse_sun", "plane_field_sun", "horizon")
# the sensor tables' names stay importable from here (read by gcs_core.io.mission_sensor)
__all__ = [
    "BOOK_KEYS",
    "COMMON_KEYS",
    "HORIZON_OBSERVABLES",
    "MISSION_FILE",
    "NOISE_CORRELATION_KEYS",
    "RESERVED_NAMES",
    "SPINNER_TYPES",
    "SUN_TYPES",
    "BookKey",
    "read_mission_spec",
    "unknown_key_hint",
]
_TOP_TABLES = ("mission", "ephemeris", "orbit", "aux", "onboard_attitude", "sensor")
_MISSION_KEYS = ("name", "epoch", "attitude_mode", "spin_axis_guess_deg")


# --- tables ---------------------------------------------------------------------------


def unknown_key_hint(key: str) -> str:
    """``; did you mean 'X'?`` for an unknown top-level table or key of ``[mission]``,
    ``[orbit]``, ``[ephemeris]``, ``[aux]`` or ``[onboard_attitude]`` (dotted as in
    :attr:`MissionSpec.unknown_keys`), ``''`` when nothing known is close."""
    table, _, last = key.rpartition(".")
    known = {
        "": _TOP_TABLES,
        "mission": _MISSION_KEYS,
        "orbit": ORBIT_KEYS,
        "ephemeris": ("file", *GROUND_KEYS),
        "aux": ("file",),
        "onboard_attitude": ("file",),
    }.get(table, ())
    return did_you_mean(last, known)


def _check_links(ctx: Ctx, sensors: list[SensorSpec]) -> None:
    by_name = {s.name: s for s in sensors}
    for index, s in enumerate(sensors, start=1):
        ref = s.book.get("sun_sensor") if s.type == "horizon" else None
        if ref is None:
            continue
        other = by_name.get(ref)
        if other is None or other.type != "plane_field_sun":
            found = f"a {other.type} sensor" if other else "no such sensor"
            raise ctx.error(
                f"sun_sensor {ref!r} must name a plane_field_sun sensor of this mission ({found})",
                f"sensor[{index}].sun_sensor",
                "sensor",
                index,
                "sun_sensor",
            )


def _load_toml(path: Path) -> tuple[dict, str]:
    try:
        raw = path.read_bytes()
    except OSError as err:
        raise InputError(f"cannot read {MISSION_FILE} ({err.strerror})", file=path) from None
    text = toml_values.decode(raw, path, InputError)
    return toml_values.loads(text, path, InputError), text


def _locate(mission_dir: str | os.PathLike) -> tuple[Path, Path]:
    """The mission directory and its mission.toml (or a .toml file given itself)."""
    given = Path(mission_dir)
    kind = refuse_unreadable(given, "mission directory")
    if kind == "dir":
        check_directory_readable(given, "mission directory")
        root, path = given, given / MISSION_FILE
    elif given.name == MISSION_FILE or given.suffix == ".toml":
        root, path = given.parent, given
    else:
        raise InputError(f"mission directory not found{did_you_mean_path(given, want_dir=True)}", file=given)
    if refuse_unreadable(path, MISSION_FILE) != "file":
        raise InputError(
            f"{MISSION_FILE} not found: a mission directory holds "
            f"{MISSION_FILE}, ephemeris.csv and telemetry/ (ICD §1)",
            file=path,
        )
    return root, path


@dataclass(frozen=True)
class _Header:
    """``[mission]``: name, epoch (UTC), attitude mode and the spin axis guess [deg]."""

    name: str
    epoch: datetime
    mode: str
    spin_guess: tuple[float, float] | None


def _epoch(ctx: Ctx, raw: object) -> datetime:
    """``mission.epoch``: a TOML date-time (UTC if naive) or an ISO-8601 UTC string."""
    if isinstance(raw, datetime):
        try:
            return raw.replace(tzinfo=UTC) if raw.tzinfo is None else raw.astimezone(UTC)
        except OverflowError:
            raise ctx.error("date-time out of range", "mission.epoch", "mission", 1, "epoch") from None
    if isinstance(raw, str):
        try:
            return parse_utc(raw)
        except ValueError as err:
            raise ctx.error(str(err), "mission.epoch", "mission", 1, "epoch") from None
    raise ctx.error(f"must be an ISO-8601 UTC string, not {show(raw)}", "mission.epoch", "mission", 1, "epoch")


def _spin_guess(ctx: Ctx, m: dict) -> tuple[float, float] | None:
    """``mission.spin_axis_guess_deg`` = [RA, Dec] [deg], if given."""
    if "spin_axis_guess_deg" not in m:
        return None
    ra, dec = numbers(
        ctx, m["spin_axis_guess_deg"], 2, "mission.spin_axis_guess_deg", "mission", 1, "spin_axis_guess_deg"
    )
    if not (0.0 <= ra <= 360.0 and -90.0 <= dec <= 90.0):
        raise ctx.error(
            f"[RA, Dec] must have RA in [0, 360] and Dec in [-90, 90], not [{ra:g}, {dec:g}]",
            "mission.spin_axis_guess_deg",
            "mission",
            1,
            "spin_axis_guess_deg",
        )
    return (ra, dec)


def _read_header(ctx: Ctx, doc: dict, unknown: list[str]) -> _Header:
    """``[mission]``, its unknown keys added to ``unknown``."""
    m = doc.get("mission")
    if not isinstance(m, dict):
        raise ctx.error("missing [mission] table (name, epoch, attitude_mode)", "mission", "mission")
    for key in ("name", "epoch", "attitude_mode"):
        if key not in m:
            raise ctx.error(f"missing key '{key}' in [mission]", f"mission.{key}", "mission")
    name = string(ctx, m["name"], "mission.name", "mission", 1, "name")
    epoch = _epoch(ctx, m["epoch"])
    mode = string(ctx, m["attitude_mode"], "mission.attitude_mode", "mission", 1, "attitude_mode")
    if mode not in ATTITUDE_MODES:
        raise ctx.error(
            f"attitude_mode must be one of {', '.join(ATTITUDE_MODES)}, not {mode!r}",
            "mission.attitude_mode",
            "mission",
            1,
            "attitude_mode",
        )
    spin_guess = _spin_guess(ctx, m)
    unknown += [f"mission.{k}" for k in m if k not in _MISSION_KEYS]
    return _Header(name, epoch, mode, spin_guess)


@dataclass(frozen=True)
class _Site:
    """Where the spacecraft is: an ephemeris file and/or ``[orbit]`` (MissionSpec's orbit
    fields), or a ground mission's position [km] and Earth rate [rad/s]."""

    ephemeris: Path | None
    orbit: dict
    ground: tuple[float, float, float] | None
    earth: tuple[float, float, float] | None


def _read_site(ctx: Ctx, root: Path, doc: dict, mode: str, planning: bool, unknown: list[str]) -> _Site:
    """``[ephemeris]`` / ``[orbit]`` (a plan may leave the orbit to ``[trade.orbit]``)."""
    e = doc.get("ephemeris")
    if isinstance(e, dict) and "ground_position_km" in e and "file" not in e:
        ground = ground_position(ctx, e, mode, unknown)
        return _Site(None, {}, ground, earth_rate(ctx, e))
    if planning and "ephemeris" not in doc and "orbit" not in doc:
        return _Site(None, {}, None, None)  # the orbit is the plan's [trade.orbit]
    ephemeris, orbit = ephemeris_or_orbit(ctx, root, doc, unknown)
    return _Site(ephemeris, orbit, None, None)


def _read_sensors(ctx: Ctx, root: Path, doc: dict, mode: str, planning: bool) -> list[SensorSpec]:
    """Every ``[[sensor]]`` (:func:`~gcs_core.io.mission_sensor.read_sensor`), names unique,
    links checked."""
    raw_sensors = doc.get("sensor")
    if raw_sensors is None:
        raise ctx.error("no [[sensor]] tables: the mission has no sensors to calibrate", "sensor", "sensor")
    if not isinstance(raw_sensors, list):
        raise ctx.error("sensors must be [[sensor]] tables (an array of tables)", "sensor", "sensor")
    sensors: list[SensorSpec] = []
    seen: dict[str, int] = {}
    for index, raw in enumerate(raw_sensors, start=1):
        s = read_sensor(ctx, root, raw, index, mode, planning)
        if s.name in seen:
            raise ctx.error(
                f"sensor name {s.name!r} is used twice (sensor[{seen[s.name]}] "
                f"and sensor[{index}]); names must be unique",
                f"sensor[{index}].name",
                "sensor",
                index,
                "name",
            )
        seen[s.name] = index
        sensors.append(s)
    _check_links(ctx, sensors)
    return sensors


def _refuse_sun_sensors(ctx: Ctx, sensors: list[SensorSpec]) -> None:
    """A ground mission has no Sun (docs/ground.md)."""
    for index, s in enumerate(sensors, start=1):
        if s.type in SUN_TYPES:
            raise ctx.error(
                f"a ground mission has no Sun: sensor {s.name!r} of type {s.type} cannot be used (docs/ground.md)",
                f"sensor[{index}].type",
                "sensor",
                index,
                "type",
            )


def read_mission_spec(mission_dir: str | os.PathLike, *, planning: bool = False) -> MissionSpec:
    """Read and check ``mission.toml`` (ICD §3, §5).

    Parameters
    ----------
    mission_dir : the mission directory, or the mission.toml file itself.
    planning : the file is a plan (docs/planning.md): an analysis config that holds its own
        ``[mission]`` and ``[[sensor]]`` tables. Sensors need no telemetry and may give a
        ``cadence`` and their own ``gaps``; the orbit may be left to ``[trade.orbit]``
        (neither ``[ephemeris]`` nor ``[orbit]``); the config's tables are not reported.

    Returns
    -------
    MissionSpec with paths resolved against the mission directory (every file checked
    to exist), the epoch as a timezone-aware UTC datetime, one SensorSpec per
    ``[[sensor]]`` table in file order.

    Raises
    ------
    InputError naming mission.toml, the line and the key at fault.
    """
    root, path = _locate(mission_dir)
    doc, text = _load_toml(path)
    ctx = Ctx(path, Locator(text))
    unknown: list[str] = [k for k in doc if k not in _TOP_TABLES and not planning]
    header = _read_header(ctx, doc, unknown)
    site = _read_site(ctx, root, doc, header.mode, planning, unknown)
    aux = optional_file(ctx, root, doc, "aux", unknown)
    onboard = optional_file(ctx, root, doc, "onboard_attitude", unknown)
    sensors = _read_sensors(ctx, root, doc, header.mode, planning)
    if site.ground is not None:
        _refuse_sun_sensors(ctx, sensors)
    for k in unknown:
        log.warning("%s: unknown key '%s' kept but not used%s", path, k, unknown_key_hint(k))
    return MissionSpec(
        root=root,
        name=header.name,
        epoch=header.epoch,
        attitude_mode=header.mode,
        ephemeris_file=site.ephemeris,
        sensors=tuple(sensors),
        spin_axis_guess_deg=header.spin_guess,
        aux_file=aux,
        onboard_file=onboard,
        unknown_keys=tuple(unknown),
        ground_position_km=site.ground,
        earth_rate_rad_s=site.earth,
        **site.orbit,
    )
