"""Attitude and sensor-bias accuracy prediction without data (seed §3.1, §3.2, §4.3).

"The first function requires a predictor which predicts the attitude and sensor bias
determination accuracies achievable under various geometrical conditions" (§3.1).
:func:`predict` takes a mission description, an ephemeris and a data plan, builds the
calibration's own Problem from frame times only (:mod:`.synth`), evaluates every
model's partials at the nominal state and accumulates information over time:

* static states (method ``"information"``, the batch estimator's setting):
  ``P(t) = (P̄⁻¹ + Σ_{t_k≤t} Hᵀ R⁻¹ H)⁻¹`` (Eq 3-2, :mod:`.information`);
* a gyro-carried attitude with process noise (method ``"kalman"``): the covariance
  recursion of Eq 3-4 (:mod:`.kalman`);
* the whole-span fit's final covariance (method ``"whole_span"``, the default fit's).

What each method does is read from :mod:`.methods`, never from its name.

Elements with role ``consider`` add ``S P_c Sᵀ``; the result carries the σ contribution
of each of them to every solve-for element and the noise-only part (an error budget).
"""

from __future__ import annotations

import logging
from collections.abc import Mapping
from dataclasses import dataclass
from typing import Any, Protocol, runtime_checkable

import numpy as np

from gcs_core.config_problem import sensors_off, state_options
from gcs_core.config_schema import AnalysisConfig
from gcs_core.ephem.ephemeris import Ephemeris
from gcs_core.ephem.orbit import build_ephemeris
from gcs_core.errors import InputError
from gcs_core.estimators.batch.least_squares import name_combinations
from gcs_core.estimators.registry import estimator
from gcs_core.estimators.whole_span.grid import process_noise
from gcs_core.estimators.whole_span.uses import predicted_covariance
from gcs_core.io.csvio import read_table
from gcs_core.io.importer import EPHEMERIS_COLUMNS, ImportedMission, load_mission
from gcs_core.io.tle_table import tle_ephemeris_table
from gcs_core.io.types import MissionSpec
from gcs_core.predictor import information as info
from gcs_core.predictor.kalman import kalman_history
from gcs_core.predictor.magnitude import magnitude_rows, magnitude_sensors
from gcs_core.predictor.methods import PredictionMethod, prediction_method
from gcs_core.predictor.plan import DataPlan
from gcs_core.predictor.synth import PlannedProblem, median_step, plan_problem
from gcs_core.problem.attitude import RPY
from gcs_core.problem.build import Problem
from gcs_core.problem.gyro_attitude import GyroAttitude
from gcs_core.problem.linearization import linearize
from gcs_core.problem.prepare import PhysicsOptions

log = logging.getLogger(__name__)

#: margin of an orbit-built ephemeris beyond the plan span [s] (time-tag and crossing shifts)
EPHEMERIS_MARGIN_S = 120.0
#: an element whose predicted σ is within this fraction of its a priori is "undetermined"
UNDETERMINED_FRACTION = 0.01


@runtime_checkable
class ConfiguredAnalysis(Protocol):
    """What :func:`predict` reads of an analysis (:class:`gcs_core.session.Analysis`): its
    config and its loaded mission."""

    config: AnalysisConfig
    mission: Any


@dataclass(frozen=True)
class PredictionResult:
    """Predicted accuracies of a data plan, with the error budget.

    Attributes
    ----------
    times : (T,) output times [s since epoch].
    names : the n solve-for elements; units : their units.
    sigma : (T, n) predicted 1-σ, noise and consider elements together.
    sigma_noise : (T, n) noise-only 1-σ (data noise and a priori).
    attitude_sigma : (T, 3) 1-σ attitude error at each output time about the body axes
        [rad] (spinning missions: of the spin-axis unit-vector components).
    P : (n, n) final noise-only covariance; P_consider : (n, n) with consider elements.
    consider : consider element names.
    budget : consider element -> (n,) its 1-σ contribution to each solve-for element.
    noise_only : (n,) final noise-only 1-σ.
    availability : sensor -> fraction of the plan's cadence slots with a usable frame.
    frames : sensor -> number of usable frames.
    method : ``"information"`` (Eq 3-2), ``"kalman"`` (Eq 3-4) or ``"whole_span"`` (Eq 3-2's
        history, the final covariance the whole-span fit's).
    plan : the data plan.
    unobservable : combinations of elements the data cannot separate (final time).
    prior : (n,) a-priori 1-σ of the solve-for elements.
    warnings : the batch method's computed warning (:func:`batch_warning`), if any.
    """

    times: np.ndarray
    names: tuple[str, ...]
    units: tuple[str, ...]
    sigma: np.ndarray
    sigma_noise: np.ndarray
    attitude_sigma: np.ndarray
    P: np.ndarray
    P_consider: np.ndarray
    consider: tuple[str, ...]
    budget: Mapping[str, np.ndarray]
    noise_only: np.ndarray
    availability: Mapping[str, float]
    frames: Mapping[str, int]
    method: str
    plan: DataPlan | None = None
    unobservable: tuple[str, ...] = ()
    prior: np.ndarray | None = None
    warnings: tuple[str, ...] = ()

    def index(self, name: str) -> int:
        try:
            return self.names.index(name)
        except ValueError:
            raise KeyError(f"'{name}' is not a solve-for element of this prediction") from None

    def sigma_of(self, name: str, *, noise_only: bool = False) -> np.ndarray:
        """(T,) σ history of one element."""
        return (self.sigma_noise if noise_only else self.sigma)[:, self.index(name)]

    @property
    def undetermined(self) -> tuple[str, ...]:
        """Elements the plan does not determine: a final noise-only σ within
        :data:`UNDETERMINED_FRACTION` of the a priori (the data add under about 2 % of the
        prior information). A post-fit σ of such an element mirrors its a priori and the
        state the fit is linearized at (e.g. a sine frequency whose amplitude is nominally
        zero), not the data plan."""
        if self.prior is None:
            return ()
        ok = np.isfinite(self.prior) & (self.noise_only >= (1.0 - UNDETERMINED_FRACTION) * self.prior)
        return tuple(n for n, u in zip(self.names, ok) if u)

    @property
    def final_sigma(self) -> dict[str, float]:
        """Element -> final total 1-σ."""
        return {n: float(s) for n, s in zip(self.names, self.sigma[-1])}

    def as_report(self) -> dict[str, Any]:
        """JSON-ready summary: final σ, budget, availability, frames (internal units;
        an infinite σ becomes None)."""
        num = lambda x: float(x) if np.isfinite(x) else None
        return {
            "method": self.method,
            "plan": None
            if self.plan is None
            else {
                "start": self.plan.start,
                "end": self.plan.end,
                "step": self.plan.step,
                "gaps": [list(g) for g in self.plan.gaps],
                "frames": self.plan.frames,
                "stars": self.plan.stars,
                "catalog": None if self.plan.catalog is None else str(self.plan.catalog),
                "maneuvers": [
                    {"start": m.start, "duration": m.duration, "axis": m.axis, "rate_deg_s": m.rate_deg_s}
                    for m in self.plan.maneuvers
                ],
            },
            "state": [
                {
                    "name": r["name"],
                    "unit": r["unit"],
                    "sigma": num(r["sigma"]),
                    "noise_only": num(r["noise_only"]),
                    "consider": {c: num(v) for c, v in r["consider"].items()},
                }
                for r in self.budget_rows()
            ],
            "attitude_sigma_rad": [num(x) for x in self.attitude_sigma[-1]],
            "availability": {k: float(v) for k, v in self.availability.items()},
            "frames": dict(self.frames),
            "unobservable": list(self.unobservable),
            "undetermined": list(self.undetermined),
            "warnings": list(self.warnings),
        }

    def budget_rows(self) -> list[dict[str, Any]]:
        """One row per solve-for element: total, noise-only and each consider contribution."""
        return [
            {
                "name": n,
                "unit": u,
                "sigma": float(self.sigma[-1, i]),
                "noise_only": float(self.noise_only[i]),
                "consider": {c: float(v[i]) for c, v in self.budget.items()},
            }
            for i, (n, u) in enumerate(zip(self.names, self.units))
        ]


# ----------------------------------------------------------------------------------------
def _method(method: str | None, cfg: AnalysisConfig | None) -> PredictionMethod:
    if method is None:
        method = "information" if cfg is None else estimator(cfg.method).prediction
    return prediction_method(method)


def _checks_batch(method: PredictionMethod, cfg: AnalysisConfig | None) -> bool:
    """The plan is predicted, by a method that leaves out the gyro's process noise, for the
    configured estimator whose own method that is (the batch): its σ are then compared with
    the whole-span σ (:func:`batch_warning`)."""
    return cfg is not None and method.leaves_out_process_noise and estimator(cfg.method).prediction == method.name


def _mission_parts(source, mission, cfg):
    """(spec, telemetry, ephemeris table, aux, onboard) of whatever was given."""
    m = mission
    if m is None and cfg is not None:
        m = load_mission(cfg.mission)
    if m is None:
        m = source
    if isinstance(m, ImportedMission):
        return m.spec, dict(m.telemetry), m.ephemeris_table, m.aux, m.onboard
    if isinstance(m, MissionSpec):
        eph_table = None
        if m.ephemeris_file is not None and m.ephemeris_file.is_file():
            eph_table = read_table(m.ephemeris_file, required=EPHEMERIS_COLUMNS, what="ephemeris")
        return m, {}, eph_table, None, None
    raise InputError(
        f"cannot predict from a {type(m).__name__}: give an AnalysisConfig, an Analysis, "
        "an ImportedMission, a MissionSpec or a Problem",
        key="prediction",
    )


def _ephemeris(spec: MissionSpec, eph_table, plan: DataPlan, orbit, step: float):
    if eph_table is not None:
        eph = Ephemeris.from_table(eph_table)
        if eph.t_start <= plan.start and eph.t_end >= plan.end:
            return eph
        if orbit is None and getattr(spec, "orbit_tle", None) is None:
            eph.check_covers(np.array([plan.start, plan.end]), what="the prediction plan")
    tle = getattr(spec, "orbit_tle", None)
    if orbit is None and tle is not None:
        # the mission's [orbit] tle propagated over the plan (gcs_core.ephem.tle)
        return Ephemeris.from_table(
            tle_ephemeris_table(
                tle,
                spec.epoch,
                plan.start,
                plan.end,
                frame=spec.orbit_frame,
                step_s=spec.orbit_step_s,
                margin_s=EPHEMERIS_MARGIN_S,
            )
        )
    if orbit is None:
        raise InputError(
            "no ephemeris for the plan: give the mission's ephemeris.csv, an [orbit] tle or a [trade.orbit] table",
            key="prediction.orbit",
        )
    if hasattr(orbit, "table"):  # two-line elements of a plan (gcs_core.predictor.source)
        return Ephemeris.from_table(orbit.table(spec.epoch, plan.start, plan.end, EPHEMERIS_MARGIN_S))
    return build_ephemeris(orbit, spec.epoch, plan.start - EPHEMERIS_MARGIN_S, plan.end + EPHEMERIS_MARGIN_S, step)


def _telemetry_span(telemetry) -> tuple[float, float] | None:
    tabs = [t for t in telemetry.values() if len(t)]
    if not tabs:
        return None
    return min(float(t.t[0]) for t in tabs), max(float(t.t[-1]) for t in tabs)


def predict(
    source,
    *,
    plan: DataPlan | None = None,
    mission=None,
    orbit=None,
    method: str | None = None,
    ephemeris_step: float = 30.0,
    catalog=None,
) -> PredictionResult:
    """Predict the σ of every solve-for element over a data plan (module docstring).

    Parameters
    ----------
    source : an :class:`~gcs_core.config_schema.AnalysisConfig` (mission, physics, state roles,
        ``[prediction]`` plan and method), a :class:`~gcs_core.session.Analysis`, an
        :class:`~gcs_core.io.importer.ImportedMission`, a
        :class:`~gcs_core.io.types.MissionSpec` (pre-launch: no telemetry), or a
        :class:`~gcs_core.problem.build.Problem` (its own frames are the plan's frames;
        its measured values are ignored).
    plan : the data plan; default from the config's ``[prediction]`` table, the
        telemetry span, or the Problem's frames.
    mission : the mission when ``source`` is a config and the mission is already loaded
        (or is only a MissionSpec).
    orbit : :class:`~gcs_core.ephem.orbit.KeplerOrbit` / ``TleOrbit``, used when the
        mission has no ephemeris covering the plan (:func:`~gcs_core.ephem.orbit.build_ephemeris`).
    method : ``"information"`` (Eq 3-2) or ``"kalman"`` (Eq 3-4, gyro process noise);
        default from the config (``kalman`` for ``method = "kalman"``); ``"whole_span"``
        (the default fit's setting) is Eq 3-2's history whose final covariance is the
        whole-span fit's, the gyro noise carried as process noise
        (:func:`~gcs_core.estimators.whole_span.uses.predicted_covariance`).
    ephemeris_step : tabulation step of an orbit-built ephemeris [s].
    catalog : the star catalog already read (:class:`~gcs_core.predictor.stars.Catalog`),
        for ``stars = "catalog"`` without reading a file here.

    Returns
    -------
    :class:`PredictionResult`.
    """
    if isinstance(source, Problem):
        return _predict_problem(source, plan, _method(method, None))
    cfg = None
    if isinstance(source, ConfiguredAnalysis):
        cfg, mission = source.config, mission if mission is not None else source.mission
    elif isinstance(source, AnalysisConfig):
        cfg = source
    spec, telemetry, eph_table, aux, onboard = _mission_parts(source, mission, cfg)
    if plan is None:
        span = _telemetry_span(telemetry)
        if cfg is not None:
            plan = DataPlan.from_config(cfg, span=span)
        elif span is not None:
            plan = DataPlan(*span)
        else:
            raise InputError("no data plan: give DataPlan(start, end, ...)", key="prediction.start")
    off = sensors_off(cfg, spec)
    gyro_off = any(s.type == "gyro" and s.name in off for s in spec.sensors)
    if off:
        from dataclasses import replace

        spec = replace(spec, sensors=tuple(s for s in spec.sensors if s.name not in off))
        telemetry = {k: v for k, v in telemetry.items() if k not in off}
    eph = _ephemeris(spec, eph_table, plan, orbit, ephemeris_step)
    physics = cfg.physics if cfg is not None else PhysicsOptions()
    planned = plan_problem(
        spec,
        eph,
        plan,
        telemetry=telemetry,
        aux=aux,
        onboard=onboard,
        physics=physics,
        options=state_options(cfg),
        use_gyro=not gyro_off,
        catalog=catalog,
    )
    m = _method(method, cfg)
    return _run(planned, plan, m, warn_batch=_checks_batch(m, cfg), magnitude=magnitude_sensors(spec))


def _predict_problem(problem: Problem, plan: DataPlan | None, method: PredictionMethod) -> PredictionResult:
    """Prediction for a Problem's own frames (values ignored), restricted to the plan."""
    if plan is None:
        t = [sd.t for sd in problem.sensors if sd.n]
        if not t:
            raise InputError("the problem has no frames", key="prediction")
        plan = DataPlan(min(float(x[0]) for x in t), max(float(x[-1]) for x in t))
    cadence = {sd.name: median_step(sd.t) or 1.0 for sd in problem.sensors}
    planned = PlannedProblem(
        problem, problem.state.values(), None, cadence, {k: int(plan.grid(c).size) for k, c in cadence.items()}
    )
    return _run(planned, plan, method)


def _run(
    planned: PlannedProblem,
    plan: DataPlan,
    method: PredictionMethod,
    *,
    warn_batch: bool = False,
    magnitude: set[str] | frozenset[str] = frozenset(),
) -> PredictionResult:
    problem, values = planned.problem, planned.values
    state = problem.state
    names = tuple(state.solve_for)
    cons = tuple(state.consider)
    if not names:
        raise InputError("nothing to predict: every state element is held or consider", key="state")
    n = len(names)
    times = plan.output_times()
    masks = info.masks_in(plan, problem)
    sigma0 = np.array([state[nm].sigma0 for nm in names], dtype=float)
    sigma_c = np.array([state[nm].sigma0 for nm in cons], dtype=float)
    if np.any(~np.isfinite(sigma_c)):
        raise InputError("a consider element needs a finite a-priori sigma", key="state.elements")
    lins: list = linearize(problem, values, names + cons)
    lins = [magnitude_rows(lin) if lin.name in magnitude else lin for lin in lins]
    rows = [info.weighted_rows(lin, sd.t, masks[sd.name]) for lin, sd in zip(lins, problem.sensors)]
    frames = {sd.name: int(t.size) for (t, _), sd in zip(rows, problem.sensors)}
    A_final = info.final_information(rows, n + len(cons), plan.end)[:n, :n]
    used = method.used(isinstance(problem.attitude, GyroAttitude) and tuple(names[:3]) == RPY)
    if used is not method:
        log.info("no gyro carries a solved-for attitude: the prediction uses Eq 3-2")
    use_kalman = used.gyro_recursion
    if use_kalman:
        hist = kalman_history(problem, values, names, cons, sigma0, sigma_c, times, masks=masks)
    else:
        A_cum = info.binned_information(rows, times, n + len(cons))
        hist = info.static_history(
            A_cum, n, info.prior_information(sigma0), sigma_c, _attitude_partials(problem, values, names, times)
        )
    final = None
    if magnitude and (use_kalman or process_noise(problem) is not None):
        raise InputError(
            f"the magnitude-only observable of {', '.join(sorted(magnitude))} is predicted without a "
            "gyro's process noise (Eq 3-2): turn the gyro off or use the vector observable",
            key="models",
        )
    if (used.whole_span_final or warn_batch) and not use_kalman:
        final = predicted_covariance(
            problem, values, names, cons, {k: ~np.asarray(v, bool) for k, v in masks.items()}, A_final, sigma0, sigma_c
        )
    warnings: tuple[str, ...] = ()
    if used.leaves_out_process_noise and final is not None:
        warnings = batch_warning(names, hist["sigma_noise"][-1], np.sqrt(np.diag(final[0])))
    elif used.whole_span_final and final is not None:  # the end of the plan: the whole-span covariance
        P, P_cons, budget = final
        hist["P"], hist["P_consider"], hist["budget"] = P, P_cons, budget
        hist["sigma_noise"][-1] = np.sqrt(np.diag(P))
        hist["sigma"][-1] = np.sqrt(np.diag(P_cons))
    slots = planned.slots
    availability = {k: (frames.get(k, 0) / slots[k] if slots.get(k) else 0.0) for k in slots if k in frames}
    unobs = tuple(name_combinations(A_final, names, 1e-7))
    return PredictionResult(
        times=times,
        names=names,
        units=tuple(state[nm].unit for nm in names),
        sigma=hist["sigma"],
        sigma_noise=hist["sigma_noise"],
        attitude_sigma=hist["attitude_sigma"],
        P=hist["P"],
        P_consider=hist["P_consider"],
        consider=cons,
        budget={c: hist["budget"][j] for j, c in enumerate(cons)},
        noise_only=hist["sigma_noise"][-1].copy(),
        availability=availability,
        frames=frames,
        method=used.name,
        plan=plan,
        unobservable=unobs,
        prior=sigma0.copy(),
        warnings=warnings,
    )


#: the batch's σ understates the whole-span σ (the gyro noise as process noise) by more
#: than this factor for some element: the plan's batch σ is not to be trusted
BATCH_UNDERSTATES = 1.1


def batch_warning(names, sigma_batch: np.ndarray, sigma_whole_span: np.ndarray) -> tuple[str, ...]:
    """The computed warning of a plan predicted for the batch method (the fits give the same
    for data, :meth:`gcs_core.session.Analysis._method_warnings`): the batch takes the
    gyro-propagated attitude as exact, so where the gyro noise matters its σ is too small.
    The ratio whole-span σ / batch σ of each element for this plan, when one exceeds
    :data:`BATCH_UNDERSTATES`."""
    with np.errstate(divide="ignore", invalid="ignore"):
        ratio = np.asarray(sigma_whole_span, float) / np.asarray(sigma_batch, float)
    ok = np.isfinite(ratio)
    if not np.any(ok) or float(np.max(ratio[ok])) <= BATCH_UNDERSTATES:
        return ()
    order = [i for i in np.argsort(-np.where(ok, ratio, 0.0)) if ok[i]][:4]
    worst = ", ".join(f"{names[i]} ×{ratio[i]:.2f}" for i in order)
    return (
        "batch method: the gyro noise (not modelled by the batch) makes its predicted σ too "
        f"small for this plan (σ with the process noise / batch σ: {worst}). Use method = "
        '"whole_span" (the default) for honest σ.',
    )


def _attitude_partials(problem: Problem, values, names, times) -> np.ndarray:
    """(T, 3, n) ``∂δθ(t)/∂x`` (three-axis) or ``∂Â/∂x`` (spinning) over the solve-for columns."""
    att = problem.attitude.evaluate(values, times)
    J = np.zeros((times.size, 3, len(names)))
    col = {nm: j for j, nm in enumerate(names)}
    for a, nm in enumerate(att.names):
        if nm in col:
            J[:, :, col[nm]] = att.J[:, :, a]
    return J
