"""One ``[[sensor]]`` table of mission.toml: its name, type, telemetry, placement and data
book (ICD §2, §5), for :func:`gcs_core.io.mission.read_mission_spec`.

The data-book keys each sensor type knows, their shapes, units and ranges are the table
:data:`BOOK_KEYS`; optional keys that are absent get their nominal value there. Keys a table
does not know are kept (in ``SensorSpec.book`` and ``SensorSpec.unknown_keys``) and reported
through ``logging.warning``. Every refusal names the dotted key, e.g. ``sensor[2].noise``
(sensors counted from 1 in file order), and its line.
"""

from __future__ import annotations

import logging
import math
import re
from collections.abc import Callable
from dataclasses import dataclass
from pathlib import Path
from typing import Any

from gcs_core.errors import InputError
from gcs_core.io.noise_psd import PSD_KEYS, correlated_sigma
from gcs_core.io.plan_sensor import PLAN_SENSOR_KEYS, plan_keys
from gcs_core.io.toml_fields import Ctx, existing_file, number, numbers, string
from gcs_core.io.types import SENSOR_TYPES, SensorSpec
from gcs_core.suggest import closest, did_you_mean

#: the reader's logger (mission.toml's warnings come from one place)
log = logging.getLogger("gcs_core.io.mission")

#: sensor types that only make sense on a spinning mission (placed by their own keys).
SPINNER_TYPES = ("plane_field_sun", "horizon")
#: sensor names that would collide with non-sensor state elements (``att.*``, ``model.*``).
RESERVED_NAMES = ("att", "model", "field")
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
#: correlated part (default: all of ``noise``), in the sensor's telemetry units ``u``, or
#: instead of that σ one PSD form (gcs_core/io/noise_psd.py, converted to it exactly)
NOISE_CORRELATION_KEYS = {
    "noise_correlation_s": BookKey(0, "s", required=False, default=None, check=_positive),
    "noise_correlated": BookKey(0, "telemetry units", required=False, default=None, check=_positive),
    **{k: BookKey(0, unit, required=False, default=None, check=_positive) for k, (unit, _) in PSD_KEYS.items()},
}
for _keys in BOOK_KEYS.values():
    if "noise" in _keys:
        _keys.update(NOISE_CORRELATION_KEYS)
#: keys every [[sensor]] table may hold besides its type's data-book keys.
COMMON_KEYS = ("name", "type", "telemetry", "alignment_deg")


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


@dataclass(frozen=True)
class _Table:
    """One ``[[sensor]]`` table being read: where its errors point."""

    ctx: Ctx
    raw: dict
    index: int

    @property
    def base(self) -> str:
        return f"sensor[{self.index}]"

    def error(self, message: str, key: str, tkey: str | None = None) -> InputError:
        """An InputError at ``sensor[i].key`` (the line of ``tkey`` in the table, else the table's)."""
        return self.ctx.error(message, f"{self.base}.{key}", "sensor", self.index, tkey)


def _table(ctx: Ctx, raw: Any, index: int, planning: bool) -> _Table:
    """The table, with its required keys (a plan's sensors need no telemetry)."""
    if not isinstance(raw, dict):
        raise ctx.error("must be a table ([[sensor]])", f"sensor[{index}]", "sensor", index)
    tab = _Table(ctx, raw, index)
    for key in ("name", "type") if planning else ("name", "type", "telemetry"):
        if key not in raw:
            who = repr(raw["name"]) if isinstance(raw.get("name"), str) else "without a name"
            raise tab.error(f"missing key '{key}' in [[sensor]] number {index} (sensor {who})", key)
    return tab


def _name(tab: _Table) -> str:
    name = string(tab.ctx, tab.raw.get("name"), f"{tab.base}.name", "sensor", tab.index, "name")
    if not _NAME.fullmatch(name):
        raise tab.error(
            f"sensor name {name!r} must start with a letter and hold only letters, digits, '_' and '-' (at most 64)",
            "name",
            "name",
        )
    if name.lower() in RESERVED_NAMES:
        raise tab.error(
            f"sensor name {name!r} is reserved (state elements {', '.join(n + '.*' for n in RESERVED_NAMES)})",
            "name",
            "name",
        )
    return name


def _type(tab: _Table, name: str, mode: str) -> str:
    stype = string(tab.ctx, tab.raw.get("type"), f"{tab.base}.type", "sensor", tab.index, "type")
    if stype not in SENSOR_TYPES:
        raise tab.error(
            f"unknown sensor type {stype!r} for sensor {name!r}; known types: {', '.join(SENSOR_TYPES)}", "type", "type"
        )
    if stype in SPINNER_TYPES and mode != "spinning":
        raise tab.error(f'sensor type {stype!r} needs attitude_mode = "spinning", not {mode!r}', "type", "type")
    return stype


def _telemetry(tab: _Table, root: Path, name: str, planning: bool) -> Path:
    """The telemetry file, checked to exist; a plan's (no telemetry) is where it would be,
    never read."""
    if planning and "telemetry" not in tab.raw:
        return root / "telemetry" / f"{name}.csv"
    return existing_file(
        tab.ctx,
        root,
        tab.raw.get("telemetry"),
        f"{tab.base}.telemetry",
        "sensor",
        f"telemetry (sensor {name!r})",
        tab.index,
        "telemetry",
    )


def _alignment(tab: _Table, name: str, stype: str, mode: str) -> tuple[float, float, float] | None:
    """``alignment_deg`` [deg] (ICD §2): required but on a spinning mission, where its own
    sensors are placed by their own keys."""
    if "alignment_deg" not in tab.raw:
        if mode != "spinning":
            raise tab.error(
                f"missing key 'alignment_deg' for sensor {name!r} (a {mode} mission "
                "places every sensor by alignment_deg = [a1, a2, a3], ICD §2)",
                "alignment_deg",
            )
        return None
    if stype in SPINNER_TYPES:
        raise tab.error(
            f"a {stype} sensor of a spinning mission is placed by its own keys, not by alignment_deg (ICD §2)",
            "alignment_deg",
            "alignment_deg",
        )
    a1, a2, a3 = numbers(
        tab.ctx, tab.raw["alignment_deg"], 3, f"{tab.base}.alignment_deg", "sensor", tab.index, "alignment_deg"
    )
    for i, a in enumerate((a1, a2, a3)):
        if abs(a) > 360.0:
            raise tab.error(f"must be in [-360, 360], not {a:g} [deg]", f"alignment_deg[{i}]", "alignment_deg")
    return (a1, a2, a3)


def _book(tab: _Table, name: str, stype: str, planning: bool) -> dict[str, Any]:
    """The type's data-book keys (:data:`BOOK_KEYS`), absent optional ones at their
    default, and a plan's own keys."""
    raw, known = tab.raw, BOOK_KEYS[stype]
    book: dict[str, Any] = {}
    for key, spec in known.items():
        if key in raw:
            book[key] = _book_value(tab.ctx, spec, raw[key], f"{tab.base}.{key}", tab.index, key)
        elif spec.required:
            typo = closest(key, [k for k in raw if k not in COMMON_KEYS and k not in known])
            hint = f"; '{typo}' is not a {stype} key: did you mean '{key}'?" if typo else ""
            raise tab.error(f"missing key '{key}' for {stype} sensor {name!r} [{spec.unit}] (ICD §5){hint}", key)
        elif key not in NOISE_CORRELATION_KEYS:  # absent: white noise, nothing stored
            book[key] = spec.default
    if planning:
        book.update(plan_keys(tab.ctx, raw, tab.base, tab.index))
    _psd_form(tab, book)
    return book


def _psd_form(tab: _Table, book: dict[str, Any]) -> None:
    """A Gauss–Markov part declared as a PSD level (:data:`~gcs_core.io.noise_psd.PSD_KEYS`)
    becomes its σ ``noise_correlated`` (the one form the book keeps, so a mission written
    back from it reads the same): it needs
    ``noise_correlation_s``, excludes the other forms, and may not exceed ``noise``."""
    given = [k for k in ("noise_correlated", *PSD_KEYS) if k in book]
    psd = [k for k in given if k in PSD_KEYS]
    if not psd:
        return
    key = psd[0]
    if len(given) > 1:
        others = ", ".join(k for k in given if k != key)
        raise tab.error(f"give one form of the correlated noise, not {key} and {others}", key, key)
    tau = book.get("noise_correlation_s")
    if tau is None:
        raise tab.error(f"{key} needs noise_correlation_s (the τ [s] of the Gauss–Markov part)", key, key)
    sig_c = correlated_sigma(key, book[key], tau)
    noise = book.get("noise")
    if noise is not None and sig_c > noise * (1.0 + 1e-12):
        unit = PSD_KEYS[key][0]
        raise tab.error(
            f"{book[key]:g} [{unit}] with τ = {tau:g} s is a correlated σ of {sig_c:.6g}, above noise = {noise:g}"
            " (the stated σ holds the correlated part and the white rest)",
            key,
            key,
        )
    del book[key]
    book["noise_correlated"] = sig_c


def _unknown(tab: _Table, name: str, stype: str, planning: bool, book: dict[str, Any]) -> tuple[str, ...]:
    """Keys the table's type does not know: kept in ``book``, reported, not used."""
    known = BOOK_KEYS[stype]
    extra = PLAN_SENSOR_KEYS if planning else ()
    unknown = tuple(k for k in tab.raw if k not in COMMON_KEYS and k not in known and k not in extra)
    for k in unknown:
        book[k] = _plain(tab.raw[k])
        log.warning(
            "%s: unknown key '%s.%s' (sensor %r, type %s) kept but not used%s",
            tab.ctx.file,
            tab.base,
            k,
            name,
            stype,
            did_you_mean(k, (*COMMON_KEYS, *known)),
        )
    return unknown


def read_sensor(ctx: Ctx, root: Path, raw: Any, index: int, mode: str, planning: bool = False) -> SensorSpec:
    """The ``index``-th ``[[sensor]]`` table ``raw`` of a mission of attitude ``mode``
    (``planning``: of a plan file, docs/planning.md), checked (module docstring)."""
    tab = _table(ctx, raw, index, planning)
    name = _name(tab)
    stype = _type(tab, name, mode)
    telemetry = _telemetry(tab, root, name, planning)
    alignment = _alignment(tab, name, stype, mode)
    book = _book(tab, name, stype, planning)
    unknown = _unknown(tab, name, stype, planning, book)
    noise = book.pop("noise") if "noise" in BOOK_KEYS[stype] else None
    return SensorSpec(
        name=name,
        type=stype,
        telemetry=telemetry,
        alignment_deg=alignment,
        noise=noise,
        book=book,
        unknown_keys=unknown,
    )
