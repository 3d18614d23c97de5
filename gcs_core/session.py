"""One analysis session: mission + config → fit → diagnose → add → refit.

The TUI and the headless commands both drive an :class:`Analysis`; that is why a
config saved from the TUI and run with ``gcs batch`` gives the same numbers. Nothing
here knows about screens or terminals.
"""

from __future__ import annotations

import logging
from collections.abc import Callable, Iterable, Mapping
from dataclasses import dataclass, replace

import numpy as np

from gcs_core import stepwise
from gcs_core.config_problem import problem_from_config
from gcs_core.config_schema import AnalysisConfig
from gcs_core.diagnosis import aliases, determination, goodness, physics
from gcs_core.diagnosis import holdout as held_out
from gcs_core.diagnosis import search as search_session
from gcs_core.diagnosis.catalogue import Effect, mission_catalogue
from gcs_core.diagnosis.discovery import Step
from gcs_core.diagnosis.honest_sigma import SIGMA_WINDOW, fit_sigma_scale
from gcs_core.diagnosis.physics import PhysicsNeed
from gcs_core.diagnosis.ranking import Candidate, rank_candidates
from gcs_core.diagnosis.structure import StructureReport
from gcs_core.errors import ConfigError
from gcs_core.estimators.batch.least_squares import BatchOptions
from gcs_core.estimators.kalman.options import FilterOptions
from gcs_core.estimators.registry import Estimator, FitSettings, KalmanEstimator, estimator
from gcs_core.estimators.results import FitResult
from gcs_core.models.drift import split_family
from gcs_core.noise import correlated as noise_correlation
from gcs_core.noise import correlated_sigma
from gcs_core.noise.weighting import NoiseWeighting, same_factors, stated_residuals, weighted_sensors
from gcs_core.problem.build import Problem
from gcs_core.problem.prepare import PHYSICS_EFFECTS, PhysicsOptions
from gcs_core.problem.state import HELD, SOLVE_FOR

log = logging.getLogger(__name__)


@dataclass(frozen=True)
class FitRecord:
    """One fit of a session, as the session stores it (and :meth:`Analysis.fit` returns its
    ``result``).

    result : the fit, its residuals normalized by the stated σ (under long-run weighting
        the fit weighted its sensors by ``σ × k``: :mod:`gcs_core.noise.weighting`);
    holdout_rms, holdout_chi2 : sensor -> normalized RMS and χ² test on the held-out span
        ({} when none was held out);
    warnings : the estimator's honesty warnings about its method on these data;
    noise : with ``noise_weighting = "long_run"`` or ``"correlated"``, the factors the fit was
        weighted with;
    correlation : sensor -> its noise correlation, declared or measured on the residuals.
    """

    result: FitResult
    holdout_rms: Mapping[str, float]
    holdout_chi2: Mapping[str, goodness.ChiSquare]
    warnings: tuple[str, ...]
    noise: NoiseWeighting | None
    correlation: Mapping[str, noise_correlation.SensorCorrelation]


class Analysis:
    """A mission under analysis, as configured.

    Attributes
    ----------
    config : the analysis config (updated as effects are added or removed).
    mission : the imported mission.
    problem : the current state definition and prepared sensors.
    result : the latest fit (None before the first).
    candidates : the latest ranking.
    steps : the add/refit history.
    holdout_rms, holdout_chi2 : sensor -> normalized RMS and χ² test on the held-out span.
    warnings : the latest fit's honesty warnings about the method.
    stop_reason : why the latest discovery stopped ("" before one).
    noise : with ``[filter] noise_weighting = "correlated"`` (the default) or ``"long_run"``,
        the factors the latest fit weighted its sensors with (:mod:`gcs_core.noise.weighting`);
        else None.
    correlation : sensor -> its noise correlation on the latest fit's residuals, declared or
        measured (:mod:`gcs_core.noise.correlated`).
    """

    def __init__(self, config: AnalysisConfig, *, mission=None):
        from gcs_core.io.importer import load_mission

        self.config = config
        self.mission = mission if mission is not None else load_mission(config.mission)
        self.record: FitRecord | None = None  # the latest fit, as stored
        self.candidates: list[Candidate] = []
        self.steps: list[Step] = []
        self.stop_reason = ""
        self._factors: dict = {}  # sensor -> NoiseFactor the problem's σ carry
        self._factors_mode = config.filter.noise_weighting  # the weighting the factors come from
        #: fit with the factors as they are, measuring but not refitting (gcs_core/diagnosis/alternative.py)
        self.hold_factors = False
        #: sensor -> generic family effects the residual-structure search made candidates
        self.offered: dict[str, tuple[str, ...]] = {}
        self.problem: Problem = self._build()
        self._goodness: tuple | None = None  # (result it was formed for, GoodnessOfFit)
        self._null_at_prior: tuple | None = None  # (problem, combinations)
        self._physics_needed: tuple | None = None  # (result it was scored on, rows)
        self._aliases: tuple | None = None  # (result it was formed for, aliases)
        self.sigma_window = SIGMA_WINDOW  # [s] of sigma_scale(); 0 = off, None = chosen
        self._sigma_scale: tuple | None = None  # (result, window, SigmaScale | None)
        self.structure_report: StructureReport | None = None  # the latest search
        self._structure: tuple | None = None  # (result, sensors asked, report) of the latest search
        self.search_sensors: tuple[str, ...] = ()  # sensors searched on request besides the misfit ones

    # ------------------------------------------------------------------ set-up
    @property
    def physics(self) -> PhysicsOptions:
        return self.config.physics

    def _build(self) -> Problem:
        """The state definition and prepared sensors of the current config
        (:func:`gcs_core.config_problem.problem_from_config`), weighted by the long-run
        noise factors when the fit is (the fit's σ are then the stated σ × k)."""
        problem = problem_from_config(self.config, self.mission, families=self._families())
        if self._scale():
            problem.sensors = weighted_sensors(problem.sensors, self._scale())
        return problem

    def _families(self) -> dict[str, tuple[str, ...]]:
        """sensor -> generic family effects its model carries: those offered by the search and
        those the config names (:mod:`gcs_core.models.drift`)."""
        out = {k: list(v) for k, v in self.offered.items()}
        for eid in (*self.config.state.effects, *self.config.state.exclude):
            sensor, _, effect = eid.partition(".")
            if split_family(effect) is not None and effect not in out.setdefault(sensor, []):
                out[sensor].append(effect)
        return {k: tuple(v) for k, v in out.items() if v}

    def structure(self, sensors: Iterable[str] = (), *, offer: bool = False) -> StructureReport:
        """Residual-structure search (:mod:`gcs_core.diagnosis.structure`) of every sensor with
        residuals (``sensors`` and :attr:`search_sensors` are labelled "on request"), once per
        fit; with ``offer`` the families of what it finds become candidates (the problem is
        then rebuilt: rank again)."""
        if self.result is None:
            self.fit()
        asked = (*self.search_sensors, *sensors)
        cached = self._structure
        if cached is not None and cached[0] is self.result and cached[1] == asked:
            self.structure_report = cached[2]  # one search per fit (discovery's last step asks again)
        else:
            self.structure_report = search_session.run(self, asked)
            self._structure = (self.result, asked, self.structure_report)
        if offer:
            search_session.offer(self, self.structure_report)
            self._structure = (self.result, asked, self.structure_report)  # same residuals, families added
        return self.structure_report

    def _scale(self) -> dict[str, float]:
        """sensor -> the factor its stated σ is weighted with (only those above 1)."""
        return {n: f.factor for n, f in self._factors.items() if f.factor != 1.0}

    def catalogue(self) -> list[Effect]:
        return mission_catalogue(self.problem, self.physics)

    def effects_in_state(self) -> list[str]:
        out = []
        for e in self.catalogue():
            if e.physics:
                on, _ = PHYSICS_EFFECTS[e.effect]
                if getattr(self.physics, e.effect) == on:  # a config may omit a key: its default
                    out.append(e.id)
            elif all(self.problem.state[n].role == SOLVE_FOR for n in e.elements):
                out.append(e.id)
        return out

    def candidate_effects(self) -> list[Effect]:
        """Effects not in the state: sensor effects wholly held, physics options off."""
        out = []
        for e in self.catalogue():
            if e.physics:
                on, _ = PHYSICS_EFFECTS[e.effect]
                if getattr(self.physics, e.effect) != on:
                    out.append(e)
            elif e.effect != "attitude" and all(self.problem.state[n].role == HELD for n in e.elements):
                out.append(e)
        return out

    # ------------------------------------------------------------------ fitting
    def batch_options(self) -> BatchOptions:
        return BatchOptions(
            max_iterations=self.config.filter.max_iterations,
            edit_k=self.config.filter.edit_k or None,
            edit_k_sensor=self._edit_k_sensor(),
        )

    def _edit_k_sensor(self) -> dict[str, float | None]:
        """Per-sensor k of the k-σ editing; a sensor weighted by a long-run factor ``f`` is
        edited at ``k / f`` of its weighted σ, i.e. still at ``k`` of its stated σ (an
        outlier is a per-sample notion)."""
        fl = self.config.filter
        out = {k: (v or None) for k, v in fl.edit_k_sensor.items()}
        for name, f in self._scale().items():
            k = fl.edit_k_sensor.get(name, fl.edit_k)
            out[name] = k / f if k else None
        return out

    def holdout_masks(self) -> dict[str, np.ndarray]:
        """Held-out frames per sensor (True = held out): 5-min blocks spread over the span
        by the golden-ratio rotation (:mod:`gcs_core.diagnosis.holdout`)."""
        return held_out.holdout_masks(self.problem.sensors, self.config.diagnosis.holdout_fraction)

    def fit(
        self, *, holdout: bool = True, initial: Mapping[str, float] | None = None, previous: FitResult | None = None
    ) -> FitResult:
        """Fit the current state; with ``holdout`` also score the held-out span.

        ``initial`` warm-starts the iterations (e.g. from the previous step's solution);
        the a priori stays at the configured values. ``previous``: the solution before a step
        (whole-span: the refit starts at it, knots and edits included, and ends at or below it).
        """
        mode = self.config.filter.noise_weighting
        if self._factors_mode != mode:  # switched weighting: start again from the stated σ
            self._factors, self._factors_mode = {}, mode
            self.problem = self._build()
        res = self._fit_once(initial=initial, previous=previous)
        noise: NoiseWeighting | None = None
        correlation: dict[str, noise_correlation.SensorCorrelation] = {}
        if mode in ("long_run", "correlated"):
            res, noise, correlation = self._reweight(res)
        if mode != "correlated":  # measured and reported; the weights stay the configured ones
            names = [sd.name for sd in self.problem.sensors if sd.name != self.problem.gyro_name]
            correlation = noise_correlation.measure(res, names, weights=self._scale())
        holdout_rms: dict[str, float] = {}
        holdout_chi2: dict[str, goodness.ChiSquare] = {}
        masks = self.holdout_masks() if holdout else {}
        if masks:
            # the training fit starts from the full fit's solution (a whole-span fit's: knots too)
            training = estimator(self.estimator.training)
            res_train = training.fit(self.problem, self.fit_settings(), edited=masks, **res.warm_start())
            stated = self._stated_problem()  # held-out residuals against the stated σ
            holdout_rms = res_train.holdout_rms(stated, masks)
            holdout_chi2 = goodness.holdout_tests(stated, res_train, masks)
        if mode == "correlated" and self._scale():  # σ of fast signatures: the sandwich with C
            res = correlated_sigma.honest(self.problem, res, correlation, self._scale())
        result = stated_residuals(res, self._scale())
        warnings = tuple(self.estimator.warnings(self.problem, result))
        self.record = FitRecord(result, holdout_rms, holdout_chi2, warnings, noise, correlation)
        self.candidates = []
        for w in warnings:
            log.warning("%s", w)
        return result

    # the latest fit's parts (read-only: a fit replaces its record whole)
    @property
    def result(self) -> FitResult | None:
        """The latest fit, its residuals against the stated σ (None before the first)."""
        return self.record.result if self.record is not None else None

    @property
    def holdout_rms(self) -> Mapping[str, float]:
        return self.record.holdout_rms if self.record is not None else {}

    @property
    def holdout_chi2(self) -> Mapping[str, goodness.ChiSquare]:
        return self.record.holdout_chi2 if self.record is not None else {}

    @property
    def warnings(self) -> list[str]:
        return list(self.record.warnings) if self.record is not None else []

    @property
    def noise(self) -> NoiseWeighting | None:
        return self.record.noise if self.record is not None else None

    @property
    def correlation(self) -> Mapping[str, noise_correlation.SensorCorrelation]:
        return self.record.correlation if self.record is not None else {}

    @property
    def estimator(self) -> Estimator:
        """The configured estimation method (:mod:`gcs_core.estimators.registry`)."""
        return estimator(self.config.method)

    def fit_settings(self) -> FitSettings:
        return FitSettings(self.batch_options(), self.filter_options(), self.config.filter.block_seconds)

    def _fit_once(self, *, initial=None, previous: FitResult | None = None):
        """One fit of the current problem with its current weights."""
        return self.estimator.fit(self.problem, self.fit_settings(), initial=initial, previous=previous)

    def _reweight(
        self, res: FitResult
    ) -> tuple[FitResult, NoiseWeighting, dict[str, noise_correlation.SensorCorrelation]]:
        """``noise_weighting = "long_run"`` or ``"correlated"``: measure each sensor's noise
        factor on the fit's residuals (the batch-means ratio, or ``√κ`` of its Gauss–Markov
        correlation, declared or significant) and refit with ``σ × k`` (``noise_passes``
        times at most, at least twice when correlated, fewer when the factors stop moving by
        more than their sampling error), module :mod:`gcs_core.noise.weighting`; returns the
        refit, the weighting and each sensor's correlation."""
        fl = self.config.filter
        sensors = [sd.name for sd in self.problem.sensors if sd.name != self.problem.gyro_name]
        correlated = fl.noise_weighting == "correlated"
        declared = noise_correlation.declared_correlation(self.mission.spec) if correlated else {}
        passes = 0
        correlation: dict[str, noise_correlation.SensorCorrelation] = {}
        for _ in range(0 if self.hold_factors else max(fl.noise_passes, 2) if correlated else fl.noise_passes):
            factors, corr = noise_correlation.factors(res, sensors, fl, declared, self._scale())
            correlation = corr if correlated else correlation
            if same_factors(factors, self._factors):  # the weights stand; the latest measurement is kept
                old = self._factors
                self._factors = {n: replace(f, factor=old[n].factor if n in old else 1.0) for n, f in factors.items()}
                break
            before, self._factors = self._scale(), factors
            after = self._scale()
            ratio = {n: after.get(n, 1.0) / before.get(n, 1.0) for n in set(before) | set(after)}
            self.problem = replace(self.problem, sensors=weighted_sensors(self.problem.sensors, ratio))
            # from the solution's values, its knots laid out and its frames edited for the new
            # weights (the whole-span grid follows the information, the editing the σ)
            res = self._fit_once(initial=res.state.values())
            passes += 1
        if correlated and (passes or self.hold_factors):  # the correlation the final residuals show (reported)
            correlation = noise_correlation.measure(res, sensors, declared, self._scale())
        window = float("nan") if correlated else fl.noise_window
        noise = NoiseWeighting(window, passes, dict(self._factors), fl.noise_weighting)
        log.info("%s", noise.summary())  # the TUI's engine log shows it
        return res, noise, correlation

    def _stated_problem(self) -> Problem:
        """The current problem with the stated σ (itself when nothing is reweighted)."""
        scale = self._scale()
        if not scale:
            return self.problem
        return replace(
            self.problem, sensors=weighted_sensors(self.problem.sensors, {n: 1 / k for n, k in scale.items()})
        )

    def filter_options(self) -> FilterOptions:
        return FilterOptions(edit_k=self.config.filter.edit_k or None, edit_k_sensor=self._edit_k_sensor())

    def make_filter(self):
        """A stepping FILTR machine on the current problem (the TUI steps it block by block)."""
        return KalmanEstimator.make_filter(self.problem, self.fit_settings())

    def rank(self) -> list[Candidate]:
        res = self.result if self.result is not None else self.fit()
        self.candidates = rank_candidates(
            self.problem,
            res,
            self.candidate_effects(),
            alpha=self.config.diagnosis.significance,
            smoothed=res.scores_own_residuals,
        )
        return self.candidates

    def physics_needed(self) -> list[PhysicsNeed]:
        """For each always-on physics option in the model, what switching it off would cost
        (:func:`gcs_core.diagnosis.physics.physics_needed`), once per fit."""
        if self.result is None:
            self.fit()
        res = self.result
        assert res is not None  # fitted above
        if self._physics_needed is not None and self._physics_needed[0] is res:
            return self._physics_needed[1]
        on_ids = set(self.effects_in_state())
        phys = [e for e in self.catalogue() if e.physics and e.id in on_ids]
        out = (
            physics.physics_needed(
                self.problem,
                res,
                phys,
                alpha=self.config.diagnosis.significance,
                smoothed=res.scores_own_residuals,
            )
            if phys
            else []
        )
        self._physics_needed = (res, out)  # one score pass per fit
        return out

    def rms(self) -> dict[str, float]:
        return {k: v.rms_normalized for k, v in self.result.residuals.items()} if self.result else {}

    # ------------------------------------------------------------------ add / remove
    def _set_effect(self, effect_id: str, on: bool) -> None:
        cat = {e.id: e for e in self.catalogue()}
        if effect_id not in cat:
            import difflib

            close = difflib.get_close_matches(effect_id, list(cat), n=1, cutoff=0.75)
            hint = f"; did you mean '{close[0]}'?" if close else ""
            raise ConfigError(f"unknown effect '{effect_id}'{hint} (see `gcs effects`)", key="state.effects")
        e = cat[effect_id]
        if e.physics:
            on_val, off_val = PHYSICS_EFFECTS[e.effect]
            self.config = self.config.with_changes(physics={e.effect: on_val if on else off_val})
        else:
            effects = [x for x in self.config.state.effects if x != effect_id]
            exclude = [x for x in self.config.state.exclude if x != effect_id]
            if on:
                effects.append(effect_id)
                base = _intercept_of(e, self.problem.state)
                if base and base not in effects:  # a family carries its base effect when held
                    effects.append(base)
                    exclude = [x for x in exclude if x != base]
            else:
                exclude.append(effect_id)
            self.config = self.config.with_changes(state={"effects": tuple(effects), "exclude": tuple(exclude)})
        self.problem = self._build()

    def _apply(self, action: str, effect_id: str, on: bool) -> Step:
        res = self.result if self.result is not None else self.fit()
        before = self.rms()
        chi_before, previous, scale_before = res.chi2, res, self._scale()
        prev_values = previous.state.values()
        self._set_effect(effect_id, on)
        # warm start from the previous solution; the a priori stays the configured one
        warm = {k: v for k, v in prev_values.items() if k in self.problem.state}
        res = self.fit(initial=warm, previous=previous)
        scale = self._scale()
        for name, r in previous.residuals.items():  # Δχ² at the new fit's weights (residuals: stated σ)
            k0, k1 = scale_before.get(name, 1.0), scale.get(name, 1.0)
            if k0 != k1:
                chi_before += r.chi2 * (1.0 / k1**2 - 1.0 / k0**2)
        est = {}
        e = {x.id: x for x in self.catalogue()}.get(effect_id)
        if e is not None:
            est = {n: res.state[n].value for n in e.elements if n in res.state}
        step = Step(action, effect_id, before, self.rms(), dict(self.holdout_rms), chi_before - res.chi2, res.chi2, est)
        self.steps.append(step)
        return step

    def add_effect(self, effect_id: str) -> Step:
        return self._apply("add", effect_id, True)

    def remove_effect(self, effect_id: str) -> Step:
        return self._apply("remove", effect_id, False)

    def first_step(self) -> Step:
        res = self.result or self.fit()
        step = Step("fit", None, {}, self.rms(), dict(self.holdout_rms), 0.0, res.chi2)
        self.steps.append(step)
        return step

    # ------------------------------------------------------------------ discovery
    def discover(self, *, max_steps: int = 10, progress: Callable[[str], None] | None = None) -> list[Step]:
        """Stepwise discovery (:func:`gcs_core.stepwise.discover`): add the most
        significant identifiable candidate while one passes the Bonferroni-corrected level;
        ``stop_reason`` says why it stopped."""
        self.stop_reason = stepwise.discover(self, max_steps=max_steps, progress=progress)
        return self.steps

    # ------------------------------------------------------------------ honesty
    def goodness(self) -> goodness.GoodnessOfFit | None:
        """χ² of the latest fit on its effective dof, per sensor and on the held-out span,
        with the verdict "consistent with noise" or "model inadequate: ..." at the
        session's family-wise significance (:mod:`gcs_core.diagnosis.goodness`); None
        before a fit."""
        res = self.result
        if res is None:
            return None
        if self._goodness is None or self._goodness[0] is not res:
            carried = self.config.filter.noise_weighting == "correlated"
            infl = noise_correlation.chi2_inflations(self.correlation) if carried else {}  # κ₂
            g = goodness.goodness_of_fit(
                self.problem,
                res,
                holdout=noise_correlation.inflated_tests(self.holdout_chi2, infl),
                alpha=self.config.diagnosis.significance,
                inflation=infl,
            )
            self._goodness = (res, g)
        return self._goodness[1]

    def sigma_scale(self):
        """The latest fit's correlation-robust σ scales over windows of ``sigma_window``
        (:mod:`gcs_core.diagnosis.honest_sigma`), once per result; None when off, before a
        fit, or not estimable (too few windows: logged)."""
        res, c = self.result, self._sigma_scale
        if res is None:
            return None
        if c is None or c[0] is not res or c[1] != self.sigma_window:
            c = self._sigma_scale = (
                res,
                self.sigma_window,
                fit_sigma_scale(self.problem, res, self._scale(), self.sigma_window),
            )
        return c[2]

    def set_by_prior(self) -> dict[str, str]:
        """Solve-for elements the a priori set rather than the data (prior share of the
        information above one half, :func:`gcs_core.diagnosis.determination.set_by_prior`),
        with the reason; {} before a fit."""
        res = self.result
        if res is None:
            return {}
        return determination.set_by_prior(self.problem, res.solve_for, res.P)

    def null_at_prior(self) -> list[str]:
        """Combinations the data do not determine at the a-priori linearization
        (:func:`gcs_core.diagnosis.determination.null_at_prior`), once per state."""
        if self._null_at_prior is None or self._null_at_prior[0] is not self.problem:
            try:
                combos = determination.null_at_prior(
                    self.problem, self.problem.state.solve_for, self.batch_options().rank_tol * 1e3
                )
            except (np.linalg.LinAlgError, ValueError, FloatingPointError) as exc:
                log.info("no linearization at the a priori: %s", exc)
                combos = []
            self._null_at_prior = (self.problem, combos)
        return self._null_at_prior[1]

    # ------------------------------------------------------------------ what the fit left open
    def not_determined(self) -> dict[str, str]:
        """Solve-for elements the latest fit did not determine, with the reason
        (:func:`gcs_core.diagnosis.determination.not_determined`); {} before a fit."""
        res = self.result
        if res is None:
            return {}
        out = determination.not_determined(self.problem, res.state.values(), res.sigma)
        sigma0 = {n: self.problem.state[n].sigma0 for n in res.solve_for}
        for name, why in aliases.set_by_prior(self.aliases(), res.sigma, sigma0).items():
            out.setdefault(name, why)
        return out

    def aliases(self) -> list:
        """The combinations of elements the latest fit left to the a priori, named
        (:func:`gcs_core.diagnosis.aliases.problem_aliases`); [] before a fit."""
        res = self.result
        if res is None:
            return []
        if self._aliases is None or self._aliases[0] is not res:
            self._aliases = (res, aliases.problem_aliases(self.problem, res))
        return self._aliases[1]


def _intercept_of(e: Effect, state) -> str | None:
    """The base effect a generic family adds with it (its held elements, see
    :func:`gcs_core.diagnosis.catalogue.mission_catalogue`), or None."""
    parts = split_family(e.effect)
    if parts is None or e.sensor is None:
        return None
    base = [n for n in e.elements if state[n].effect == parts[0]]
    return f"{e.sensor}.{parts[0]}" if base else None
