"""mission.toml: the sensor inventory and data-book values (ICD §3, §5).

:func:`read_mission_spec` reads and checks the file and returns a
:class:`~gcs_core.io.types.MissionSpec`. Every refusal is an
:class:`~gcs_core.errors.InputError` naming ``mission.toml``, the line (found by a
light scan of the text, since ``tomllib`` keeps no positions) and the dotted key, e.g.
``sensor[2].noise`` (sensors counted from 1 in file order).

The data-book keys each sensor type knows, their shapes, units and ranges are the
table :data:`BOOK_KEYS`; optional keys that are absent get their nominal value there.
Keys a table does not know are kept (in ``SensorSpec.book`` and
``SensorSpec.unknown_keys``, or ``MissionSpec.unknown_keys``) and reported through
``logging.warning``, never silently ignored.
"""

from __future__ import annotations

import logging
import math
import os
import re
from collections.abc import Callable
from dataclasses import dataclass
from datetime import UTC, datetime
from pathlib import Path
from typing import Any

from gcs_core import toml_values
from gcs_core.ephem.timescale import parse_utc
from gcs_core.errors import InputError
from gcs_core.inputs import check_directory_readable, refuse_unreadable
from gcs_core.io.orbit_spec import GROUND_KEYS, ORBIT_KEYS, earth_rate, ephemeris_or_orbit, ground_position
from gcs_core.io.plan_sensor import PLAN_SENSOR_KEYS, plan_keys
from gcs_core.io.toml_fields import Ctx, Locator, existing_file, number, numbers, optional_file, show, string
from gcs_core.io.types import ATTITUDE_MODES, SENSOR_TYPES, MissionSpec, SensorSpec
from gcs_core.suggest import closest, did_you_mean, did_you_mean_path

log = logging.getLogger(__name__)

MISSION_FILE = "mission.toml"
#: sensor types that only make sense on a spinning mission (placed by their own keys).
SPINNER_TYPES = ("plane_field_sun", "horizon")
#: sensor names that would collide with non-sensor state elements (``att.*``, ``model.*``).
RESERVED_NAMES = ("att", "model", "field")
#: sensor types that need the Sun, which a ground mission has none of (docs/ground.md).
SUN_TYPES = ("fine_sun", "coarse_sun", "plane_field_sun", "horizon")
HORIZON_OBSERVABLES = ("in_out", "width_midscan")
_NAME = re.compile(r"[A-Za-z][A-Za-z0-9_\-]{0,63}")


# --- ranges -------------------------------------------------------------------------


def _positive(v: float) -> str | None:
    return None if v > 0 else "must be > 0"


def _nonnegative(v: float) -> str | None:
    return None if v >= 0 else "must be >= 0"


def _within(lo: float, hi: float, *, open_lo: bool = False, open_hi: bool = False) -> Callable[[float], str | None]:
    interval = f"{'(' if open_lo else '['}{lo:g}, {hi:g}{')' if open_hi else ']'}"

    def check(v: float) -> str | None:
        ok = (v > lo if open_lo else v >= lo) and (v < hi if open_hi else v <= hi)
        return None if ok else f"must be in {interval}"

    return check


def _nonzero(v: float) -> str | None:
    return None if v != 0 else "must not be 0 (it divides)"


@dataclass(frozen=True)
class BookKey:
    """One data-book key of a sensor type (ICD §5).

    Attributes
    ----------
    size : 0 for a number, n for a list of n numbers, -1 for a string.
    unit : unit of the value as written in mission.toml.
    required : must be present; otherwise ``default`` is filled in.
    check : range check of each number, returning a complaint or None.
    index_checks : extra checks of single list entries, ``{index: check}``.
    choices : allowed values of a string key.
    """

    size: int
    unit: str
    required: bool = True
    default: Any = None
    check: Callable[[float], str | None] | None = None
    index_checks: tuple[tuple[int, Callable[[float], str | None]], ...] = ()
    choices: tuple[str, ...] = ()


_FOV = BookKey(0, "deg", check=_within(0.0, 90.0, open_lo=True))
_NOISE = BookKey(0, "telemetry units", check=_positive)
_SMALL_ANGLE_DEG = _within(-90.0, 90.0, open_lo=True, open_hi=True)

#: sensor type -> data-book key -> description (ICD §5). ``noise`` and
#: ``alignment_deg`` are handled with the common keys below.
BOOK_KEYS: dict[str, dict[str, BookKey]] = {
    "magnetometer": {
        "noise": BookKey(0, "nT", check=_positive),
        "bias": BookKey(3, "nT", check=_within(-1e6, 1e6)),
    },
    "gyro": {
        "bias": BookKey(3, "rad/s", check=_within(-1.0, 1.0)),
        "arw": BookKey(0, "rad/s^0.5", check=_positive),
        "rrw": BookKey(0, "rad/s^1.5", check=_nonnegative),
        "electronic": BookKey(0, "rad", required=False, default=0.0, check=_nonnegative),
    },
    "star_tracker": {
        "noise": BookKey(0, "rad", check=_positive),
        "scale": BookKey(2, "1", check=_within(0.0, 10.0, open_lo=True)),
        "fov_deg": _FOV,
    },
    "fine_sun": {
        "noise": BookKey(0, "counts", check=_positive),
        "coeff_alpha": BookKey(4, "1, 1/count, 1, 1", index_checks=((1, _nonzero),)),
        "coeff_beta": BookKey(4, "1, 1/count, 1, 1", index_checks=((1, _nonzero),)),
        "fov_deg": _FOV,
    },
    "coarse_sun": {
        "noise": BookKey(0, "counts", check=_positive),
        "scale": BookKey(2, "rad/count", check=_nonzero),
        "bias": BookKey(2, "rad", check=_within(-math.pi, math.pi)),
        "fov_deg": _FOV,
    },
    "plane_field_sun": {
        "noise": BookKey(0, "rad", check=_positive),
        "tilt_deg": BookKey(0, "deg", check=_SMALL_ANGLE_DEG),
        "bias": BookKey(0, "rad", check=_within(-math.pi, math.pi)),
    },
    "horizon": {
        "noise": BookKey(0, "s", check=_positive),
        "gamma_deg": BookKey(0, "deg", check=_within(0.0, 180.0, open_lo=True, open_hi=True)),
        "phi_h_deg": BookKey(0, "deg", check=_within(-360.0, 360.0)),
        "horizon_height_km": BookKey(0, "km", check=_within(0.0, 1000.0)),
        # the biases Δγ, Δρ, ΔΦ, ε_S, ε_H, Δt are state elements, nominally zero (ICD §5),
        # not data-book keys; ε_S is the tilt_deg of the plane-field sensor named here
        "sun_sensor": BookKey(-1, "", required=False, default=None),
        "observable": BookKey(-1, "", required=False, default="in_out", choices=HORIZON_OBSERVABLES),
    },
    # an attitude quaternion measured by another instrument (docs/ground.md)
    "attitude_reference": {
        "noise": BookKey(0, "rad", check=_positive),
    },
}
#: a sensor's noise declared correlated (first-order Gauss–Markov; docs/icd_extensions.md,
#: gcs_core/noise/correlated.py): the correlation time τ [s] and the σ of the
#: correlated part (default: all of ``noise``), in the sensor's telemetry units
NOISE_CORRELATION_KEYS = {
    "noise_correlation_s": BookKey(0, "s", required=False, default=None, check=_positive),
    "noise_correlated": BookKey(0, "telemetry units", required=False, default=None, check=_positive),
}
for _keys in BOOK_KEYS.values():
    if "noise" in _keys:
        _keys.update(NOISE_CORRELATION_KEYS)
#: keys every [[sensor]] table may hold besides its type's data-book keys.
COMMON_KEYS = ("name", "type", "telemetry", "alignment_deg")
_TOP_TABLES = ("mission", "ephemeris", "orbit", "aux", "onboard_attitude", "sensor")
_MISSION_KEYS = ("name", "epoch", "attitude_mode", "spin_axis_guess_deg")


def _book_value(ctx: Ctx, spec: BookKey, value: Any, key: str, index: int, tkey: str) -> Any:
    if spec.size == -1:
        text = string(ctx, value, key, "sensor", index, tkey)
        if spec.choices and text not in spec.choices:
            raise ctx.error(f"must be one of {', '.join(spec.choices)}, not {text!r}", key, "sensor", index, tkey)
        return text
    vals: tuple[float, ...]
    if spec.size == 0:
        vals = (number(ctx, value, key, "sensor", index, tkey),)
    else:
        vals = numbers(ctx, value, spec.size, key, "sensor", index, tkey)
    for i, v in enumerate(vals):
        complaints = [spec.check(v)] if spec.check else []
        complaints += [c(v) for j, c in spec.index_checks if j == i]
        for complaint in complaints:
            if complaint:
                sub = key if spec.size == 0 else f"{key}[{i}]"
                raise ctx.error(f"{complaint}, not {v:g} [{spec.unit}]", sub, "sensor", index, tkey)
    return vals[0] if spec.size == 0 else vals


def _plain(value: Any) -> Any:
    """TOML value -> something hashable-ish to keep in a book (lists become tuples)."""
    if isinstance(value, list):
        return tuple(_plain(v) for v in value)
    if isinstance(value, dict):
        return {k: _plain(v) for k, v in value.items()}
    return value


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


def _read_sensor(ctx: Ctx, root: Path, raw: Any, index: int, mode: str, planning: bool = False) -> SensorSpec:
    base = f"sensor[{index}]"
    if not isinstance(raw, dict):
        raise ctx.error("must be a table ([[sensor]])", base, "sensor", index)
    for key in ("name", "type") if planning else ("name", "type", "telemetry"):
        if key not in raw:
            who = repr(raw["name"]) if isinstance(raw.get("name"), str) else "without a name"
            raise ctx.error(
                f"missing key '{key}' in [[sensor]] number {index} (sensor {who})", f"{base}.{key}", "sensor", index
            )
    name = string(ctx, raw.get("name"), f"{base}.name", "sensor", index, "name")
    if not _NAME.fullmatch(name):
        raise ctx.error(
            f"sensor name {name!r} must start with a letter and hold only letters, digits, '_' and '-' (at most 64)",
            f"{base}.name",
            "sensor",
            index,
            "name",
        )
    if name.lower() in RESERVED_NAMES:
        raise ctx.error(
            f"sensor name {name!r} is reserved (state elements {', '.join(n + '.*' for n in RESERVED_NAMES)})",
            f"{base}.name",
            "sensor",
            index,
            "name",
        )
    stype = string(ctx, raw.get("type"), f"{base}.type", "sensor", index, "type")
    if stype not in SENSOR_TYPES:
        raise ctx.error(
            f"unknown sensor type {stype!r} for sensor {name!r}; known types: {', '.join(SENSOR_TYPES)}",
            f"{base}.type",
            "sensor",
            index,
            "type",
        )
    if stype in SPINNER_TYPES and mode != "spinning":
        raise ctx.error(
            f'sensor type {stype!r} needs attitude_mode = "spinning", not {mode!r}',
            f"{base}.type",
            "sensor",
            index,
            "type",
        )
    # a plan (planning=True) has no telemetry: the path is where it would be, never read
    telemetry = (
        root / "telemetry" / f"{name}.csv"
        if planning and "telemetry" not in raw
        else existing_file(
            ctx,
            root,
            raw.get("telemetry"),
            f"{base}.telemetry",
            "sensor",
            f"telemetry (sensor {name!r})",
            index,
            "telemetry",
        )
    )
    alignment: tuple[float, float, float] | None = None
    if "alignment_deg" in raw:
        if stype in SPINNER_TYPES:
            raise ctx.error(
                f"a {stype} sensor of a spinning mission is placed by its own keys, not by alignment_deg (ICD §2)",
                f"{base}.alignment_deg",
                "sensor",
                index,
                "alignment_deg",
            )
        a1, a2, a3 = numbers(ctx, raw["alignment_deg"], 3, f"{base}.alignment_deg", "sensor", index, "alignment_deg")
        alignment = (a1, a2, a3)
        for i, a in enumerate(alignment):
            if abs(a) > 360.0:
                raise ctx.error(
                    f"must be in [-360, 360], not {a:g} [deg]",
                    f"{base}.alignment_deg[{i}]",
                    "sensor",
                    index,
                    "alignment_deg",
                )
    elif mode != "spinning":
        raise ctx.error(
            f"missing key 'alignment_deg' for sensor {name!r} (a {mode} mission "
            "places every sensor by alignment_deg = [a1, a2, a3], ICD §2)",
            f"{base}.alignment_deg",
            "sensor",
            index,
        )
    book: dict[str, Any] = {}
    known = BOOK_KEYS[stype]
    for key, spec in known.items():
        if key in raw:
            book[key] = _book_value(ctx, spec, raw[key], f"{base}.{key}", index, key)
        elif spec.required:
            typo = closest(key, [k for k in raw if k not in COMMON_KEYS and k not in known])
            hint = f"; '{typo}' is not a {stype} key: did you mean '{key}'?" if typo else ""
            raise ctx.error(
                f"missing key '{key}' for {stype} sensor {name!r} [{spec.unit}] (ICD §5){hint}",
                f"{base}.{key}",
                "sensor",
                index,
            )
        elif key not in NOISE_CORRELATION_KEYS:  # absent: white noise, nothing stored
            book[key] = spec.default
    if planning:
        book.update(plan_keys(ctx, raw, base, index))
    extra = PLAN_SENSOR_KEYS if planning else ()
    unknown = tuple(k for k in raw if k not in COMMON_KEYS and k not in known and k not in extra)
    for k in unknown:
        book[k] = _plain(raw[k])
        log.warning(
            "%s: unknown key '%s.%s' (sensor %r, type %s) kept but not used%s",
            ctx.file,
            base,
            k,
            name,
            stype,
            did_you_mean(k, (*COMMON_KEYS, *known)),
        )
    noise = book.pop("noise") if "noise" in known else None
    return SensorSpec(
        name=name,
        type=stype,
        telemetry=telemetry,
        alignment_deg=alignment,
        noise=noise,
        book=book,
        unknown_keys=unknown,
    )


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
    doc, text = _load_toml(path)
    ctx = Ctx(path, Locator(text))
    unknown: list[str] = [k for k in doc if k not in _TOP_TABLES and not planning]

    m = doc.get("mission")
    if not isinstance(m, dict):
        raise ctx.error("missing [mission] table (name, epoch, attitude_mode)", "mission", "mission")
    for key in ("name", "epoch", "attitude_mode"):
        if key not in m:
            raise ctx.error(f"missing key '{key}' in [mission]", f"mission.{key}", "mission")
    name = string(ctx, m["name"], "mission.name", "mission", 1, "name")
    epoch_raw = m["epoch"]
    if isinstance(epoch_raw, datetime):
        try:
            epoch = epoch_raw.replace(tzinfo=UTC) if epoch_raw.tzinfo is None else epoch_raw.astimezone(UTC)
        except OverflowError:
            raise ctx.error("date-time out of range", "mission.epoch", "mission", 1, "epoch") from None
    elif isinstance(epoch_raw, str):
        try:
            epoch = parse_utc(epoch_raw)
        except ValueError as err:
            raise ctx.error(str(err), "mission.epoch", "mission", 1, "epoch") from None
    else:
        raise ctx.error(
            f"must be an ISO-8601 UTC string, not {show(epoch_raw)}", "mission.epoch", "mission", 1, "epoch"
        )
    mode = string(ctx, m["attitude_mode"], "mission.attitude_mode", "mission", 1, "attitude_mode")
    if mode not in ATTITUDE_MODES:
        raise ctx.error(
            f"attitude_mode must be one of {', '.join(ATTITUDE_MODES)}, not {mode!r}",
            "mission.attitude_mode",
            "mission",
            1,
            "attitude_mode",
        )
    spin_guess = None
    if "spin_axis_guess_deg" in m:
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
        spin_guess = (ra, dec)
    unknown += [f"mission.{k}" for k in m if k not in _MISSION_KEYS]

    e = doc.get("ephemeris")
    ground = None
    earth = None
    orbit: dict = {}
    if isinstance(e, dict) and "ground_position_km" in e and "file" not in e:
        ground = ground_position(ctx, e, mode, unknown)
        earth = earth_rate(ctx, e)
        ephemeris = None
    elif planning and "ephemeris" not in doc and "orbit" not in doc:
        ephemeris, orbit = None, {}  # the orbit is the plan's [trade.orbit]
    else:
        ephemeris, orbit = ephemeris_or_orbit(ctx, root, doc, unknown)
    aux = optional_file(ctx, root, doc, "aux", unknown)
    onboard = optional_file(ctx, root, doc, "onboard_attitude", unknown)

    raw_sensors = doc.get("sensor")
    if raw_sensors is None:
        raise ctx.error("no [[sensor]] tables: the mission has no sensors to calibrate", "sensor", "sensor")
    if not isinstance(raw_sensors, list):
        raise ctx.error("sensors must be [[sensor]] tables (an array of tables)", "sensor", "sensor")
    sensors: list[SensorSpec] = []
    seen: dict[str, int] = {}
    for index, raw in enumerate(raw_sensors, start=1):
        s = _read_sensor(ctx, root, raw, index, mode, planning)
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
    if ground is not None:
        for index, s in enumerate(sensors, start=1):
            if s.type in SUN_TYPES:
                raise ctx.error(
                    f"a ground mission has no Sun: sensor {s.name!r} of type {s.type} cannot be used (docs/ground.md)",
                    f"sensor[{index}].type",
                    "sensor",
                    index,
                    "type",
                )
    for k in unknown:
        log.warning("%s: unknown key '%s' kept but not used%s", path, k, unknown_key_hint(k))
    return MissionSpec(
        root=root,
        name=name,
        epoch=epoch,
        attitude_mode=mode,
        ephemeris_file=ephemeris,
        sensors=tuple(sensors),
        spin_axis_guess_deg=spin_guess,
        aux_file=aux,
        onboard_file=onboard,
        unknown_keys=tuple(unknown),
        ground_position_km=ground,
        earth_rate_rad_s=earth,
        **orbit,
    )
