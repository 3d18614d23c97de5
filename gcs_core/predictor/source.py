"""A plan, read once: the one source ``gcs predict``, ``trade``, ``optimize`` and
``montecarlo`` build their problem from (docs/planning.md).

The seed's predictor plans before any data exist (§3.1, §4.3). A *plan* is an analysis
config whose mission is either a mission directory or, before launch, the config itself:
``[mission]`` and ``[[sensor]]`` tables (the data book, each sensor with its ``cadence``,
field of view and own ``gaps``), an orbit, the ``[prediction]`` span, gaps and slews.
:func:`load_source` reads everything the prediction needs into one :class:`PlanSource`:

* the mission description (:func:`~gcs_core.io.mission.read_mission_spec`; a plan's
  sensors need no telemetry);
* the orbit, one for every command: ``[trade.orbit]`` Kepler elements when given, else
  the mission's ``[orbit] tle`` (its two lines, read here), else the mission's ephemeris
  file (its rows, read here);
* the star catalog of ``stars = "catalog"`` (its stars, read here);
* the base data plan: ``[prediction]``, its span defaulting to one hour from 0 (or from
  ``start``).

Nothing in a :class:`PlanSource` refers to a file again: it is what a cluster's workers
receive (:mod:`gcs_core.trade.engine`), so they need none of the submitting machine's
paths. :func:`predict_source` is the one call that predicts a plan of it.
"""

from __future__ import annotations

import hashlib
import json
from dataclasses import dataclass, replace
from pathlib import Path
from typing import Any

from gcs_core.config import load_config
from gcs_core.config_schema import AnalysisConfig
from gcs_core.errors import InputError
from gcs_core.io.types import MissionSpec, Table
from gcs_core.predictor.plan import DataPlan

#: span of a plan whose [prediction] gives no end [s]
DEFAULT_SPAN_S = 3600.0
#: keys of the [trade.orbit] table (Kepler elements at the mission epoch)
ORBIT_KEYS = ("a_km", "e", "i_deg", "raan_deg", "argp_deg", "mean_anomaly_deg")


@dataclass(frozen=True)
class TleElements:
    """Two-line elements, read; :meth:`table` propagates them over a span (SGP4,
    :func:`gcs_core.io.tle_table.tle_lines_table`)."""

    line1: str
    line2: str
    frame: str = "teme"
    step_s: float = 10.0
    name: str = "TLE"

    def table(self, epoch, t_start: float, t_end: float, margin_s: float) -> Table:
        from gcs_core.io.tle_table import tle_lines_table

        return tle_lines_table(
            self.line1,
            self.line2,
            epoch,
            t_start,
            t_end,
            frame=self.frame,
            step_s=self.step_s,
            margin_s=margin_s,
            tle_file=self.name,
        )


@dataclass(frozen=True)
class PlanSource:
    """Everything a plan's prediction needs (module docstring); picklable, no file paths
    read after it is built.

    Attributes
    ----------
    config : the analysis config (method, state roles, physics, planning tables).
    spec : the mission description.
    plan : the base data plan (``[prediction]``, the sensors' own gaps).
    orbit : :class:`~gcs_core.ephem.orbit.KeplerOrbit`, :class:`TleElements` or None
        (then ``ephemeris`` holds the mission's ephemeris rows).
    ephemeris : the mission's ephemeris table, or None.
    catalog : the star catalog of ``stars = "catalog"``, or None.
    content : hash of the config's settings and the mission description (what the numbers
        depend on, not where the files are).
    """

    config: AnalysisConfig
    spec: MissionSpec
    plan: DataPlan
    orbit: Any = None
    ephemeris: Table | None = None
    catalog: Any = None
    content: str = ""

    def predict(self, plan: DataPlan | None = None, *, config: AnalysisConfig | None = None, spec=None, method=None):
        """:func:`predict_source` of this source."""
        return predict_source(self, plan, config=config, spec=spec, method=method)


def is_plan_file(cfg: AnalysisConfig) -> bool:
    """The config describes its own mission (no mission directory)."""
    return Path(cfg.mission).suffix == ".toml" and Path(cfg.mission).is_file()


def read_spec(cfg: AnalysisConfig) -> MissionSpec:
    """The mission description of a config: its mission directory's, or its own tables."""
    from gcs_core.io.mission import read_mission_spec

    if is_plan_file(cfg):
        return read_mission_spec(cfg.mission, planning=True)
    if not Path(cfg.mission).is_dir():
        raise InputError(f"no mission directory at {cfg.mission}", file=cfg.path, key="analysis.mission")
    return read_mission_spec(cfg.mission)


def base_plan(cfg: AnalysisConfig, spec: MissionSpec) -> DataPlan:
    """``[prediction]`` as a plan, the span defaulting to :data:`DEFAULT_SPAN_S` from its start
    (or 0), with each sensor's own ``gaps``."""
    start = 0.0 if cfg.prediction.start is None else cfg.prediction.start
    plan = DataPlan.from_config(cfg, span=(start, start + DEFAULT_SPAN_S))
    if plan.catalog is not None and not plan.catalog.is_absolute():
        # the config joined it to its mission directory, itself relative to where gcs runs
        plan = replace(plan, catalog=plan.catalog.resolve())
    own = {s.name: tuple(s.get("gaps")) for s in spec.sensors if s.get("gaps")}
    return replace(plan, sensor_gaps=own) if own else plan


def kepler_orbit(orbit, epoch):
    """A :class:`~gcs_core.ephem.orbit.KeplerOrbit` from a ``[trade.orbit]`` table, or None."""
    if not orbit:
        return None
    from gcs_core.ephem.orbit import KeplerOrbit

    if not isinstance(orbit, dict):
        raise InputError("must be a table of Kepler elements", key="trade.orbit")
    missing = [k for k in ORBIT_KEYS if k not in orbit]
    if missing:
        raise InputError(f"missing {', '.join(missing)} (an orbit needs {', '.join(ORBIT_KEYS)})", key="trade.orbit")
    try:
        a_km, e, i_deg, raan_deg, argp_deg, mean_anomaly_deg = (float(orbit[k]) for k in ORBIT_KEYS)
    except (TypeError, ValueError):
        raise InputError("every orbit element must be a number", key="trade.orbit") from None
    return KeplerOrbit(a_km, e, i_deg, raan_deg, argp_deg, mean_anomaly_deg, epoch)


def load_source(cfg: AnalysisConfig | str | Path, *, method: str | None = None) -> PlanSource:
    """Read a plan (module docstring); ``method`` overrides the config's."""
    from gcs_core.config_checks import check_against_mission
    from gcs_core.ephem.tle import read_tle
    from gcs_core.io.csvio import read_table
    from gcs_core.io.importer import EPHEMERIS_COLUMNS
    from gcs_core.predictor.synth import star_catalog

    if not isinstance(cfg, AnalysisConfig):
        cfg = load_config(cfg)
    if method is not None:
        cfg = cfg.with_changes(method=method)
    spec = read_spec(cfg)
    check_against_mission(cfg, spec)
    plan = base_plan(cfg, spec)
    orbit: Any = kepler_orbit((cfg.trade or {}).get("orbit"), spec.epoch)
    eph = None
    if orbit is None and spec.orbit_tle is not None:
        line1, line2 = read_tle(spec.orbit_tle)
        orbit = TleElements(line1, line2, spec.orbit_frame, spec.orbit_step_s, str(spec.orbit_tle))
    elif orbit is None and spec.ephemeris_file is not None:
        eph = read_table(spec.ephemeris_file, required=EPHEMERIS_COLUMNS, what="ephemeris")
    elif orbit is None:
        raise InputError(
            "the plan has no orbit: give [trade.orbit] Kepler elements, an [orbit] tle file or an [ephemeris] file",
            file=cfg.path,
            key="trade.orbit",
        )
    spec = replace(spec, ephemeris_file=None, orbit_tle=None)  # nothing read from disk again
    catalog = None
    if plan.stars == "catalog" and any(s.type == "star_tracker" for s in spec.sensors):
        catalog = star_catalog(spec, plan, {})
    return PlanSource(cfg, spec, plan, orbit, eph, catalog, _content(cfg, spec, orbit, eph, catalog))


def _content(cfg: AnalysisConfig, spec: MissionSpec, orbit, eph, catalog) -> str:
    d = {
        "config": cfg.digest(),
        "trade_orbit": (cfg.trade or {}).get("orbit"),
        "mission": repr((spec.name, spec.epoch.isoformat(), spec.attitude_mode, spec.spin_axis_guess_deg)),
        "sensors": [repr((s.name, s.type, s.alignment_deg, s.noise, sorted(s.book.items()))) for s in spec.sensors],
        "orbit": repr(orbit) if isinstance(orbit, TleElements) else None,  # Kepler: trade_orbit
        "ephemeris": None if eph is None else hashlib.sha256(eph.stack(list(eph.columns)).tobytes()).hexdigest(),
        "catalog": None if catalog is None else len(catalog),
    }
    return hashlib.sha256(json.dumps(d, sort_keys=True, default=str).encode()).hexdigest()[:16]


def predict_source(
    source: PlanSource,
    plan: DataPlan | None = None,
    *,
    config: AnalysisConfig | None = None,
    spec: MissionSpec | None = None,
    method: str | None = None,
):
    """The prediction of ``plan`` (default the source's) with ``config``/``spec`` (default the
    source's; a trade study's plan changes them) and the source's orbit, ephemeris and
    catalog: the one way every planning command predicts."""
    from gcs_core.io.importer import ImportedMission
    from gcs_core.predictor.predict import predict

    cfg = config or source.config
    sp = spec or source.spec
    mission: Any = sp
    if source.ephemeris is not None:
        mission = ImportedMission(spec=sp, ephemeris_table=source.ephemeris, telemetry={})
    return predict(
        cfg,
        mission=mission,
        plan=plan or source.plan,
        orbit=source.orbit,
        method=method,
        catalog=source.catalog,
    )


__all__ = [
    "DEFAULT_SPAN_S",
    "PlanSource",
    "TleElements",
    "base_plan",
    "is_plan_file",
    "kepler_orbit",
    "load_source",
    "predict_source",
    "read_spec",
]
