"""The analysis config's value checks (:mod:`gcs_core.config`): each refusal is one
:class:`~gcs_core.errors.ConfigError` naming the file and the full key."""

from __future__ import annotations

import math
import os
import re
from pathlib import Path
from typing import Any

from gcs_core.errors import ConfigError
from gcs_core.problem.state import ROLES
from gcs_core.suggest import did_you_mean
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
        hint = did_you_mean(extra[0], known)
        _fail(f"{prefix}{quote(extra[0])}", f"unknown key{hint} (known: {', '.join(sorted(known))})", file)


def _pair(g: Any) -> bool:
    return isinstance(g, list) and len(g) == 2 and all(number_complaint(x) is None for x in g) and g[0] < g[1]


#: ``[filter] noise_weighting``'s choices, the default window [s] of the long-run factor
#: and the most reweighting passes (:mod:`gcs_core.noise.weighting`)
#: ("correlated", the default: each sensor's Gauss–Markov correlation, declared or measured
#: where significant, gcs_core/noise/correlated.py; white sensors keep their σ)
NOISE_WEIGHTINGS = ("correlated", "stated", "long_run")
DEFAULT_NOISE_WEIGHTING = "correlated"
NOISE_WINDOW_S = 0.5  # longer than the BROAD optical error's 35–100 ms, short against hand motions
NOISE_MAX_PASSES = 3

#: a [models] value that switches a sensor off
MODEL_OFF = "off"


def check_against_mission(cfg, spec) -> None:
    """The checks that need the mission, on a loaded
    :class:`~gcs_core.config_schema.AnalysisConfig` ``cfg``: ``[models]`` names its sensors with their
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
    (:mod:`gcs_core.noise.weighting`; sensor names are checked against the mission by
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
        "noise_weighting": _choice(
            fl, "noise_weighting", NOISE_WEIGHTINGS, DEFAULT_NOISE_WEIGHTING, "filter.noise_weighting", f
        ),
        "noise_window": _number(fl, "noise_window", NOISE_WINDOW_S, f, positive=True, prefix="filter."),
        "noise_passes": _number(fl, "noise_passes", 1, f, lo=1, hi=NOISE_MAX_PASSES, integer=True, prefix="filter."),
        "noise_sensors": tuple(sensors),
    }


#: ``prediction.maneuvers[i].axis``: the reference axes (Eq 4-36)
AXES = ("roll", "pitch", "yaw")
#: the predictor's star models for tracker frames (:mod:`gcs_core.predictor.stars`)
STAR_MODELS = ("sky", "uniform", "catalog", "telemetry")
ELEMENT_KEYS = ("role", "value", "sigma")
#: an element's a-priori value and finite σ, internal units (rad, nT, ...): within ±1e12, σ ≥ 1e-15
ELEMENT_LIMIT = 1e12
ELEMENT_SIGMA_MIN = 1e-15
MANEUVER_KEYS = ("start", "duration", "axis", "rate_deg_s")
_ID = re.compile(r"^[A-Za-z][A-Za-z0-9_-]*\.\S+$")


def read_state(st: dict, f) -> dict[str, Any]:
    """``[state]``'s values: ``effects``, ``exclude`` (effect ids), ``attitude_sigma_deg`` and
    ``elements`` (element name -> (role, value, sigma)); unknown keys are checked by the caller."""
    lists = {}
    for key in ("effects", "exclude"):
        lst = _list(st, key, f"state.{key}", f)
        for i, e in enumerate(lst, start=1):
            _require(
                isinstance(e, str) and _ID.match(e) is not None,
                f"state.{key}[{i}]",
                f'must be an effect id like "TAM1.alignment" (see gcs effects), not {show(e)}',
                f,
            )
        lists[key] = tuple(lst)
    elements = {}
    for name_e, ov in _table(st, "elements", "state.elements", f).items():
        pre = f"state.elements.{quote(name_e)}."
        _require("." in name_e, pre[:-1], 'must be an element name like "TAM1.bias_x"', f)
        _require(isinstance(ov, dict), pre[:-1], f"must be a table (role, value, sigma), not {show(ov)}", f)
        _unknown(ov, ELEMENT_KEYS, pre, f)
        role = ov.get("role")
        _require(
            role is None or (isinstance(role, str) and role in ROLES),
            pre + "role",
            f"must be one of {', '.join(ROLES)}, not {show(role)}",
            f,
        )
        sigma = _number(ov, "sigma", None, f, positive=True, prefix=pre, allow_inf=True)
        if sigma is not None and sigma != math.inf:  # 1/σ² and σ² must stay far from overflow
            _require(sigma >= ELEMENT_SIGMA_MIN, pre + "sigma", f"must be ≥ {ELEMENT_SIGMA_MIN}, not {sigma}", f)
            _require(sigma <= ELEMENT_LIMIT, pre + "sigma", f"must be ≤ {ELEMENT_LIMIT}, not {sigma}", f)
        elements[name_e] = (
            role,
            _number(ov, "value", None, f, lo=-ELEMENT_LIMIT, hi=ELEMENT_LIMIT, prefix=pre),
            sigma,
        )
    att_sig = _number(st, "attitude_sigma_deg", 1.0, f, positive=True, hi=180.0, prefix="state.")
    return {**lists, "attitude_sigma_deg": att_sig, "elements": elements}


def read_prediction(pr: dict, mission: Path, f) -> dict[str, Any]:
    """``[prediction]``'s values, the keys of :class:`~gcs_core.config_schema.PredictionConfig` (each
    maneuver as a (start, duration, axis, rate_deg_s) tuple; the catalog resolved against the
    ``mission`` directory); unknown keys are checked by the caller."""
    gaps = _list(pr, "gaps", "prediction.gaps", f)
    for i, g in enumerate(gaps, start=1):
        _require(
            _pair(g),
            f"prediction.gaps[{i}]",
            f"must be a [start, end] pair of numbers with start < end, not {show(g)}",
            f,
        )
    mans = []
    for i, m in enumerate(_list(pr, "maneuvers", "prediction.maneuvers", f), start=1):
        pre = f"prediction.maneuvers[{i}]."
        _require(isinstance(m, dict), pre[:-1], f"must be a table ([[prediction.maneuvers]]), not {show(m)}", f)
        _unknown(m, MANEUVER_KEYS, pre, f)
        for k in MANEUVER_KEYS:
            _require(k in m, pre + k, "missing: a maneuver needs start, duration, axis and rate_deg_s", f)
        mans.append(
            (
                _number(m, "start", 0.0, f, prefix=pre),
                _number(m, "duration", 0.0, f, positive=True, prefix=pre),
                _choice(m, "axis", AXES, None, pre + "axis", f),
                _number(m, "rate_deg_s", 0.0, f, lo=-180.0, hi=180.0, prefix=pre),
            )
        )
    pred_start = _number(pr, "start", None, f, prefix="prediction.")
    pred_end = _number(pr, "end", None, f, prefix="prediction.")
    if pred_start is not None and pred_end is not None:
        _require(
            pred_end > pred_start,
            "prediction.end",
            f"must be later than prediction.start ({pred_start}), not {pred_end}",
            f,
        )
    pred_catalog = None
    if "catalog" in pr:
        cat = pr["catalog"]  # a file beside any stars but "catalog": DataPlan refuses it
        _require(
            isinstance(cat, str) and cat.strip() != "" and "\0" not in cat,
            "prediction.catalog",
            f"must be a string, not {show(cat)}",
            f,
        )
        pred_catalog = Path(os.path.normpath(mission / cat))
    return {
        "step": _number(pr, "step", 10.0, f, positive=True, prefix="prediction."),
        "gaps": tuple((float(a), float(b)) for a, b in gaps),
        "maneuvers": tuple(mans),
        "start": pred_start,
        "end": pred_end,
        "stars": _choice(pr, "stars", STAR_MODELS, None, "prediction.stars", f) if "stars" in pr else None,
        "catalog": pred_catalog,
    }
