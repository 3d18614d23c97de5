"""The analysis config's value checks (:mod:`gcs_core.config`): each refusal is one
:class:`~gcs_core.errors.ConfigError` naming the file and the full key."""

from __future__ import annotations

import difflib
from typing import Any

from gcs_core.errors import ConfigError
from gcs_core.toml_values import number_complaint, quote, show


def _fail(key: str | None, message: str, file) -> None:
    raise ConfigError(message, file=file, key=key or None)


def _require(cond: bool, key: str, message: str, file) -> None:
    if not cond:
        _fail(key, message, file)


def _table(parent: dict, key: str, full: str, file) -> dict:
    v = parent.get(key, {})
    _require(isinstance(v, dict), full, f"must be a table, not {show(v)}", file)
    return v


def _list(parent: dict, key: str, full: str, file) -> list:
    v = parent.get(key, [])
    _require(isinstance(v, list), full, f"must be a list, not {show(v)}", file)
    return v


def _number(
    table: dict, key: str, default, file, *, positive=False, lo=None, hi=None, prefix="", integer=False, allow_inf=False
):
    full = f"{prefix}{key}"
    if key not in table:
        return default
    v = table[key]
    complaint = number_complaint(v, allow_inf=allow_inf)
    if complaint:
        _fail(full, complaint, file)
    v = float(v)
    if integer:
        _require(v == int(v), full, f"must be a whole number, not {v}", file)
    if positive:
        _require(v > 0, full, f"must be > 0, not {v}", file)
    if lo is not None:
        _require(v >= lo, full, f"must be ≥ {lo}, not {v}", file)
    if hi is not None:
        _require(v <= hi, full, f"must be ≤ {hi}, not {v}", file)
    return int(v) if integer else v


def _choice(table: dict, key: str, choices, default, full: str, file):
    v = table.get(key, default)
    _require(isinstance(v, str) and v in choices, full, f"must be one of {', '.join(choices)}, not {show(v)}", file)
    return v


def _unknown(table: dict, known, prefix: str, file) -> None:
    extra = sorted(str(k) for k in set(table) - set(known))
    if extra:
        close = difflib.get_close_matches(extra[0], list(known), n=1)
        hint = f"; did you mean '{close[0]}'?" if close else ""
        _fail(f"{prefix}{quote(extra[0])}", f"unknown key{hint} (known: {', '.join(sorted(known))})", file)


def _pair(g: Any) -> bool:
    return isinstance(g, list) and len(g) == 2 and all(number_complaint(x) is None for x in g) and g[0] < g[1]


#: ``[filter] noise_weighting``'s choices, the default window [s] of the long-run factor
#: and the most reweighting passes (:mod:`gcs_core.diagnosis.weighting`)
NOISE_WEIGHTINGS = ("stated", "long_run")
NOISE_WINDOW_S = 0.5  # longer than the BROAD optical error's 35–100 ms, short against hand motions
NOISE_MAX_PASSES = 3

#: a [models] value that switches a sensor off
MODEL_OFF = "off"


def check_against_mission(cfg, spec) -> None:
    """The checks that need the mission, on a loaded
    :class:`~gcs_core.config.AnalysisConfig` ``cfg``: ``[models]`` names its sensors with their
    types, and effect ids and element names start with one of its sensors (``att.``/``model.``
    too).

    ``spec`` is the mission's :class:`~gcs_core.io.types.MissionSpec`.
    """
    f = cfg.path
    types = {s.name: s.type for s in spec.sensors}
    listed = ", ".join(types) or "none"
    st = cfg.state
    for name, model in cfg.models.items():
        key = f"models.{quote(name)}"
        _require(name in types, key, f"no sensor named '{name}' in mission {spec.name} (sensors: {listed})", f)
        _require(
            model in (types[name], MODEL_OFF),
            key,
            f'sensor {name} is a {types[name]}: use "{types[name]}" or "off", not {show(model)}',
            f,
        )
    _require(
        any(cfg.models.get(name, kind) != MODEL_OFF for name, kind in types.items()),
        "models",
        "every sensor's model is off: there is nothing to fit (turn one on)",
        f,
    )
    for key, ids in (("state.effects", st.effects), ("state.exclude", st.exclude)):
        for i, e in enumerate(ids, start=1):
            owner = e.split(".")[0]
            _require(
                owner in types or owner == "model",
                f"{key}[{i}]",
                f"effect {e}: no sensor named '{owner}' in mission {spec.name} (sensors: {listed})",
                f,
            )
    for name in cfg.filter.edit_k_sensor:
        _require(
            name in types,
            f"filter.edit_k_sensor.{quote(name)}",
            f"no sensor named '{name}' in mission {spec.name} (sensors: {listed})",
            f,
        )
    for i, name in enumerate(cfg.filter.noise_sensors, start=1):
        _require(
            name in types,
            f"filter.noise_sensors[{i}]",
            f"no sensor named '{name}' in mission {spec.name} (sensors: {listed})",
            f,
        )
    for name in st.elements:
        owner = name.split(".")[0]
        _require(
            owner in types or owner == "att",
            f"state.elements.{quote(name)}",
            f"element {name}: no sensor named '{owner}' in mission {spec.name} (sensors: {listed})",
            f,
        )


def edit_k_sensor(fl: dict, f) -> dict[str, float]:
    """``[filter.edit_k_sensor]``: sensor name -> k ≥ 0 (sensor names are checked against
    the mission by :func:`gcs_core.config_checks.check_against_mission`)."""
    table = _table(fl, "edit_k_sensor", "filter.edit_k_sensor", f)
    return {str(name): _number(table, name, 5.0, f, lo=0.0, prefix="filter.edit_k_sensor.") for name in table}


def noise_weighting(fl: dict, f) -> dict[str, Any]:
    """``[filter] noise_weighting, noise_window, noise_passes, noise_sensors``
    (:mod:`gcs_core.diagnosis.weighting`; sensor names are checked against the mission by
    :func:`check_against_mission`)."""
    sensors = _list(fl, "noise_sensors", "filter.noise_sensors", f)
    for i, name in enumerate(sensors, start=1):
        _require(
            isinstance(name, str) and name != "",
            f"filter.noise_sensors[{i}]",
            f"must be a sensor name, not {show(name)}",
            f,
        )
    return {
        "noise_weighting": _choice(fl, "noise_weighting", NOISE_WEIGHTINGS, "stated", "filter.noise_weighting", f),
        "noise_window": _number(fl, "noise_window", NOISE_WINDOW_S, f, positive=True, prefix="filter."),
        "noise_passes": _number(fl, "noise_passes", 1, f, lo=1, hi=NOISE_MAX_PASSES, integer=True, prefix="filter."),
        "noise_sensors": tuple(sensors),
    }
