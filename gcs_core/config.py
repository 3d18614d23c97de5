"""The analysis configuration (TOML): one file for the TUI and the headless runs.

Example (every table optional except ``[analysis]``)::

    [analysis]
    mission = "../sample_data/missions/nominal-sunpoint"   # relative to this file
    method = "batch"              # batch | kalman

    [physics]
    stellar_aberration = true
    solar_aberration = true
    sun_parallax = true
    field_model = "igrf"          # igrf | dipole

    [models]                      # observation/transition model per sensor; "off" drops it
    CSS1 = "coarse_sun"
    IRU = "gyro"

    [state]
    effects = ["TAM1.alignment"]  # catalogue effects added to the solve-for set
    exclude = []                  # seed effects held instead
    attitude_sigma_deg = 1.0

    [state.elements."TAM1.bias_x"]
    role = "solve-for"            # solve-for | consider | held
    value = 0.0                   # internal units of the element
    sigma = 200.0

    [filter]
    block_seconds = 600.0
    edit_k = 5.0                  # 0 disables k-sigma editing
    max_iterations = 20

    [diagnosis]
    significance = 0.001          # family-wise, Bonferroni-corrected over candidates
    holdout_fraction = 0.25

    [prediction]
    start = 0.0
    end = 7200.0
    step = 10.0
    gaps = [[1800.0, 2400.0]]
    [[prediction.maneuvers]]
    start = 3000.0
    duration = 600.0
    axis = "yaw"                  # roll | pitch | yaw (Eq 4-36)
    rate_deg_s = 0.1

    [verification]
    requirement_deg = 0.01

Every error names the key and says what is wrong (:class:`~gcs_core.errors.ConfigError`).
"""

from __future__ import annotations

import hashlib
import json
import math
import tomllib
from dataclasses import asdict, dataclass, field, fields, replace
from pathlib import Path
from typing import Any

from gcs_core.errors import ConfigError
from gcs_core.models.base import ROLES

METHODS = ("batch", "kalman")
FIELD_MODELS = ("igrf", "dipole")
AXES = ("roll", "pitch", "yaw")


@dataclass(frozen=True)
class ElementConfig:
    """Override of one state element: role, initial value, a-priori sigma (internal units)."""

    role: str | None = None
    value: float | None = None
    sigma: float | None = None


@dataclass(frozen=True)
class Maneuver:
    """A constant-rate maneuver about one reference axis (Eq 4-35, 4-36)."""

    start: float
    duration: float
    axis: str
    rate_deg_s: float


@dataclass(frozen=True)
class AnalysisConfig:
    """Everything an analysis run needs besides the mission data.

    Attributes
    ----------
    path : where the config was read from (relative paths resolve against its folder).
    mission : mission directory.
    method : ``batch`` (static states, gyro-propagated attitude with Q = 0) or
        ``kalman`` (filter and smoother with gyro process noise).
    physics : always-on physics switches (see :mod:`gcs_core.sidp.prepare`).
    models : sensor -> chosen model type, or ``"off"``.
    effects, exclude : catalogue effect ids added to / removed from the solve-for set.
    elements : element name -> :class:`ElementConfig`.
    attitude_sigma_deg : a-priori sigma of the attitude elements.
    block_seconds, edit_k, max_iterations : FILTR options.
    significance, holdout_fraction : diagnosis options.
    pred_start, pred_end, pred_step, gaps, maneuvers : predictor data plan.
    requirement_deg : VERIF attitude accuracy requirement.
    """

    path: Path | None = None
    mission: Path = Path(".")
    method: str = "batch"
    physics: dict = field(default_factory=lambda: {"stellar_aberration": True, "solar_aberration": True,
                                                   "sun_parallax": True, "field_model": "igrf"})
    models: dict = field(default_factory=dict)
    effects: tuple[str, ...] = ()
    exclude: tuple[str, ...] = ()
    elements: dict = field(default_factory=dict)
    attitude_sigma_deg: float = 1.0
    block_seconds: float = 600.0
    edit_k: float = 5.0
    max_iterations: int = 20
    significance: float = 0.001
    holdout_fraction: float = 0.25
    pred_start: float | None = None
    pred_end: float | None = None
    pred_step: float = 10.0
    gaps: tuple[tuple[float, float], ...] = ()
    maneuvers: tuple[Maneuver, ...] = ()
    requirement_deg: float = 0.01

    # ------------------------------------------------------------------ derived
    def with_changes(self, **kw) -> "AnalysisConfig":
        return replace(self, **kw)

    def digest(self) -> str:
        """A short hash of the settings (provenance of calibrations)."""
        return hashlib.sha256(json.dumps(to_dict(self), sort_keys=True).encode()).hexdigest()[:16]


def _require(cond: bool, key: str, message: str, file) -> None:
    if not cond:
        raise ConfigError(message, file=file, key=key)


def _number(table: dict, key: str, default, file, *, positive=False, lo=None, hi=None, prefix=""):
    full = f"{prefix}{key}"
    if key not in table:
        return default
    v = table[key]
    _require(isinstance(v, (int, float)) and not isinstance(v, bool), full,
             f"must be a number, got {v!r}", file)
    v = float(v)
    _require(math.isfinite(v), full, "must be finite", file)
    if positive:
        _require(v > 0, full, f"must be > 0, got {v}", file)
    if lo is not None:
        _require(v >= lo, full, f"must be ≥ {lo}, got {v}", file)
    if hi is not None:
        _require(v <= hi, full, f"must be ≤ {hi}, got {v}", file)
    return v


def _unknown(table: dict, known: set, prefix: str, file) -> None:
    extra = sorted(set(table) - known)
    if extra:
        raise ConfigError(f"unknown key (known: {', '.join(sorted(known))})", file=file,
                          key=f"{prefix}{extra[0]}")


def load_config(path: str | Path) -> AnalysisConfig:
    """Read and validate an analysis config; errors name the key."""
    path = Path(path)
    if not path.is_file():
        raise ConfigError("config file not found", file=path)
    try:
        data = tomllib.loads(path.read_text(encoding="utf-8"))
    except UnicodeDecodeError:
        raise ConfigError("config file is not UTF-8 text", file=path) from None
    except tomllib.TOMLDecodeError as err:
        raise ConfigError(f"TOML syntax: {err}", file=path) from None
    return config_from_dict(data, path=path)


def config_from_dict(data: dict, *, path: Path | None = None) -> AnalysisConfig:
    f = path
    _unknown(data, {"analysis", "physics", "models", "state", "filter", "diagnosis", "prediction",
                    "verification"}, "", f)
    an = data.get("analysis", {})
    _require(isinstance(an, dict), "analysis", "must be a table", f)
    _unknown(an, {"mission", "method", "name"}, "analysis.", f)
    _require("mission" in an and isinstance(an["mission"], str), "analysis.mission",
             "must name the mission directory (a string)", f)
    base = path.parent if path is not None else Path(".")
    mission = Path(an["mission"])
    if not mission.is_absolute():
        mission = (base / mission)
    method = an.get("method", "batch")
    _require(method in METHODS, "analysis.method", f"must be one of {', '.join(METHODS)}, got {method!r}", f)

    ph = dict(AnalysisConfig().physics)
    phys = data.get("physics", {})
    _unknown(phys, set(ph), "physics.", f)
    for k, v in phys.items():
        if k == "field_model":
            _require(v in FIELD_MODELS, "physics.field_model", f"must be one of {', '.join(FIELD_MODELS)}", f)
        else:
            _require(isinstance(v, bool), f"physics.{k}", "must be true or false", f)
        ph[k] = v

    models = data.get("models", {})
    _require(isinstance(models, dict), "models", "must be a table of sensor = model", f)
    for k, v in models.items():
        _require(isinstance(v, str), f"models.{k}", "must be a model name or \"off\"", f)

    st = data.get("state", {})
    _unknown(st, {"effects", "exclude", "attitude_sigma_deg", "elements"}, "state.", f)
    effects = st.get("effects", [])
    exclude = st.get("exclude", [])
    for key, lst in (("state.effects", effects), ("state.exclude", exclude)):
        _require(isinstance(lst, list) and all(isinstance(e, str) and "." in e for e in lst), key,
                 "must be a list of effect ids like \"TAM1.alignment\"", f)
    elements = {}
    for name, ov in st.get("elements", {}).items():
        pre = f"state.elements.{name}."
        _require(isinstance(ov, dict), f"state.elements.{name}", "must be a table", f)
        _unknown(ov, {"role", "value", "sigma"}, pre, f)
        role = ov.get("role")
        _require(role is None or role in ROLES, pre + "role", f"must be one of {', '.join(ROLES)}", f)
        elements[name] = ElementConfig(role, _number(ov, "value", None, f, prefix=pre),
                                       _number(ov, "sigma", None, f, positive=True, prefix=pre)
                                       if ov.get("sigma") != math.inf else math.inf)
    att_sig = _number(st, "attitude_sigma_deg", 1.0, f, positive=True, prefix="state.")

    fl = data.get("filter", {})
    _unknown(fl, {"block_seconds", "edit_k", "max_iterations"}, "filter.", f)
    dg = data.get("diagnosis", {})
    _unknown(dg, {"significance", "holdout_fraction"}, "diagnosis.", f)
    pr = data.get("prediction", {})
    _unknown(pr, {"start", "end", "step", "gaps", "maneuvers"}, "prediction.", f)
    gaps = pr.get("gaps", [])
    _require(isinstance(gaps, list) and all(isinstance(g, list) and len(g) == 2 and g[0] < g[1] for g in gaps),
             "prediction.gaps", "must be a list of [start, end] pairs with start < end", f)
    mans = []
    for i, m in enumerate(pr.get("maneuvers", [])):
        pre = f"prediction.maneuvers[{i}]."
        _unknown(m, {"start", "duration", "axis", "rate_deg_s"}, pre, f)
        _require(m.get("axis") in AXES, pre + "axis", f"must be one of {', '.join(AXES)}", f)
        mans.append(Maneuver(_number(m, "start", 0.0, f, prefix=pre),
                             _number(m, "duration", 0.0, f, positive=True, prefix=pre),
                             m["axis"], _number(m, "rate_deg_s", 0.0, f, prefix=pre)))
    vf = data.get("verification", {})
    _unknown(vf, {"requirement_deg"}, "verification.", f)
    return AnalysisConfig(
        path=path, mission=mission, method=method, physics=ph, models=dict(models),
        effects=tuple(effects), exclude=tuple(exclude), elements=elements, attitude_sigma_deg=att_sig,
        block_seconds=_number(fl, "block_seconds", 600.0, f, positive=True, prefix="filter."),
        edit_k=_number(fl, "edit_k", 5.0, f, lo=0.0, prefix="filter."),
        max_iterations=int(_number(fl, "max_iterations", 20, f, lo=1, hi=1000, prefix="filter.")),
        significance=_number(dg, "significance", 0.001, f, lo=1e-12, hi=0.5, prefix="diagnosis."),
        holdout_fraction=_number(dg, "holdout_fraction", 0.25, f, lo=0.0, hi=0.9, prefix="diagnosis."),
        pred_start=_number(pr, "start", None, f, prefix="prediction."),
        pred_end=_number(pr, "end", None, f, prefix="prediction."),
        pred_step=_number(pr, "step", 10.0, f, positive=True, prefix="prediction."),
        gaps=tuple((float(a), float(b)) for a, b in gaps), maneuvers=tuple(mans),
        requirement_deg=_number(vf, "requirement_deg", 0.01, f, positive=True, prefix="verification."))


def to_dict(cfg: AnalysisConfig, *, relative_to: Path | None = None) -> dict[str, Any]:
    """The TOML-ready dictionary of a config (paths relative to ``relative_to``)."""
    mission = cfg.mission
    if relative_to is not None:
        try:
            mission = Path(_relpath(cfg.mission, relative_to))
        except ValueError:
            pass
    out: dict[str, Any] = {
        "analysis": {"mission": str(mission), "method": cfg.method},
        "physics": dict(cfg.physics),
        "models": dict(cfg.models),
        "state": {"effects": list(cfg.effects), "exclude": list(cfg.exclude),
                  "attitude_sigma_deg": cfg.attitude_sigma_deg,
                  "elements": {k: {kk: vv for kk, vv in asdict(v).items() if vv is not None}
                               for k, v in cfg.elements.items()}},
        "filter": {"block_seconds": cfg.block_seconds, "edit_k": cfg.edit_k,
                   "max_iterations": cfg.max_iterations},
        "diagnosis": {"significance": cfg.significance, "holdout_fraction": cfg.holdout_fraction},
        "prediction": {"step": cfg.pred_step, "gaps": [list(g) for g in cfg.gaps],
                       "maneuvers": [asdict(m) for m in cfg.maneuvers]},
        "verification": {"requirement_deg": cfg.requirement_deg},
    }
    if cfg.pred_start is not None:
        out["prediction"]["start"] = cfg.pred_start
    if cfg.pred_end is not None:
        out["prediction"]["end"] = cfg.pred_end
    return out


def _relpath(p: Path, base: Path) -> str:
    import os
    return os.path.relpath(Path(p).resolve(), Path(base).resolve())


def save_config(cfg: AnalysisConfig, path: str | Path) -> Path:
    """Write the config atomically (write new, then replace)."""
    import os
    import tempfile

    import tomli_w

    path = Path(path)
    text = tomli_w.dumps(to_dict(cfg, relative_to=path.parent))
    path.parent.mkdir(parents=True, exist_ok=True)
    fd, tmp = tempfile.mkstemp(dir=path.parent, prefix=f".{path.name}.", suffix=".tmp")
    try:
        with os.fdopen(fd, "w", encoding="utf-8") as fh:
            fh.write(text)
            fh.flush()
            os.fsync(fh.fileno())
        os.replace(tmp, path)
    except BaseException:
        if os.path.exists(tmp):
            os.unlink(tmp)
        raise
    return path


def default_config(mission_dir: str | Path) -> AnalysisConfig:
    return AnalysisConfig(mission=Path(mission_dir))
