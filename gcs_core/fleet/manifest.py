"""The fleet manifest (TOML): which spacecraft, where their data come from, which config.

::

    [fleet]
    name = "demo"                     # a label for the report
    days = ["day1", "day2"]           # the days, in order ({day} in the data paths)
    output = "out"                    # each spacecraft's SCDS and ASF, the reports
    template = "base.toml"            # optional: an analysis config the template starts from
    discover = true                   # also run missing-effect discovery
    max_steps = 3                     # discovery: at most this many additions
    moved_sigma = 3.0                 # a parameter moved: |Δ| > N σ since its last accepted value
    outlier_sigma = 5.0               # a fleet outlier: robust z beyond this

    [template.analysis]               # tables of an analysis config (gcs_core/config.py)
    method = "batch"
    [template.verification]
    requirement_deg = 0.05

    [[spacecraft]]
    name = "SC01"
    data = "data/SC01/{day}"          # the day's mission directory (ICD §1)
    [spacecraft.config.filter]        # overrides of the template for this spacecraft
    edit_k = 4.0

Relative paths resolve against the manifest's folder. Every spacecraft's config (template
plus overrides, the mission set to its data) is checked when the manifest is read, so a
bad key stops the run before any work, as one line naming the key
(``spacecraft[SC01].config.filter.edit_k``) and the manifest.
"""

from __future__ import annotations

import copy
import re
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

from gcs_core import toml_values
from gcs_core.config import config_from_dict
from gcs_core.config_schema import AnalysisConfig
from gcs_core.errors import ConfigError

__all__ = ["Manifest", "Spacecraft", "read_manifest", "FLEET_KEYS", "SPACECRAFT_KEYS"]

FLEET_KEYS = ("name", "days", "output", "template", "discover", "max_steps", "moved_sigma", "outlier_sigma")
SPACECRAFT_KEYS = ("name", "data", "config")
TOP_KEYS = ("fleet", "template", "spacecraft")
_NAME = re.compile(r"^[A-Za-z0-9][A-Za-z0-9_.-]{0,63}$")
#: a stand-in mission directory while the template alone is checked
_PLACEHOLDER = "."


@dataclass(frozen=True)
class Spacecraft:
    """One ``[[spacecraft]]``: its name, its data path (``{day}`` replaced per day) and the
    config tables overriding the template."""

    name: str
    data: str
    overrides: dict = field(default_factory=dict)


@dataclass(frozen=True)
class Manifest:
    """A fleet manifest as read (module docstring)."""

    path: Path
    name: str
    days: tuple[str, ...]
    output: Path
    template: dict
    spacecraft: tuple[Spacecraft, ...]
    discover: bool = True
    max_steps: int = 3
    moved_sigma: float = 3.0
    outlier_sigma: float = 5.0

    def mission_dir(self, sc: Spacecraft, day: str) -> Path:
        """The mission directory of ``sc`` on ``day``."""
        p = Path(sc.data.replace("{day}", day)).expanduser()
        return p if p.is_absolute() else (self.path.parent / p)

    def config(self, sc: Spacecraft, day: str) -> AnalysisConfig:
        """The analysis config of ``sc`` on ``day``: the template, its overrides, its data."""
        return _config(self, sc, str(self.mission_dir(sc, day)))

    def spacecraft_named(self, name: str) -> Spacecraft:
        for sc in self.spacecraft:
            if sc.name == name:
                return sc
        raise KeyError(name)


def _fail(path: Path, key: str, message: str) -> ConfigError:
    return ConfigError(message, file=path, key=key)


def _merge(base: dict, over: dict) -> dict:
    """``over``'s tables merged key by key into a copy of ``base``."""
    out = copy.deepcopy(base)
    for k, v in over.items():
        if isinstance(v, dict) and isinstance(out.get(k), dict):
            out[k] = _merge(out[k], v)
        else:
            out[k] = copy.deepcopy(v)
    return out


def _checked(doc: dict, path: Path, prefix: str) -> AnalysisConfig:
    """``config_from_dict`` with a failing key named where it is written in the manifest."""
    try:
        return config_from_dict(doc, path=path)
    except ConfigError as err:
        key = f"{prefix}.{err.key}" if err.key else prefix
        raise ConfigError(err.message, file=path, key=key) from None


def _config(m: Manifest, sc: Spacecraft, mission: str) -> AnalysisConfig:
    doc = _merge(m.template, sc.overrides)
    doc.setdefault("analysis", {})["mission"] = mission
    return _checked(doc, m.path, f"spacecraft[{sc.name}].config")


def _number(t: dict, key: str, default: float, path: Path, *, lo: float, whole: bool = False) -> Any:
    v = t.get(key, default)
    ok = toml_values.is_number(v) and float(v) >= lo and (not whole or float(v) == int(v))
    if not ok or v != v:
        kind = "a whole number" if whole else "a number"
        raise _fail(path, f"fleet.{key}", f"must be {kind} ≥ {lo:g}, not {toml_values.show(v)}")
    return int(v) if whole else float(v)


def _fleet_table(doc: dict, path: Path) -> dict:
    fl = doc.get("fleet", {})
    if not isinstance(fl, dict):
        raise _fail(path, "fleet", "must be a table")
    for k in fl:
        if k not in FLEET_KEYS:
            raise _fail(path, f"fleet.{k}", f"unknown key (known: {', '.join(FLEET_KEYS)})")
    return fl


def _days(fl: dict, path: Path) -> tuple[str, ...]:
    days = fl.get("days")
    if not isinstance(days, list) or not days:
        raise _fail(path, "fleet.days", 'missing or empty: list the days, e.g. days = ["2024-05-14"]')
    for i, d in enumerate(days, start=1):
        if not isinstance(d, str) or not _NAME.match(d):
            raise _fail(
                path, f"fleet.days[{i}]", f"must be a short name of letters, digits, -_. not {toml_values.show(d)}"
            )
    if len(set(days)) != len(days):
        raise _fail(path, "fleet.days", "holds a day twice")
    return tuple(days)


def _template(fl: dict, doc: dict, path: Path) -> dict:
    base: dict = {}
    if "template" in fl:
        t = fl["template"]
        if not isinstance(t, str) or not t.strip():
            raise _fail(path, "fleet.template", f"must be an analysis config's path, not {toml_values.show(t)}")
        tp = Path(t).expanduser()
        tp = tp if tp.is_absolute() else path.parent / tp
        if not tp.is_file():
            raise _fail(path, "fleet.template", f"no such config file: {tp}")
        base = toml_values.loads(toml_values.decode(tp.read_bytes(), tp, ConfigError), tp, ConfigError)
        base.get("analysis", {}).pop("mission", None)  # each spacecraft's data replace it
    inline = doc.get("template", {})
    if not isinstance(inline, dict):
        raise _fail(path, "template", "must be a table of analysis-config tables")
    tmpl = _merge(base, inline)
    if isinstance(tmpl.get("analysis"), dict) and "mission" in tmpl["analysis"]:
        raise _fail(path, "template.analysis.mission", "each spacecraft's data name its mission: leave it out")
    check = _merge(tmpl, {"analysis": {"mission": _PLACEHOLDER}})
    _checked(check, path, "template")
    return tmpl


def _spacecraft(doc: dict, path: Path) -> tuple[Spacecraft, ...]:
    lst = doc.get("spacecraft")
    if not isinstance(lst, list) or not lst:
        raise _fail(path, "spacecraft", "missing: give one [[spacecraft]] table per spacecraft (name, data)")
    out, seen = [], set()
    for i, t in enumerate(lst, start=1):
        where = f"spacecraft[{i}]"
        if not isinstance(t, dict):
            raise _fail(path, where, "must be a table (name, data, config)")
        name = t.get("name")
        if not isinstance(name, str) or not _NAME.match(name):
            raise _fail(
                path, f"{where}.name", f"must be a short name of letters, digits, -_. not {toml_values.show(name)}"
            )
        if name in seen:
            raise _fail(path, f"{where}.name", f"spacecraft '{name}' is named twice")
        seen.add(name)
        for k in t:
            if k not in SPACECRAFT_KEYS:
                raise _fail(path, f"spacecraft[{name}].{k}", f"unknown key (known: {', '.join(SPACECRAFT_KEYS)})")
        data = t.get("data")
        if not isinstance(data, str) or not data.strip():
            raise _fail(path, f"spacecraft[{name}].data", 'missing: the mission directory, e.g. "data/SC01/{day}"')
        over = t.get("config", {})
        if not isinstance(over, dict):
            raise _fail(path, f"spacecraft[{name}].config", "must be a table of analysis-config tables")
        if isinstance(over.get("analysis"), dict) and "mission" in over["analysis"]:
            raise _fail(
                path, f"spacecraft[{name}].config.analysis.mission", "the data key names the mission: leave it out"
            )
        out.append(Spacecraft(name, data, over))
    return tuple(out)


def read_manifest(path: str | Path) -> Manifest:
    """Read and check a fleet manifest (module docstring); one :class:`ConfigError` naming
    the key and the manifest for the first problem found."""
    path = Path(path).expanduser()
    if not path.is_file():
        raise ConfigError("no such fleet manifest", file=path)
    path = path.resolve()  # the data, template and output resolve against its folder
    doc = toml_values.loads(toml_values.decode(path.read_bytes(), path, ConfigError), path, ConfigError)
    for k in doc:
        if k not in TOP_KEYS:
            raise _fail(path, k, f"unknown table (known: {', '.join(TOP_KEYS)})")
    fl = _fleet_table(doc, path)
    name = fl.get("name", path.stem)
    if not isinstance(name, str):
        raise _fail(path, "fleet.name", f"must be a string, not {toml_values.show(name)}")
    out = fl.get("output", "fleet-out")
    if not isinstance(out, str) or not out.strip():
        raise _fail(path, "fleet.output", f"must be a folder's path, not {toml_values.show(out)}")
    output = Path(out).expanduser()
    discover = fl.get("discover", True)
    if not isinstance(discover, bool):
        raise _fail(path, "fleet.discover", f"must be true or false, not {toml_values.show(discover)}")
    m = Manifest(
        path=path,
        name=name,
        days=_days(fl, path),
        output=output if output.is_absolute() else path.parent / output,
        template=_template(fl, doc, path),
        spacecraft=_spacecraft(doc, path),
        discover=discover,
        max_steps=_number(fl, "max_steps", 3, path, lo=1, whole=True),
        moved_sigma=_number(fl, "moved_sigma", 3.0, path, lo=0.0),
        outlier_sigma=_number(fl, "outlier_sigma", 5.0, path, lo=0.0),
    )
    for sc in m.spacecraft:  # every spacecraft's config, before any work
        _config(m, sc, _PLACEHOLDER)
    return m
