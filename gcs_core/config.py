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
    noise_weighting = "long_run"  # correlated (default) | stated | long_run
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

import os
from dataclasses import fields, replace
from pathlib import Path

from gcs_core import toml_values
from gcs_core.config_checks import (
    MODEL_OFF,
    _choice,
    _fail,
    _number,
    _require,
    _table,
    _unknown,
    edit_k_sensor,
    noise_weighting,
    read_prediction,
    read_state,
)
from gcs_core.config_schema import (
    METHODS,
    PLAN_MISSION_TABLES,
    PLANNING_TABLES,
    TABLES,
    AnalysisConfig,
    DiagnosisConfig,
    ElementConfig,
    FilterConfig,
    Maneuver,
    PredictionConfig,
    StateConfig,
    VerificationConfig,
    to_dict,
)
from gcs_core.errors import ConfigError
from gcs_core.fileperm import write_atomic
from gcs_core.inputs import refuse_unreadable
from gcs_core.io.types import SENSOR_TYPES
from gcs_core.problem.prepare import FIELD_MODELS, PhysicsOptions
from gcs_core.suggest import did_you_mean_path
from gcs_core.toml_values import quote as _quote
from gcs_core.toml_values import show as _show

#: table dataclass -> its table's name
_TABLE_OF = {FilterConfig: "filter", DiagnosisConfig: "diagnosis", VerificationConfig: "verification"}


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
    kind = refuse_unreadable(path, "config file", error=ConfigError)
    if kind == "dir":
        _fail(None, "is a directory, not a config file", path)
    if kind != "file":
        _fail(None, f"config file not found{did_you_mean_path(path)}", path)
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
    state = read_state(st, f)

    fl = tables["filter"]
    _unknown(fl, TABLES["filter"], "filter.", f)
    dg = tables["diagnosis"]
    _unknown(dg, TABLES["diagnosis"], "diagnosis.", f)
    pr = tables["prediction"]
    _unknown(pr, TABLES["prediction"], "prediction.", f)
    # a plan file's catalog sits beside the plan, a mission's in its directory
    prediction = read_prediction(pr, mission.parent if plan_file else mission, f)
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
            effects=state["effects"],
            exclude=state["exclude"],
            attitude_sigma_deg=state["attitude_sigma_deg"],
            elements={k: ElementConfig(*v) for k, v in state["elements"].items()},
        ),
        filter=FilterConfig(
            **{k: _read(fl, FilterConfig, k, f) for k in ("block_seconds", "edit_k", "max_iterations")},
            edit_k_sensor=edit_k_sensor(fl, f),
            **noise_weighting(fl, f),
        ),
        diagnosis=DiagnosisConfig(
            **{k: _read(dg, DiagnosisConfig, k, f) for k in ("significance", "holdout_fraction")}
        ),
        prediction=PredictionConfig(
            **{**prediction, "maneuvers": tuple(Maneuver(*m) for m in prediction["maneuvers"])}
        ),
        verification=VerificationConfig(requirement_deg=_read(vf, VerificationConfig, "requirement_deg", f)),
        trade=dict(tables["trade"]),
        montecarlo=dict(tables["montecarlo"]),
    )


def _read(table: dict, cls, key: str, f):
    """A number of table ``cls`` within its field's documented bounds (one source with the reference)."""
    fld = next(x for x in fields(cls) if x.name == key)
    m = fld.metadata
    bounds = {b: m[b] for b in ("positive", "lo", "hi", "integer") if b in m}
    return _number(table, key, fld.default, f, prefix=f"{_TABLE_OF[cls]}.", **bounds)


# ---------------------------------------------------------------------------- writing
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
    if refuse_unreadable(p, "mission directory or config file", error=ConfigError) == "dir":
        return default_config(p)
    if p.name == "mission.toml" and p.is_file():  # the mission's own file: its directory
        return default_config(p.parent)
    if p.suffix == ".toml" or p.is_file():
        return load_config(p)
    raise ConfigError(f"no such mission directory or config file{did_you_mean_path(p)}", file=p)
