"""The analyst's session as the screens see it — no Textual here.

A :class:`Workbench` holds one :class:`gcs_core.session.Analysis` and the results the
screens draw (fit, ranking, FILTR blocks, prediction, verification). Every method
that computes is synchronous and may take seconds; the app calls them from thread
workers and the screens read the attributes afterwards. Results are swapped in by
plain attribute assignment at the end of each method, so a screen never sees half of
an update.

Changing the config (models, roles, σ, physics, plan) rebuilds the analysis from the
config and the already-imported mission; a fit is always a fresh fit of the current
config, which is why a config saved from the TUI reproduces the TUI's numbers when
run headless (``Analysis(load_config(path)).fit()``).
"""

from __future__ import annotations

import copy
import logging
import math
from collections.abc import Callable
from dataclasses import dataclass, replace
from pathlib import Path
from types import EllipsisType
from typing import Any

from gcs_core.config import config_for, fit_key, save_config
from gcs_core.config_schema import METHODS, AnalysisConfig, ElementConfig
from gcs_core.errors import ConfigError
from gcs_core.problem.prepare import PHYSICS_EFFECTS
from gcs_core.problem.state import ROLES
from gcs_core.session import Analysis
from gcs_tui.tui import paths
from gcs_tui.tui.derive import segments

log = logging.getLogger(__name__)

Progress = Callable[[float, float | None, str], None]
"""``progress(done, total, text)`` callback handed to long methods."""


@dataclass(frozen=True)
class SensorRow:
    """One line of the Mission screen.

    Attributes
    ----------
    name, type : sensor name and ICD type; model : chosen model (type or ``off``).
    samples : telemetry rows kept; t0, t1 : first and last time [s]; cadence : median step [s].
    spans : contiguous ``(t0, t1)`` spans; dropped_nan, dropped_duplicates : rows dropped on import.
    """

    name: str
    type: str
    model: str
    samples: int
    t0: float
    t1: float
    cadence: float
    spans: tuple[tuple[float, float], ...]
    dropped_nan: int
    dropped_duplicates: int

    @property
    def gaps(self) -> int:
        return max(len(self.spans) - 1, 0)


@dataclass(frozen=True)
class ModelRow:
    """One line of the Models screen: a sensor's model or a physics option."""

    key: str
    kind: str
    """``sensor``, ``physics`` or ``method``."""
    label: str
    value: str
    choices: tuple[str, ...]


class Workbench:
    """One analysis session and everything computed from it (module docstring).

    Attributes
    ----------
    analysis : the current :class:`Analysis` (None before a mission is opened).
    save_path : where ``config: save`` writes by default.
    filtr : the FILTR runner (:class:`gcs_tui.tui.filtr_run.FiltrRun`) or None.
    prediction : the latest predictor result, or None.
    verification : the latest VERIF result, or None.
    fitted_config : digest of the config of the latest fit ('' before any).
    scds_path : the calibration history file (None: the engine's default for the analysis).
    out_dir : where files the user did not name go (None: :meth:`work_dir` decides).
    """

    def __init__(
        self,
        analysis: Analysis | None = None,
        *,
        save_path: str | Path | None = None,
        scds_path: str | Path | None = None,
    ):
        self.analysis = analysis
        self.save_path = Path(save_path) if save_path else None
        self.scds_path = Path(scds_path) if scds_path else None
        self.filtr = None
        self.prediction = None
        self.verification = None
        self.fitted_config = ""
        self.out_dir: Path | None = None
        self._saved = analysis_key(analysis.config) if analysis is not None else ""
        if analysis is not None and analysis.result is not None:
            self.fitted_config = fit_key(analysis.config)

    # ------------------------------------------------------------------ opening
    @classmethod
    def open(
        cls, path: str | Path, *, save_path: str | Path | None = None, scds_path: str | Path | None = None
    ) -> Workbench:
        """Import the mission of ``path`` (config or mission directory); no fit yet."""
        wb = cls(save_path=save_path, scds_path=scds_path)
        wb.load(path)
        return wb

    def load(self, path: str | Path) -> None:
        cfg = config_for(path)
        analysis = Analysis(cfg)
        self.fitted_config = ""
        self._replace(analysis, keep_steps=False)  # a new mission: a new history
        self._saved = analysis_key(cfg)

    def _replace(self, analysis: Analysis, *, keep_steps: bool = True) -> None:
        if keep_steps and self.analysis is not None:
            analysis.steps = list(self.analysis.steps)
        self.analysis = analysis
        self.filtr = None
        self.prediction = None
        self.verification = None

    # ------------------------------------------------------------------ views
    @property
    def ready(self) -> bool:
        return self.analysis is not None

    @property
    def current(self) -> Analysis:
        """The open analysis (what every view below reads; a mission must be open)."""
        if self.analysis is None:
            raise ConfigError("no mission is open")
        return self.analysis

    @property
    def config(self) -> AnalysisConfig:
        return self.current.config

    @property
    def mission(self):
        return self.current.mission

    @property
    def result(self):
        return self.analysis.result if self.analysis is not None else None

    @property
    def unsaved(self) -> bool:
        """True when the config has edits not yet saved to a file (``q`` asks then)."""
        return self.ready and analysis_key(self.config) != self._saved

    def work_dir(self) -> Path:
        """Where files the user did not name go (config, SCDS, screenshots): :attr:`out_dir`
        (``gcs tui --out``) if set, else the folder of the analysis config that was opened
        or saved, else the folder that holds the mission directory; when that folder is
        bundled with GCS (``sample_data/``), ``./out`` instead, so that nothing is written
        among the bundled files."""
        if self.out_dir is not None:
            return Path(self.out_dir).expanduser().resolve()
        folder = Path.cwd()
        if self.ready and self.config.path is not None:
            folder = Path(self.config.path).resolve().parent
        elif self.ready:
            folder = Path(self.mission.spec.root).resolve().parent
        return Path.cwd().resolve() / "out" if paths.protected(folder) else folder

    def default_save_path(self) -> Path:
        """Where ``ctrl+s`` proposes to save: the file saved to before in this session, else
        the config that was opened (in :meth:`work_dir`), else the mission's name made safe
        (:func:`~gcs_tui.tui.paths.safe_stem`) — never a file bundled with GCS or tracked by
        git (a free ``<stem>-N.toml`` beside it then)."""
        if self.save_path is not None:
            return self.save_path.expanduser().resolve()
        cfg_path = self.config.path if self.ready else None
        if cfg_path is not None:
            target = self.work_dir() / paths.inside(Path("."), Path(cfg_path).stem, ".toml").name
        else:
            target = paths.inside(self.work_dir(), self.mission.name if self.ready else "gcs", ".toml")
        if target.exists() and paths.protected(target):
            target = paths.free_name(target)
        return target

    @property
    def stale(self) -> bool:
        """True when the config changed since the latest fit."""
        return self.result is None or self.fitted_config != fit_key(self.config)

    def sensor_rows(self) -> list[SensorRow]:
        """Every sensor of the mission with its telemetry counts and spans."""
        m = self.mission
        rows = []
        for s in m.spec.sensors:
            tab = m.telemetry[s.name]
            spans, cadence = segments(tab.t)
            try:
                fc = m.report.file(f"telemetry {s.name}")
                dn, dd = fc.dropped_nan, fc.dropped_duplicates
            except KeyError:
                dn, dd = tab.dropped_nan, tab.dropped_duplicates
            t0 = float(tab.t[0]) if len(tab) else math.nan
            t1 = float(tab.t[-1]) if len(tab) else math.nan
            rows.append(
                SensorRow(
                    s.name,
                    s.type,
                    self.config.models.get(s.name, s.type),
                    len(tab),
                    t0,
                    t1,
                    cadence,
                    tuple(spans),
                    dn,
                    dd,
                )
            )
        return rows

    def model_rows(self) -> list[ModelRow]:
        """Sensor models (type or off), physics switches and the estimation method."""
        cfg = self.config
        rows = [
            ModelRow(s.name, "sensor", s.name, cfg.models.get(s.name, s.type), (s.type, "off"))
            for s in self.mission.spec.sensors
        ]
        for opt, (on, off) in PHYSICS_EFFECTS.items():
            val = getattr(cfg.physics, opt)
            choices = (on, off)
            rows.append(ModelRow(opt, "physics", opt.replace("_", " "), _show(val), tuple(_show(c) for c in choices)))
        rows.append(ModelRow("method", "method", "method", cfg.method, METHODS))
        return rows

    def aux_channels(self) -> list[str]:
        aux = self.mission.aux
        return [c for c in aux.columns if c != "t"] if aux is not None else []

    # ------------------------------------------------------------------ config edits
    def set_config(self, cfg: AnalysisConfig) -> None:
        """Rebuild the analysis for ``cfg`` (same imported mission); results are dropped."""
        analysis = Analysis(cfg, mission=self.mission)
        self._replace(analysis)

    def set_model(self, key: str, value: str) -> None:
        """Set a sensor's model (its type or ``off``), a physics option or the method."""
        cfg = self.config
        rows = {r.key: r for r in self.model_rows()}
        if key not in rows:
            raise ConfigError(f"no sensor or option named '{key}'", key=f"models.{key}")
        row = rows[key]
        if value not in row.choices:
            raise ConfigError(f"must be one of {', '.join(row.choices)}", key=f"models.{key}")
        if row.kind == "sensor":
            models = dict(cfg.models)
            models[key] = value
            cfg = replace(cfg, models=models)
        elif row.kind == "physics":
            on, off = PHYSICS_EFFECTS[key]
            cfg = cfg.with_changes(physics={key: on if value == _show(on) else off})
        else:
            cfg = replace(cfg, method=value)
        self.set_config(cfg)

    def cycle_model(self, key: str) -> None:
        row = {r.key: r for r in self.model_rows()}[key]
        i = row.choices.index(row.value) if row.value in row.choices else -1
        self.set_model(key, row.choices[(i + 1) % len(row.choices)])

    def set_element(
        self, name: str, *, role: str | None = None, value: float | None = None, sigma: float | None = None
    ) -> None:
        """Override an element's role, a-priori value or σ (internal units) in the config."""
        if name not in self.current.problem.state:
            raise ConfigError(f"no state element named '{name}'", key=f"state.elements.{name}")
        if role is not None and role not in ROLES:
            raise ConfigError(f"must be one of {', '.join(ROLES)}", key=f"state.elements.{name}.role")
        if sigma is not None and not (sigma > 0):
            raise ConfigError(f"must be > 0, got {sigma}", key=f"state.elements.{name}.sigma")
        if value is not None and not math.isfinite(value):
            raise ConfigError("must be finite", key=f"state.elements.{name}.value")
        cfg = self.config
        old = cfg.state.elements.get(name, ElementConfig())
        new = ElementConfig(
            role if role is not None else old.role,
            value if value is not None else old.value,
            sigma if sigma is not None else old.sigma,
        )
        elements = dict(cfg.state.elements)
        elements[name] = new
        self.set_config(cfg.with_changes(state={"elements": elements}))

    def set_plan(
        self,
        *,
        start: float | EllipsisType | None = ...,
        end: float | EllipsisType | None = ...,
        step: float | None = None,
        gaps: tuple | None = None,
        maneuvers: tuple | None = None,
    ) -> None:
        """Change the predictor's data plan (``...`` leaves a field as it is)."""
        cfg = self.config
        kw: dict[str, Any] = {}
        if start is not ...:
            kw["start"] = start
        if end is not ...:
            kw["end"] = end
        if step is not None:
            if not step > 0:
                raise ConfigError(f"must be > 0, got {step}", key="prediction.step")
            kw["step"] = float(step)
        if gaps is not None:
            for g in gaps:
                if not g[0] < g[1]:
                    raise ConfigError("a gap needs start < end", key="prediction.gaps")
            kw["gaps"] = tuple(sorted((float(a), float(b)) for a, b in gaps))
        if maneuvers is not None:
            kw["maneuvers"] = tuple(sorted(maneuvers, key=lambda m: m.start))
        s = kw.get("start", cfg.prediction.start)
        e = kw.get("end", cfg.prediction.end)
        if s is not None and e is not None and not e > s:
            raise ConfigError("the plan needs end > start", key="prediction.end")
        # the plan does not change the fit: keep the analysis, swap the config only
        self.current.config = cfg.with_changes(prediction=kw)
        self.prediction = None

    def plan_span(self) -> tuple[float, float]:
        """The plan's (start, end), defaulting to the telemetry span."""
        t0, t1 = self.mission.span()
        cfg = self.config
        return (
            cfg.prediction.start if cfg.prediction.start is not None else t0,
            cfg.prediction.end if cfg.prediction.end is not None else t1,
        )

    def save_config(self, path: str | Path | None = None) -> Path:
        """Write the config to ``path`` (default :meth:`default_save_path`; its folder is
        created). The caller asks before replacing a file (the app does)."""
        path = Path(path).expanduser() if path else self.default_save_path()
        out = save_config(self.config, path)
        self.save_path = out
        self.current.config = replace(self.config, path=out)
        self._saved = analysis_key(self.config)
        return out

    # ------------------------------------------------------------------ fitting
    def fit(self, progress: Progress | None = None, cancelled: Callable[[], bool] | None = None) -> Analysis | None:
        """A fresh fit of the current config, the held-out score, the residual-structure
        search (its families become candidates, as discovery offers them) and the ranking.

        The new analysis replaces the current one only when it is complete and not
        ``cancelled()``; returns it (None when cancelled).
        """
        say = progress or (lambda *a: None)
        stop = cancelled or (lambda: False)
        old = self.current
        say(0, 4, "building the state")
        fresh = Analysis(old.config, mission=old.mission)
        fresh.steps = list(old.steps)
        say(1, 4, fit_stage(fresh))
        fresh.fit()
        if not fresh.steps:
            fresh.first_step()
        if stop():
            return None
        say(2, 4, "residual structure; ranking the candidate effects")
        fresh.structure(offer=True)  # the families of what the residuals follow are candidates too
        fresh.rank()
        say(3, 4, "goodness of fit")
        fresh.goodness()  # the χ² tests, formed here rather than on the UI thread
        if stop():
            return None
        say(4, 4, "done")
        self.fitted_config = fit_key(fresh.config)
        self._replace(fresh, keep_steps=False)
        return fresh

    def change_effect(
        self, effect_id: str, add: bool, progress: Progress | None = None, cancelled: Callable[[], bool] | None = None
    ):
        """Add (or remove) a catalogue effect, refit and re-rank; returns the Step.

        Works on a copy of the analysis that replaces the current one only when done
        and not ``cancelled()`` (None is returned then).
        """
        say = progress or (lambda *a: None)
        stop = cancelled or (lambda: False)
        a = copy.copy(self.current)
        a.steps = list(a.steps)
        a.offered = dict(a.offered)  # the search may offer more: not on the analysis shown
        if a.result is None:
            say(0, 3, "first fit")
            a.fit()
        if not a.steps:
            a.first_step()
        say(1, 3, ("adding " if add else "removing ") + effect_id)
        step = a.add_effect(effect_id) if add else a.remove_effect(effect_id)
        if stop():
            return None
        say(2, 3, "ranking candidates")
        a.structure(offer=True)  # families of what the residuals follow, as discovery offers them
        a.rank()
        a.goodness()
        if stop():
            return None
        say(3, 3, "done")
        self.fitted_config = fit_key(a.config)
        self._replace(a, keep_steps=False)
        return step

    def removable_effects(self) -> list[str]:
        """Effects in the state that can be removed (every one but the attitude)."""
        return [e for e in self.current.effects_in_state() if not e.endswith(".attitude")]

    def not_determined(self) -> dict[str, str]:
        """Solve-for elements the latest fit did not determine, with the reason."""
        return {} if self.result is None or self.stale else self.current.not_determined()

    def set_by_prior(self) -> dict[str, str]:
        """Solve-for elements the a priori set rather than the data, with the reason."""
        return {} if self.result is None or self.stale else self.current.set_by_prior()

    def goodness(self):
        """The goodness-of-fit tests and verdict of the latest fit (None before one)."""
        return None if self.result is None or self.stale else self.current.goodness()

    def estimates(self) -> dict[str, tuple[float, float]]:
        """Solve-for element -> (estimate, σ) of the latest fit."""
        res = self.result
        if res is None:
            return {}
        sig = res.sigma
        return {n: (res.state[n].value, sig[n]) for n in res.solve_for}


def fit_stage(a: Analysis) -> str:
    """What the progress line says while ``a`` fits: the method, the state's size and, on a
    cold start, that the numerical kernels are compiling (once; ``gcs warmup`` does it)."""
    from gcs_core.warmup import cold_start

    if cold_start():
        return "first use: compiling the numerical kernels (about 30 s, once; gcs warmup does it ahead), then fitting"
    return f"fitting ({a.config.method}, {len(a.problem.state.solve_for)} solve-for elements)"


def analysis_key(cfg: AnalysisConfig) -> str:
    """Digest of everything a saved config file holds (not where it is saved)."""
    return replace(cfg, path=None).digest()


def _show(v) -> str:
    if v is True:
        return "on"
    if v is False:
        return "off"
    return str(v)
