"""The plan space of a trade study: the keys an analyst varies and how each changes a plan.

Seed §1.1: the predictor exists to plan, before launch, "data acquisition schemes to
optimize bias observabilities" and "sensor configuration and orientations ... to
optimize the attitude and bias determination geometries". A trade study varies keys of
both kinds over a base analysis config; one *plan* is one combination of values.

Keys (times in minutes from the plan start; angles in degrees):

========================  ==============================================================
``span_min``              length of the plan (end = start + span)
``start_min``             start of the plan [min since the mission epoch]
``passes``                number of data passes (with ``pass_min`` and ``separation_min``:
                          passes of ``pass_min`` with ``separation_min`` gaps between them)
``pass_min``              length of each pass
``separation_min``        gap between consecutive passes (end of one to start of the next)
``gap_start_min``         start of one data gap, ``gap_min`` its length
``gap_min``
``maneuver.axis``         roll | pitch | yaw | none: one constant-rate maneuver (Eq 4-36)
``maneuver.rate_deg_s``   its rate
``maneuver.start_min``    its start
``maneuver.duration_min`` its duration (or ``maneuver.angle_deg``: duration = angle / rate)
``maneuver.angle_deg``    the angle turned
``maneuver.back``         true: turn back by the same angle right after (out and back)
``maneuvers``             a sequence ``axis:rate:minutes[,axis:rate:minutes...]`` flown one
                          after the other from ``maneuver.start_min`` (default: centred in
                          the span), or ``none``
``attitude_mode``         inertial | sun_pointing | earth_pointing (the reference frame)
``models.NAME``           on | off: the sensor NAME used or left out
``NAME.alignment_deg[i]`` mounting angle a_i (i = 1, 2, 3, ICD §2) of sensor NAME
``NAME.noise``            noise of sensor NAME (data-book units); ``NAME.KEY`` any numeric
                          scalar data-book key (``IRU.arw``, ``FHST1.fov_deg``, ...)
``NAME.observable``       vector | magnitude: what magnetometer NAME measures (magnitude:
                          the seed's attitude-independent CADS observable)
``NAME.window_min``       ``"A:B"``: sensor NAME delivers data only from A to B minutes
                          after the plan start (a per-sensor data window)
``effects``               catalogue effects added to the solve-for set, ``+``-joined
                          (``TAM1.alignment+FHST1.alignment``), or ``none``
========================  ==============================================================

Values on the command line: ``KEY=V1,V2,...`` or a range ``KEY=FIRST:LAST:STEP``
(both ends included).
"""

from __future__ import annotations

import itertools
import json
import math
import re
from collections.abc import Mapping, Sequence
from dataclasses import dataclass, replace
from typing import Any

from gcs_core import limits
from gcs_core.config_checks import AXES
from gcs_core.config_schema import AnalysisConfig, ElementConfig, Maneuver
from gcs_core.errors import InputError
from gcs_core.io.types import MissionSpec
from gcs_core.predictor.plan import DataPlan

PLAN_KEYS = (
    "span_min",
    "start_min",
    "passes",
    "pass_min",
    "separation_min",
    "gap_start_min",
    "gap_min",
    "maneuver.axis",
    "maneuver.rate_deg_s",
    "maneuver.start_min",
    "maneuver.duration_min",
    "maneuver.angle_deg",
    "maneuver.back",
    "maneuvers",
    "attitude_mode",
    "effects",
)
ATTITUDE_MODES = ("inertial", "sun_pointing", "earth_pointing")
_ALIGN = re.compile(r"^([A-Za-z][A-Za-z0-9_-]*)\.alignment_deg\[([123])\]$")
_BOOK = re.compile(r"^([A-Za-z][A-Za-z0-9_-]*)\.([A-Za-z_][A-Za-z0-9_]*)$")
_MODEL = re.compile(r"^models\.([A-Za-z][A-Za-z0-9_-]*)$")
#: a range longer than this is a typo, not a study
MAX_VALUES = 10000


def parse_values(text: str, key: str) -> tuple:
    """``"1,2,3"`` or ``"0:90:15"`` (ends included) -> values (numbers where they parse)."""
    text = text.strip()
    if not text:
        raise InputError("no values after '='", key=key)
    if text.count(":") == 2 and "," not in text:
        try:
            a, b, s = (float(x) for x in text.split(":"))
        except ValueError:
            raise InputError(f"a range is FIRST:LAST:STEP of numbers, not {text!r}", key=key) from None
        if not (s > 0 and b >= a) or (b - a) / s > MAX_VALUES:
            raise InputError(f"range {text!r} needs STEP > 0, LAST ≥ FIRST and at most {MAX_VALUES} values", key=key)
        n = int(math.floor((b - a) / s + 1e-9))
        return tuple(_clean(a + k * s) for k in range(n + 1))
    return tuple(_number_or_text(v.strip()) for v in text.split(","))


def _clean(x: float):
    r = round(x, 9)
    return int(r) if r == int(r) else r


def _number_or_text(v: str):
    try:
        return _clean(float(v))
    except ValueError:
        return v


def parse_vary(items: Sequence[str]) -> dict[str, tuple]:
    """``["span_min=10,20", ...]`` -> ``{"span_min": (10, 20), ...}`` (order kept)."""
    out: dict[str, tuple] = {}
    for item in items:
        if "=" not in item:
            raise InputError(f"--vary takes KEY=VALUES, not {item!r}", key="trade.vary")
        key, _, text = item.partition("=")
        key = key.strip()
        if key in out:
            raise InputError("varied twice", key=f"trade.vary.{key}")
        out[key] = parse_values(text, f"trade.vary.{key}")
    return out


#: keys that describe the same part of a plan in two ways (one replaces the other)
_EXCLUSIVE = (
    ({"span_min"}, {"passes", "pass_min", "separation_min"}),
    ({"maneuver.duration_min"}, {"maneuver.angle_deg"}),
    (
        {"maneuvers"},
        {
            "maneuver.axis",
            "maneuver.rate_deg_s",
            "maneuver.start_min",
            "maneuver.duration_min",
            "maneuver.angle_deg",
            "maneuver.back",
        },
    ),
)


def merge_vary(table: Mapping[str, tuple], given: Mapping[str, tuple]) -> dict[str, tuple]:
    """The config's ``[trade.vary]`` with the command line's keys merged in: a given key
    replaces the table's values of that key and of the keys describing the same thing
    another way (``passes`` replaces ``span_min``, ``maneuvers`` the ``maneuver.*`` keys);
    every other key of the table stays (``maneuver.back = true``, ``start_min``), after
    the given ones."""
    drop: set[str] = set()
    for a, b in _EXCLUSIVE:
        if a & set(given):
            drop |= b
        if b & set(given):
            drop |= a
    out = dict(given)  # the command line's keys first (the first varies slowest)
    out.update({k: v for k, v in table.items() if k not in drop and k not in given})
    return out


def check_key(key: str, spec: MissionSpec) -> None:
    """Refuse a key the plan space does not know, naming it (``trade.vary.KEY``)."""
    names = {s.name for s in spec.sensors}
    full = f"trade.vary.{key}"
    if key in PLAN_KEYS:
        return
    m = _MODEL.match(key) or _ALIGN.match(key)
    if m:
        if m.group(1) not in names:
            raise InputError(
                f"no sensor named '{m.group(1)}' in the mission (sensors: {', '.join(sorted(names))})", key=full
            )
        return
    m = _BOOK.match(key)
    if m and m.group(1) in names:
        return
    raise InputError(
        "unknown key (plan keys: "
        + ", ".join(PLAN_KEYS)
        + "; models.NAME, NAME.alignment_deg[i], NAME.noise, NAME.KEY)",
        key=full,
    )


#: plan keys whose values are numbers (checked for every value before the study runs)
NUMBER_KEYS = tuple(k for k in PLAN_KEYS if k.endswith(("_min", "_deg", "_deg_s")) or k == "passes")


def check_values(key: str, values: Sequence) -> None:
    """Refuse, before the study runs, a value no plan could use: text for a number key,
    a span beyond :data:`gcs_core.limits.MAX_SPAN_MIN`."""
    if key in NUMBER_KEYS or key.endswith(".noise") or _ALIGN.match(key):
        for v in values:
            x = _num({key: v}, key)
            if key in ("span_min", "pass_min", "separation_min") and x is not None and x > limits.MAX_SPAN_MIN:
                raise InputError(
                    f"{x:g} min is longer than the limit of {limits.MAX_SPAN_MIN:g} min", key=f"trade.vary.{key}"
                )


def combinations(vary: Mapping[str, Sequence]) -> list[dict[str, Any]]:
    """Every combination of the varied values (the first key varies slowest)."""
    keys = list(vary)
    return [dict(zip(keys, vals)) for vals in itertools.product(*(vary[k] for k in keys))]


def plan_id(combo: Mapping[str, Any]) -> str:
    """A stable name of one combination: ``key=value`` pairs, sorted."""
    return ";".join(f"{k}={_show(combo[k])}" for k in sorted(combo))


def _show(v) -> str:
    return json.dumps(v) if isinstance(v, str) else repr(v)


# ---------------------------------------------------------------------------- applying
@dataclass(frozen=True)
class PlanSetup:
    """One plan ready for the predictor: config, mission description and data plan."""

    config: AnalysisConfig
    spec: MissionSpec
    plan: DataPlan

    def describe(self) -> dict[str, Any]:
        """The plan's full description (JSON-ready): span, gaps, maneuvers, sensors, state."""
        p = self.plan
        return {
            "start": p.start,
            "end": p.end,
            "gaps": [list(g) for g in p.gaps],
            "maneuvers": [
                {"start": m.start, "duration": m.duration, "axis": m.axis, "rate_deg_s": m.rate_deg_s}
                for m in p.maneuvers
            ],
            "stars": p.stars,
            "sensor_gaps": {k: [list(g) for g in v] for k, v in p.sensor_gaps.items()},
            "attitude_mode": self.spec.attitude_mode,
            "sensors": {
                s.name: {
                    "type": s.type,
                    "on": self.config.models.get(s.name) != "off",
                    "alignment_deg": list(s.alignment_deg or (0.0, 0.0, 0.0)),
                    "noise": s.noise,
                    **{k: v for k, v in s.book.items() if isinstance(v, (int, float))},
                }
                for s in self.spec.sensors
            },
            "effects": list(self.config.state.effects),
            "method": self.config.method,
        }


def _num(combo, key, default=None):
    v = combo.get(key, default)
    if v is None:
        return None
    if isinstance(v, bool) or not isinstance(v, (int, float)) or not math.isfinite(v):
        raise InputError(f"must be a number, not {v!r}", key=f"trade.vary.{key}")
    return float(v)


def _flag(v, key) -> bool:
    if isinstance(v, bool):
        return v
    if isinstance(v, str) and v.lower() in ("true", "yes", "on", "false", "no", "off"):
        return v.lower() in ("true", "yes", "on")
    if isinstance(v, (int, float)) and v in (0, 1):
        return bool(v)
    raise InputError(f"must be true or false, not {v!r}", key=f"trade.vary.{key}")


def apply(cfg: AnalysisConfig, spec: MissionSpec, base_plan: DataPlan, combo: Mapping[str, Any]) -> PlanSetup:
    """The config, mission description and plan of one combination (module docstring).

    Keys not in ``combo`` keep the base's values; the base plan's gaps and maneuvers
    move with ``start_min``; a maneuver key replaces the base plan's maneuvers by the
    one maneuver (or sequence) it describes.
    """
    start = base_plan.start if "start_min" not in combo else 60.0 * _num(combo, "start_min")
    span = base_plan.end - base_plan.start
    gaps: list[tuple[float, float]] = [(a - base_plan.start, b - base_plan.start) for a, b in base_plan.gaps]
    if "span_min" in combo:
        span = 60.0 * _num(combo, "span_min")
    if any(k in combo for k in ("passes", "pass_min", "separation_min")):
        if "span_min" in combo:
            raise InputError("give span_min or passes/pass_min/separation_min, not both", key="trade.vary.span_min")
        n = int(_num(combo, "passes", 2))
        length = 60.0 * _num(combo, "pass_min", 10.0)
        sep = 60.0 * _num(combo, "separation_min", 0.0)
        if n < 1 or length <= 0 or sep < 0:
            raise InputError("passes ≥ 1, pass_min > 0 and separation_min ≥ 0 are needed", key="trade.vary.passes")
        span = n * length + (n - 1) * sep
        gaps = [(k * (length + sep) + length, (k + 1) * (length + sep)) for k in range(n - 1) if sep > 0]
    if "gap_min" in combo or "gap_start_min" in combo:
        g0 = 60.0 * _num(combo, "gap_start_min", 0.0)
        g1 = g0 + 60.0 * _num(combo, "gap_min", 0.0)
        if g1 > g0:
            gaps.append((g0, g1))
    if not span > 0:
        raise InputError(f"the plan needs a positive span, not {span / 60.0:g} min", key="trade.vary.span_min")
    shift = start - base_plan.start
    plan = replace(
        base_plan,
        start=start,
        end=start + span,
        gaps=tuple((start + a, start + b) for a, b in gaps if b > 0 and a < span),
        maneuvers=tuple(replace(m, start=m.start + shift) for m in base_plan.maneuvers),
        step=min(base_plan.step, span),
    )
    plan = _maneuver(plan, combo, base_plan)
    plan = _windows(plan, combo, base_plan)

    models = dict(cfg.models)
    for s in spec.sensors:
        key = f"models.{s.name}"
        if key in combo:
            current = cfg.models.get(s.name)
            models[s.name] = (
                "off"
                if not _flag(combo[key], key)
                else (current if current is not None and current != "off" else s.type)
            )
    off = {k for k, v in models.items() if v == "off"}
    elements = {k: v for k, v in cfg.state.elements.items() if k.split(".")[0] not in off}
    effects = tuple(e for e in cfg.state.effects if e.split(".")[0] not in off)
    if "effects" in combo:
        text = str(combo["effects"]).strip()
        extra = () if text.lower() in ("none", "") else tuple(t.strip() for t in text.split("+"))
        effects = tuple(dict.fromkeys(effects + tuple(e for e in extra if e.split(".")[0] not in off)))
    new_cfg = cfg.with_changes(
        models=models,
        state={
            "elements": elements,
            "effects": effects,
            "exclude": tuple(e for e in cfg.state.exclude if e.split(".")[0] not in off),
        },
    )
    new_spec = _spec(spec, combo)
    if "attitude_mode" in combo:
        mode = combo["attitude_mode"]
        if mode not in ATTITUDE_MODES:
            raise InputError(
                f"must be one of {', '.join(ATTITUDE_MODES)}, not {mode!r}", key="trade.vary.attitude_mode"
            )
        new_spec = replace(new_spec, attitude_mode=mode)
    return PlanSetup(new_cfg, new_spec, plan)


def parse_maneuvers(text: str) -> list[tuple[str, float, float]]:
    """``"yaw:0.1:5,roll:-0.1:5"`` -> ``[(axis, rate [deg/s], minutes), ...]`` (``none``: [])."""
    text = str(text).strip()
    if text.lower() in ("", "none"):
        return []
    out = []
    for part in text.replace("+", ",").split(","):
        bits = part.strip().split(":")
        try:
            axis, rate, minutes = bits[0], float(bits[1]), float(bits[2])
        except (IndexError, ValueError):
            raise InputError(
                f"a maneuver is axis:rate_deg_s:minutes, not {part!r}", key="trade.vary.maneuvers"
            ) from None
        if axis not in AXES or not rate or not minutes > 0:
            raise InputError(
                f"a maneuver needs an axis ({', '.join(AXES)}), a rate ≠ 0 and minutes > 0, not {part!r}",
                key="trade.vary.maneuvers",
            )
        out.append((axis, rate, minutes))
    return out


def _sequence(plan: DataPlan, combo: Mapping[str, Any]) -> DataPlan:
    seq = parse_maneuvers(combo["maneuvers"])
    total = 60.0 * sum(m for _, _, m in seq)
    if "maneuver.start_min" in combo:
        t = plan.start + 60.0 * _num(combo, "maneuver.start_min")
    else:
        t = plan.start + max(0.0, 0.5 * (plan.end - plan.start - total))
    mans = []
    for axis, rate, minutes in seq:
        mans.append(Maneuver(t, 60.0 * minutes, axis, rate))
        t += 60.0 * minutes
    return replace(plan, maneuvers=tuple(mans))


def _maneuver(plan: DataPlan, combo: Mapping[str, Any], base: DataPlan) -> DataPlan:
    if "maneuvers" in combo:
        return _sequence(plan, combo)
    keys = [k for k in combo if k.startswith("maneuver.")]
    if not keys:
        return plan
    first = base.maneuvers[0] if base.maneuvers else Maneuver(base.start, 600.0, "yaw", 0.1)
    axis = combo.get("maneuver.axis", first.axis)
    if axis == "none":
        return replace(plan, maneuvers=())
    if axis not in AXES:
        raise InputError(f"must be one of {', '.join(AXES)} or none, not {axis!r}", key="trade.vary.maneuver.axis")
    rate = _num(combo, "maneuver.rate_deg_s", first.rate_deg_s)
    t0 = plan.start + (
        60.0 * _num(combo, "maneuver.start_min") if "maneuver.start_min" in combo else first.start - base.start
    )
    duration = first.duration
    if "maneuver.duration_min" in combo:
        duration = 60.0 * _num(combo, "maneuver.duration_min")
    if "maneuver.angle_deg" in combo:
        if "maneuver.duration_min" in combo:
            raise InputError(
                "give maneuver.angle_deg or maneuver.duration_min, not both", key="trade.vary.maneuver.angle_deg"
            )
        angle = _num(combo, "maneuver.angle_deg")
        if not rate:
            raise InputError("an angle needs a rate ≠ 0", key="trade.vary.maneuver.rate_deg_s")
        duration = abs(angle / rate)
    if not duration > 0 or not rate:
        return replace(plan, maneuvers=())
    mans = [Maneuver(t0, duration, axis, rate)]
    if _flag(combo.get("maneuver.back", False), "maneuver.back"):
        mans.append(Maneuver(t0 + duration, duration, axis, -rate))
    return replace(plan, maneuvers=tuple(mans))


def _spec(spec: MissionSpec, combo: Mapping[str, Any]) -> MissionSpec:
    sensors = list(spec.sensors)
    for key in combo:
        m = _ALIGN.match(key)
        b = _BOOK.match(key) if not m else None
        if not (m or b) or key in PLAN_KEYS or key.startswith(("models.", "maneuver.")):
            continue
        found = m or b
        assert found is not None  # skipped above otherwise
        name = found.group(1)
        field = b.group(2) if b is not None else ""  # the data-book key of a book entry
        idx = next((i for i, s in enumerate(sensors) if s.name == name), None)
        if idx is None:
            raise InputError(f"no sensor named '{name}' in the mission", key=f"trade.vary.{key}")
        s = sensors[idx]
        if field == WINDOW:
            continue  # the plan's, not the sensor's (_windows)
        if field == "observable":
            sensors[idx] = replace(s, book={**s.book, "observable": observable(s, combo[key], f"trade.vary.{key}")})
            continue
        x = _num(combo, key)
        if m:
            a = list(s.alignment_deg or (0.0, 0.0, 0.0))
            a[int(m.group(2)) - 1] = x
            sensors[idx] = replace(s, alignment_deg=(a[0], a[1], a[2]))
        elif field == "noise" and s.noise is not None:
            if not x > 0:
                raise InputError(f"noise must be > 0, not {x}", key=f"trade.vary.{key}")
            sensors[idx] = replace(s, noise=x)
        else:
            book = dict(s.book)
            if field in book and not isinstance(book[field], (int, float)):
                raise InputError(f"{name}.{field} is not a scalar data-book key", key=f"trade.vary.{key}")
            book[field] = x
            sensors[idx] = replace(s, book=book)
    return replace(spec, sensors=tuple(sensors))


#: the data-book-like key of a sensor's data window (``NAME.window_min = "A:B"``)
WINDOW = "window_min"


def _windows(plan: DataPlan, combo: Mapping[str, Any], base: DataPlan) -> DataPlan:
    """``NAME.window_min = "A:B"``: sensor NAME delivers data only from A to B minutes after
    the plan's start (its own gaps before and after; the base plan's gaps of the sensor
    move with the start like the others)."""
    shift = plan.start - base.start
    own = {k: tuple((a + shift, b + shift) for a, b in v) for k, v in base.sensor_gaps.items()}
    for key, value in combo.items():
        name, _, field = key.rpartition(".")
        if field != WINDOW:
            continue
        text = str(value).replace(" ", "")
        try:
            a, b = (60.0 * float(x) for x in text.split(":"))
        except ValueError:
            raise InputError(
                f'a window is "START:END" in minutes from the plan start, not {value!r}', key=f"trade.vary.{key}"
            ) from None
        if not 0.0 <= a < b:
            raise InputError(f"a window needs 0 ≤ START < END, not {value!r}", key=f"trade.vary.{key}")
        gaps = [g for g in ((plan.start, plan.start + a), (plan.start + b, plan.end + 1.0)) if g[1] > g[0]]
        own[name] = own.get(name, ()) + tuple(gaps)
    return replace(plan, sensor_gaps=own) if own else plan


#: what a magnetometer measures in a plan: the field vector (the default) or its magnitude
#: alone (the seed's attitude-independent CADS observable, :mod:`gcs_core.predictor.magnitude`)
OBSERVABLES = ("vector", "magnitude")


def observable(sensor, value, key: str) -> str:
    """A magnetometer's ``observable`` (:data:`OBSERVABLES`), refused for other sensors."""
    if sensor.type != "magnetometer":
        raise InputError(f"only a magnetometer has an observable, not the {sensor.type} {sensor.name}", key=key)
    if value not in OBSERVABLES:
        raise InputError(f"must be one of {', '.join(OBSERVABLES)}, not {value!r}", key=key)
    return str(value)


def element_override(cfg: AnalysisConfig, name: str, **kw) -> AnalysisConfig:
    """``cfg`` with one state element's role/value/σ overridden."""
    old = cfg.state.elements.get(name, ElementConfig())
    return cfg.with_changes(state={"elements": {**cfg.state.elements, name: replace(old, **kw)}})
