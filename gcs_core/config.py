"""The analysis configuration (TOML): one file for the TUI and the headless runs.

Example (every table optional except ``[analysis]``; ``sample_data/configs/`` holds one per
sample mission)::

    [analysis]
    mission = "../missions/nominal-sunpoint"   # relative to this file
    name = "nominal, first look"  # optional label
    method = "whole_span"         # whole_span | batch | kalman

    [physics]
    stellar_aberration = true
    solar_aberration = true
    sun_parallax = true
    earth_oblateness = true       # WGS-84 horizon for horizon scanners
    field_model = "igrf"          # igrf | dipole | constant (an unknown field in a lab, docs/ground.md)

    [models]                      # per sensor: its type (as in mission.toml) or "off"
    CSS1 = "coarse_sun"
    IRU = "gyro"

    [state]
    effects = ["TAM1.alignment"]  # catalogue effects added to the solve-for set
    exclude = []                  # seed effects held instead
    attitude_sigma_deg = 1.0

    [state.elements."TAM1.bias_x"]
    role = "solve-for"            # solve-for | consider | held
    value = 0.0                   # internal units of the element
    sigma = 200.0                 # > 0, or inf (no a-priori information)

    [filter]
    block_seconds = 600.0
    edit_k = 5.0                  # 0 disables k-sigma editing
    max_iterations = 20
    noise_weighting = "long_run"  # stated (default) | long_run
    noise_window = 1.0            # [s]
    noise_passes = 2
    noise_sensors = ["FHST1"]     # default: all
    [filter.edit_k_sensor]        # per-sensor k, 0 disables that sensor's editing
    FHST1 = 4.0

    [diagnosis]
    significance = 0.001          # family-wise, Bonferroni-corrected over candidates
    holdout_fraction = 0.25

    [prediction]
    start = 0.0
    end = 7200.0
    step = 10.0
    gaps = [[1800.0, 2400.0]]
    stars = "catalog"             # catalog | telemetry | sky | uniform (tracker stars)
    catalog = "star_catalog.csv"  # CSV ra, dec, mag; relative to the mission directory
    [[prediction.maneuvers]]
    start = 3000.0
    duration = 600.0
    axis = "yaw"                  # roll | pitch | yaw (Eq 4-36)
    rate_deg_s = 0.1

    [verification]
    requirement_deg = 0.01

    # [trade] and [montecarlo], the planning tables: gcs_core/trade/__init__.py

Every error names the key and says what is wrong (:class:`~gcs_core.errors.ConfigError`);
``docs/input_checks.md`` lists the messages. Keys are dotted as in TOML: a state element
name holds a dot and is quoted (``state.elements."TAM1.bias_x".sigma``), list entries
are counted from 1 (``prediction.maneuvers[2].axis``).
"""

from __future__ import annotations

import hashlib
import json
import os
import re
from dataclasses import dataclass, field, fields, is_dataclass, replace
from pathlib import Path
from typing import Any

from gcs_core import toml_values
from gcs_core.config_checks import (
    MODEL_OFF,
    NOISE_WINDOW_S,
    _choice,
    _fail,
    _list,
    _number,
    _pair,
    _require,
    _table,
    _unknown,
    edit_k_sensor,
    noise_weighting,
)
from gcs_core.errors import ConfigError
from gcs_core.fileperm import write_atomic
from gcs_core.io.types import SENSOR_TYPES
from gcs_core.problem.prepare import PhysicsOptions
from gcs_core.problem.state import ROLES
from gcs_core.toml_values import quote as _quote
from gcs_core.toml_values import show as _show

METHODS = ("whole_span", "batch", "kalman")
FIELD_MODELS = ("igrf", "dipole", "constant")
AXES = ("roll", "pitch", "yaw")
#: the predictor's star models for tracker frames (:mod:`gcs_core.predictor.stars`)
STAR_MODELS = ("sky", "uniform", "catalog", "telemetry")
#: value of ``[models]`` that drops a sensor from the analysis
ELEMENT_KEYS = ("role", "value", "sigma")
MANEUVER_KEYS = ("start", "duration", "axis", "rate_deg_s")
_ID = re.compile(r"^[A-Za-z][A-Za-z0-9_-]*\.\S+$")

#: field metadata: written to TOML only when it holds something (an empty table is left out)
_OMIT_EMPTY = {"omit_empty": True}
#: field metadata: written only when not the default
_OMIT_DEFAULT = {"omit_default": True}


def _key(label: str, **checks) -> dict:
    """Field metadata of a key a form edits: its label with the unit, and the form's checks
    (``positive``, ``choices``)."""
    return {"label": label, **checks}


@dataclass(frozen=True)
class ElementConfig:
    """Override of one state element: role, initial value, a-priori sigma (internal units)."""

    role: str | None = None
    value: float | None = None
    sigma: float | None = None


@dataclass(frozen=True)
class Maneuver:
    """A constant-rate maneuver about one reference axis (Eq 4-35, 4-36)."""

    start: float = field(metadata=_key("start [s]"))
    duration: float = field(metadata=_key("duration [s]", positive=True))
    axis: str = field(metadata=_key("axis", choices=AXES))
    rate_deg_s: float = field(metadata=_key("rate [deg/s]"))


@dataclass(frozen=True)
class StateConfig:
    """``[state]``: the solve-for set (SODL).

    Attributes
    ----------
    effects, exclude : catalogue effect ids added to / removed from the solve-for set.
    attitude_sigma_deg : a-priori sigma of the attitude elements [deg].
    elements : element name -> :class:`ElementConfig`.
    """

    effects: tuple[str, ...] = ()
    exclude: tuple[str, ...] = ()
    attitude_sigma_deg: float = 1.0
    elements: dict[str, ElementConfig] = field(default_factory=dict)


@dataclass(frozen=True)
class FilterConfig:
    """``[filter]``: estimator options.

    Attributes
    ----------
    block_seconds : the FILTR stepping block [s].
    edit_k : k of the k-σ editing (batch) and innovation gate (Kalman); 0 for none.
    max_iterations : iteration limit of the batch and whole-span fits.
    edit_k_sensor : sensor -> its own k, 0 for none, overriding ``edit_k``.
    noise_* : the sensors' weights, :mod:`gcs_core.diagnosis.weighting`.
    """

    block_seconds: float = 600.0
    edit_k: float = 5.0
    max_iterations: int = 20
    edit_k_sensor: dict[str, float] = field(default_factory=dict, metadata=_OMIT_EMPTY)
    noise_weighting: str = field(default="stated", metadata=_OMIT_DEFAULT)
    noise_window: float = field(default=NOISE_WINDOW_S, metadata=_OMIT_DEFAULT)
    noise_passes: int = field(default=1, metadata=_OMIT_DEFAULT)
    noise_sensors: tuple[str, ...] = field(default=(), metadata=_OMIT_EMPTY)


@dataclass(frozen=True)
class DiagnosisConfig:
    """``[diagnosis]``: family-wise significance (Bonferroni over the candidates) and the
    fraction of the span held out for validation."""

    significance: float = 0.001
    holdout_fraction: float = 0.25


@dataclass(frozen=True)
class PredictionConfig:
    """``[prediction]``: the predictor's data plan.

    Attributes
    ----------
    step : frame step [s]; gaps : (start, end) pairs [s]; maneuvers : :class:`Maneuver` s.
    start, end : the plan's span [s], None for the telemetry span.
    stars : the star model (:data:`STAR_MODELS`); None: the plan's default (``"catalog"``
        when a catalog is given, else ``"sky"``).
    catalog : star catalog file (resolved against the mission directory), or None
        (``star_catalog.csv`` of the mission, if any).
    """

    step: float = field(default=10.0, metadata=_key("step [s]", positive=True))
    gaps: tuple[tuple[float, float], ...] = ()
    maneuvers: tuple[Maneuver, ...] = ()
    start: float | None = field(default=None, metadata=_key("start [s]"))
    end: float | None = field(default=None, metadata=_key("end [s]"))
    stars: str | None = None
    catalog: Path | None = None


@dataclass(frozen=True)
class VerificationConfig:
    """``[verification]``: the VERIF attitude accuracy requirement [deg]."""

    requirement_deg: float = 0.01


#: field metadata of the tables that do not change a fit (left out of :func:`fit_key`)
_NOT_FIT = {"fit": False}


@dataclass(frozen=True)
class AnalysisConfig:
    """Everything an analysis run needs besides the mission data, one attribute per
    TOML table (the ``[analysis]`` keys are the top-level attributes).

    Attributes
    ----------
    path : where the config was read from (relative paths resolve against its folder).
    mission : mission directory.
    name : an optional label (not part of :meth:`digest`).
    method : ``whole_span`` (the default: whole-span least squares with the gyro noise
        as process noise on the attitude and drift bias, :mod:`gcs_core.filtr.smoothing_batch`),
        ``batch`` (static states, gyro-propagated attitude with Q = 0) or ``kalman``
        (one-pass filter and smoother with gyro process noise, the FILTR stepping engine).
    physics : always-on physics switches (:class:`~gcs_core.problem.prepare.PhysicsOptions`).
    models : sensor -> its type, or ``"off"`` to leave the sensor out.
    state, filter, diagnosis, prediction, verification : the tables of the same name.
    trade, montecarlo : the ``[trade]`` and ``[montecarlo]`` tables as read (checked in
        detail by :mod:`gcs_core.trade`).
    """

    path: Path | None = field(default=None, metadata=_NOT_FIT)
    mission: Path = Path(".")
    name: str | None = None
    method: str = "whole_span"
    physics: PhysicsOptions = field(default_factory=PhysicsOptions)
    models: dict[str, str] = field(default_factory=dict)
    state: StateConfig = field(default_factory=StateConfig)
    filter: FilterConfig = field(default_factory=FilterConfig)
    diagnosis: DiagnosisConfig = field(default_factory=DiagnosisConfig)
    prediction: PredictionConfig = field(default_factory=PredictionConfig, metadata=_NOT_FIT)
    verification: VerificationConfig = field(default_factory=VerificationConfig, metadata=_NOT_FIT)
    trade: dict = field(default_factory=dict, metadata={**_NOT_FIT, **_OMIT_EMPTY})
    montecarlo: dict = field(default_factory=dict, metadata={**_NOT_FIT, **_OMIT_EMPTY})

    # ------------------------------------------------------------------ derived
    def with_changes(self, **kw) -> AnalysisConfig:
        """A copy with attributes changed; a table's keys are given as ``table={key: value}``
        (``cfg.with_changes(diagnosis={"holdout_fraction": 0.0})``)."""
        out = {}
        for k, v in kw.items():
            old = getattr(self, k)
            out[k] = replace(old, **v) if isinstance(v, dict) and _is_table(old) else v
        return replace(self, **out)

    def digest(self) -> str:
        """A short hash of the settings (provenance of calibrations); the label and the
        planning tables are left out."""
        d = to_dict(self)
        d["analysis"].pop("name", None)
        for extra in PLANNING_TABLES:  # planning settings do not change a calibration
            d.pop(extra, None)
        return hashlib.sha256(json.dumps(d, sort_keys=True).encode()).hexdigest()[:16]


def _is_table(v) -> bool:
    return hasattr(v, "__dataclass_fields__")


#: the attributes of :class:`AnalysisConfig` read from ``[analysis]``
ANALYSIS_KEYS = ("mission", "name", "method")
#: the planning tables (gcs trade / optimize / montecarlo), checked in detail by gcs_core.trade
PLANNING_TABLES: dict[str, tuple[str, ...]] = {
    "trade": ("vary", "targets", "orbit", "top", "output", "optimize"),
    "montecarlo": ("runs", "seed", "output"),
}
#: a plan (docs/planning.md) carries its mission description in the config itself: these
#: tables are mission.toml's, read by :func:`gcs_core.io.mission.read_mission_spec`
PLAN_MISSION_TABLES = ("mission", "sensor", "orbit", "ephemeris")
#: the tables of a config and the keys each holds (from the dataclasses' fields)
TABLES: dict[str, tuple[str, ...]] = {
    "analysis": ANALYSIS_KEYS,
    **{
        f.name: (tuple(g.name for g in fields(f.default_factory)) if is_dataclass(f.default_factory) else ())
        for f in fields(AnalysisConfig)
        if f.name not in ("path", *ANALYSIS_KEYS, *PLANNING_TABLES)
    },
}


def fit_key(cfg: AnalysisConfig) -> str:
    """Digest of the settings that change a fit: every attribute but those marked as not
    (the path, the data plan, the requirement, the planning tables), which take their
    defaults."""
    default = AnalysisConfig()
    return replace(
        cfg, **{f.name: getattr(default, f.name) for f in fields(AnalysisConfig) if not f.metadata.get("fit", True)}
    ).digest()


# ---------------------------------------------------------------------------- reading
def load_config(path: str | Path) -> AnalysisConfig:
    """Read and validate an analysis config; errors name the key (or the line and column)."""
    path = Path(path)
    if path.is_dir():
        _fail(None, "is a directory, not a config file", path)
    if not path.is_file():
        _fail(None, "config file not found", path)
    try:
        raw = path.read_bytes()
    except OSError as err:
        _fail(None, f"cannot read the config file ({err.strerror or err})", path)
    return config_from_dict(parse_toml(toml_values.decode(raw, path, ConfigError), path), path=path)


def parse_toml(text: str, path: Path | None = None) -> dict:
    """``tomllib.loads`` with its errors as :class:`ConfigError` at a line and column."""
    return toml_values.loads(text, path, ConfigError)


def config_from_dict(data: dict, *, path: Path | None = None) -> AnalysisConfig:
    """Validate the TOML tables of a config (relative paths resolve against ``path``'s folder)."""
    f = path
    _require(isinstance(data, dict), "", "a config is a TOML document of tables", f)
    _unknown(data, {**TABLES, **PLANNING_TABLES, **dict.fromkeys(PLAN_MISSION_TABLES)}, "", f)
    tables = {name: _table(data, name, name, f) for name in {**TABLES, **PLANNING_TABLES}}

    an = tables["analysis"]
    _unknown(an, TABLES["analysis"], "analysis.", f)
    plan_file = "mission" in data  # a plan: its own [mission] and [[sensor]] tables
    _require(
        not (plan_file and "mission" in an),
        "analysis.mission",
        "give a mission directory or the plan's own [mission] tables, not both",
        f,
    )
    _require(
        "mission" in an or (plan_file and path is not None),
        "analysis.mission",
        "missing: name the mission directory (or describe the mission in [mission] and [[sensor]] tables)",
        f,
    )
    mission_s = str(path) if plan_file else an["mission"]
    _require(
        isinstance(mission_s, str) and mission_s.strip() != "" and "\0" not in mission_s,
        "analysis.mission",
        f"must be the mission directory as a string, not {_show(mission_s)}",
        f,
    )
    base = path.parent if path is not None else Path(".")
    mission = Path(mission_s)
    if not mission.is_absolute():
        mission = Path(os.path.normpath(base / mission))
    name = an.get("name")
    _require(name is None or isinstance(name, str), "analysis.name", f"must be a string, not {_show(name)}", f)
    method = _choice(an, "method", METHODS, "whole_span", "analysis.method", f)

    ph = {}
    phys = tables["physics"]
    _unknown(phys, TABLES["physics"], "physics.", f)
    for k, v in phys.items():
        if k == "field_model":
            ph[k] = _choice(phys, k, FIELD_MODELS, PhysicsOptions().field_model, "physics.field_model", f)
        else:
            _require(isinstance(v, bool), f"physics.{k}", f"must be true or false, not {_show(v)}", f)
            ph[k] = v

    models = tables["models"]
    for k, v in models.items():
        _require(
            isinstance(v, str) and v in SENSOR_TYPES + (MODEL_OFF,),
            f"models.{_quote(k)}",
            f'must be the sensor\'s type ({", ".join(SENSOR_TYPES)}) or "off", not {_show(v)}',
            f,
        )

    st = tables["state"]
    _unknown(st, TABLES["state"], "state.", f)
    lists = {}
    for key in ("effects", "exclude"):
        lst = _list(st, key, f"state.{key}", f)
        for i, e in enumerate(lst, start=1):
            _require(
                isinstance(e, str) and _ID.match(e) is not None,
                f"state.{key}[{i}]",
                f'must be an effect id like "TAM1.alignment" (see gcs effects), not {_show(e)}',
                f,
            )
        lists[key] = tuple(lst)
    elements = {}
    for name_e, ov in _table(st, "elements", "state.elements", f).items():
        pre = f"state.elements.{_quote(name_e)}."
        _require("." in name_e, pre[:-1], 'must be an element name like "TAM1.bias_x"', f)
        _require(isinstance(ov, dict), pre[:-1], f"must be a table (role, value, sigma), not {_show(ov)}", f)
        _unknown(ov, ELEMENT_KEYS, pre, f)
        role = ov.get("role")
        _require(
            role is None or (isinstance(role, str) and role in ROLES),
            pre + "role",
            f"must be one of {', '.join(ROLES)}, not {_show(role)}",
            f,
        )
        elements[name_e] = ElementConfig(
            role,
            _number(ov, "value", None, f, prefix=pre),
            _number(ov, "sigma", None, f, positive=True, prefix=pre, allow_inf=True),
        )
    att_sig = _number(st, "attitude_sigma_deg", 1.0, f, positive=True, hi=180.0, prefix="state.")

    fl = tables["filter"]
    _unknown(fl, TABLES["filter"], "filter.", f)
    dg = tables["diagnosis"]
    _unknown(dg, TABLES["diagnosis"], "diagnosis.", f)
    pr = tables["prediction"]
    _unknown(pr, TABLES["prediction"], "prediction.", f)
    gaps = _list(pr, "gaps", "prediction.gaps", f)
    for i, g in enumerate(gaps, start=1):
        _require(
            _pair(g),
            f"prediction.gaps[{i}]",
            f"must be a [start, end] pair of numbers with start < end, not {_show(g)}",
            f,
        )
    mans = []
    for i, m in enumerate(_list(pr, "maneuvers", "prediction.maneuvers", f), start=1):
        pre = f"prediction.maneuvers[{i}]."
        _require(isinstance(m, dict), pre[:-1], f"must be a table ([[prediction.maneuvers]]), not {_show(m)}", f)
        _unknown(m, MANEUVER_KEYS, pre, f)
        for k in MANEUVER_KEYS:
            _require(k in m, pre + k, "missing: a maneuver needs start, duration, axis and rate_deg_s", f)
        mans.append(
            Maneuver(
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
    pred_stars = _choice(pr, "stars", STAR_MODELS, None, "prediction.stars", f) if "stars" in pr else None
    pred_catalog = None
    if "catalog" in pr:
        cat = pr["catalog"]  # a file beside any stars but "catalog": DataPlan refuses it
        _require(
            isinstance(cat, str) and cat.strip() != "" and "\0" not in cat,
            "prediction.catalog",
            f"must be a string, not {_show(cat)}",
            f,
        )
        pred_catalog = Path(os.path.normpath((mission.parent if plan_file else mission) / cat))
    vf = tables["verification"]
    _unknown(vf, TABLES["verification"], "verification.", f)
    for extra, keys in PLANNING_TABLES.items():
        _unknown(tables[extra], keys, f"{extra}.", f)
    return AnalysisConfig(
        path=path,
        mission=mission,
        name=name,
        method=method,
        physics=PhysicsOptions(**ph),
        models=dict(models),
        state=StateConfig(
            effects=lists["effects"], exclude=lists["exclude"], attitude_sigma_deg=att_sig, elements=elements
        ),
        filter=FilterConfig(
            block_seconds=_number(fl, "block_seconds", FilterConfig.block_seconds, f, positive=True, prefix="filter."),
            edit_k=_number(fl, "edit_k", FilterConfig.edit_k, f, lo=0.0, prefix="filter."),
            max_iterations=_number(
                fl, "max_iterations", FilterConfig.max_iterations, f, lo=1, hi=1000, integer=True, prefix="filter."
            ),
            edit_k_sensor=edit_k_sensor(fl, f),
            **noise_weighting(fl, f),
        ),
        diagnosis=DiagnosisConfig(
            significance=_number(
                dg, "significance", DiagnosisConfig.significance, f, lo=1e-12, hi=0.5, prefix="diagnosis."
            ),
            holdout_fraction=_number(
                dg, "holdout_fraction", DiagnosisConfig.holdout_fraction, f, lo=0.0, hi=0.9, prefix="diagnosis."
            ),
        ),
        prediction=PredictionConfig(
            step=_number(pr, "step", 10.0, f, positive=True, prefix="prediction."),
            gaps=tuple((float(a), float(b)) for a, b in gaps),
            maneuvers=tuple(mans),
            start=pred_start,
            end=pred_end,
            stars=pred_stars,
            catalog=pred_catalog,
        ),
        verification=VerificationConfig(
            requirement_deg=_number(vf, "requirement_deg", 0.01, f, positive=True, hi=180.0, prefix="verification.")
        ),
        trade=dict(tables["trade"]),
        montecarlo=dict(tables["montecarlo"]),
    )


# ---------------------------------------------------------------------------- writing
def to_dict(cfg: AnalysisConfig, *, relative_to: Path | None = None) -> dict[str, Any]:
    """The TOML-ready dictionary of a config (paths relative to ``relative_to``): one TOML
    table per table attribute, its keys in field order; None and empty optional tables
    are left out."""
    mission = cfg.mission
    if relative_to is not None:
        try:
            mission = Path(_relpath(cfg.mission, relative_to))
        except ValueError:
            pass
    analysis: dict[str, Any] = {"mission": mission.as_posix(), "method": cfg.method}
    if cfg.name is not None:
        analysis["name"] = cfg.name
    out: dict[str, Any] = {"analysis": analysis}
    for f in fields(AnalysisConfig):
        if f.name in ("path", *ANALYSIS_KEYS):
            continue
        value = getattr(cfg, f.name)
        if f.metadata.get("omit_empty") and not value:
            continue
        out[f.name] = _table_dict(value, cfg) if _is_table(value) else dict(value)
    return out


def _table_dict(table, cfg: AnalysisConfig) -> dict[str, Any]:
    """One table's TOML keys: tuples as lists, dataclasses as tables, None left out, the
    star catalog relative to the mission (as it is read)."""
    out: dict[str, Any] = {}
    for f in fields(table):
        v = getattr(table, f.name)
        m = f.metadata
        if v is None or (m.get("omit_empty") and not v) or (m.get("omit_default") and v == f.default):
            continue
        if isinstance(v, Path):  # prediction.catalog
            try:
                v = Path(_relpath(v, cfg.mission)).as_posix()
            except ValueError:
                v = Path(v).as_posix()
        out[f.name] = _toml_value(v)
    return out


def _toml_value(v):
    if _is_table(v):
        return {f.name: _toml_value(getattr(v, f.name)) for f in fields(v) if getattr(v, f.name) is not None}
    if isinstance(v, (tuple, list)):
        return [_toml_value(x) for x in v]
    if isinstance(v, dict):
        return {k: _toml_value(x) for k, x in v.items()}
    return v


def _relpath(p: Path, base: Path) -> str:
    return os.path.relpath(Path(p).resolve(), Path(base).resolve())


def save_config(cfg: AnalysisConfig, path: str | Path) -> Path:
    """Write the config atomically (write new, then replace)."""
    import tomli_w

    path = Path(path)
    text = tomli_w.dumps(to_dict(cfg, relative_to=path.parent))
    return write_atomic(path, text, parents=True)


def default_config(mission_dir: str | Path) -> AnalysisConfig:
    """The config of a mission directory with every key at its default."""
    return AnalysisConfig(mission=Path(mission_dir))


def config_for(target: str | Path) -> AnalysisConfig:
    """The analysis config a face opens for ``target``: a config file, or a mission
    directory (or its ``mission.toml``) with every key at its default. The TUI and the
    headless commands both open what they are given through here."""
    p = Path(target).expanduser()
    if p.is_dir():
        return default_config(p)
    if p.name == "mission.toml" and p.is_file():  # the mission's own file: its directory
        return default_config(p.parent)
    if p.suffix == ".toml" or p.is_file():
        return load_config(p)
    raise ConfigError("no such mission directory or config file", file=p)
