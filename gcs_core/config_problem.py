"""The calibration problem an analysis config asks for: one place that reads the config's
models, state and physics into a :class:`~gcs_core.problem.build.Problem` (the session's
fits) or into the pieces the predictor builds its plan's problem from.

* :func:`state_options` — the SODL options of ``[state]`` (effects, exclusions, element
  overrides, the attitude's a-priori σ);
* :func:`sensors_off` — the sensors ``[models]`` switches off, each checked against the
  mission;
* :func:`problem_from_config` — the problem of a config on an imported mission.
"""

from __future__ import annotations

from dataclasses import replace

from gcs_core.config_schema import AnalysisConfig
from gcs_core.errors import ConfigError
from gcs_core.io.types import MissionSpec
from gcs_core.problem.build import ElementOverride, Problem, StateOptions, build_problem
from gcs_core.units import DEG


def state_options(cfg: AnalysisConfig | None) -> StateOptions:
    """SODL options of an analysis config's ``[state]`` (the defaults without a config)."""
    if cfg is None:
        return StateOptions()
    ov = {k: ElementOverride(v.role, v.value, v.sigma) for k, v in cfg.state.elements.items()}
    return StateOptions(
        effects=cfg.state.effects,
        exclude=cfg.state.exclude,
        overrides=ov,
        attitude_sigma=cfg.state.attitude_sigma_deg * DEG,
    )


def sensors_off(cfg: AnalysisConfig | None, spec: MissionSpec) -> set[str]:
    """Sensors the config's ``[models]`` switches ``"off"``; a name the mission does not
    have is a :class:`~gcs_core.errors.ConfigError` naming its key."""
    if cfg is None:
        return set()
    names = {s.name for s in spec.sensors}
    for name in cfg.models:
        if name not in names:
            raise ConfigError(f"no sensor named '{name}' in the mission", key=f"models.{name}")
    return {name for name, m in cfg.models.items() if m == "off"}


def problem_from_config(cfg: AnalysisConfig, mission, *, families: dict[str, tuple[str, ...]] | None = None) -> Problem:
    """The problem of ``cfg`` on the imported ``mission``: its sensors less those switched
    off (the gyro off: the attitude is not gyro-carried), its state and its physics;
    ``families``: sensor -> the generic drift families its model carries
    (:mod:`gcs_core.models.drift`)."""
    spec = mission.spec
    off = sensors_off(cfg, spec)
    if off:
        kept = replace(spec, sensors=tuple(s for s in spec.sensors if s.name not in off))
        mission = replace(mission, spec=kept, telemetry={k: v for k, v in mission.telemetry.items() if k not in off})
    gyro_off = any(s.type == "gyro" and s.name in off for s in spec.sensors)
    return build_problem(
        mission, physics=cfg.physics, options=state_options(cfg), use_gyro=not gyro_off, families=families
    )
