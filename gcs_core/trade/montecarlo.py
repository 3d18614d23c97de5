"""Monte Carlo of a data plan: simulate, fit, and compare the scatter with the predicted σ.

The plan of an analysis config (``[prediction]``: span, gaps, maneuvers; the sensors' own
gaps) is flown by the project's truth simulator (:mod:`gcs_core.sim`, independent physics)
with the data book as truth, once per run with the noise re-drawn, and each run is fitted
with the configured method (:meth:`gcs_core.session.Analysis.fit`). Per run ``i`` the
simulator's seed comes from ``numpy.random.SeedSequence(seed).spawn(runs)[i]`` (entropy and
spawn key stored with the run: ``--replay i`` recomputes that run alone).

Truth drawn from the a priori. The predicted covariance is that of a truth distributed as
the a priori, ``x ~ N(x̄, P̄)``. Each run draws the estimator's a-priori mean about the
simulator's truth instead, ``x̄ = x + δ``, ``δ ~ N(0, P̄)`` (the same joint distribution of
``x̄ − x``, for every element whatever its sensor model): every solve-for element with a
finite a-priori σ, and every consider element, which the fit then holds at its drawn,
wrong value. The scatter is therefore compared with the predictor's *total* σ (noise and
consider elements together), the a priori's share as drawn (an element drawn narrower than
its σ̄, :func:`draw_sigmas`: :func:`~gcs_core.trade.mc_summary.drawn_sigma`), and the NEES
with each fit's ``P_consider``.

For each solve-for element the summary compares

* predicted σ: the predictor's σ for the same plan (:func:`gcs_core.predictor.source.predict_source`,
  the plan read once as every planning command reads it), the trackers' stars from the
  simulator's catalog;
* Monte-Carlo σ: the sample standard deviation ``s`` of ``x̂ − x_true`` over the N runs;
* the ratio ``s / σ`` with its sampling band. ``(N − 1) s² / σ² ~ χ²(N − 1)`` when σ is
  right, so the ratio of a right prediction lies in ``[sqrt(χ²_{α/2}/(N−1)),
  sqrt(χ²_{1−α/2}/(N−1))]``; the acceptance (:data:`MATCH_FRACTION`, "within 15 % once its
  sampling error is allowed for") widens that band by 15 % each way, at a family-wise
  α = :data:`ALPHA` over the elements compared (Bonferroni);
* the mean error in σ and the fit's own σ;

and the NEES ``Σ_runs eᵀ P⁻¹ e`` over the elements the plan determines, with its 95 %
χ² band (Bar-Shalom, Li & Kirubarajan 2001, §5.4.2). The verdict holds when every
determined element is inside its band and the NEES inside its own.

Truth: every element is compared with the simulator's value of the *same* quantity in
the estimator's parameterization. Elements the simulator holds at their data-book value
have that value. The attitude is the simulator's at the estimator's reference time
``t_ref`` (the first gyro knot), expressed in the estimator's reference frame. The gyro
bias depends on the method's model of it, ``b(t) = bias + bias_rate (t − t_mid)`` plus
whatever the method lets wander:

* ``whole_span`` (the default): the wander is the knots' random walk, zero at ``t_ref``
  (:mod:`gcs_core.estimators.whole_span.knots`), so ``bias_rate`` is the simulator's deterministic drift
  (its data-book ``bias_rate``) and ``bias`` the simulator's bias at ``t_ref`` carried to
  ``t_mid`` by that drift;
* ``kalman``: the walk at ``t_ref`` less the drift of the least-squares line through it;
* ``batch`` (no wander): the least-squares line through the walk over the fitted span.

A config the runs cannot use (no ``[trade.orbit]``, a spinning mission, an unknown key)
is refused before the first run: no failed runs are written.
"""

from __future__ import annotations

import json
import math
import tempfile
import time
from collections.abc import Callable
from dataclasses import dataclass, field, replace
from pathlib import Path
from typing import Any

import numpy as np

from gcs_core.errors import GcsError, InputError
from gcs_core.estimators.registry import estimator
from gcs_core.trade import engine, store
from gcs_core.trade.mc_summary import (
    ALPHA,
    CONVERGED,
    MATCH_FRACTION,
    MonteCarloResult,
    ratio_band,
    summarize,
    summary_lines,
)

#: raised-cosine ramps of the simulated maneuvers [s] (the turn is still rate × duration):
#: body rates stay continuous, as a real slew's do
RAMP_S = 20.0


@dataclass(frozen=True)
class MonteCarlo:
    """``runs`` simulations of the plan of the config at ``config_path``, seeded by ``seed``."""

    config_path: str
    runs: int
    seed: int
    #: the plan read once on the submitting machine (:mod:`gcs_core.predictor.source`),
    #: shipped to the workers; None: read from ``config_path`` where the run happens
    source: Any = field(default=None, compare=False, repr=False)
    #: element -> the σ its a-priori draw uses (:func:`draw_sigmas`); None: the a priori's
    draw: Any = field(default=None, compare=False, repr=False)

    def as_json(self) -> str:
        return json.dumps({"config_path": self.config_path, "runs": self.runs, "seed": self.seed})

    def with_source(self) -> MonteCarlo:
        if self.source is not None:
            return self
        from gcs_core.predictor.source import load_source

        return replace(self, source=load_source(self.config_path))

    def digest(self) -> str:
        import hashlib

        d = {"config": self.with_source().source.content, "seed": self.seed}
        return hashlib.sha256(json.dumps(d, sort_keys=True).encode()).hexdigest()[:16]

    def run_seed(self, i: int) -> tuple[int, list[int]]:
        """(simulator seed, spawn key) of run ``i``."""
        child = np.random.SeedSequence(self.seed).spawn(i + 1)[i]
        return int(child.generate_state(1, dtype=np.uint32)[0]), list(child.spawn_key)


# ---------------------------------------------------------------------------- one run
_CTX: dict = {}


def _context(mc: MonteCarlo):
    """(config, spec, plan) of the study: the shipped source's, else read once per process."""
    src = mc.source
    if src is None:
        src = _CTX.get(mc.config_path)
        if src is None:
            src = mc.with_source().source
            _CTX.clear()
            _CTX[mc.config_path] = src
    return src.config, src.spec, src.plan


def simulation(cfg, spec, plan, seed: int):
    """The simulator's :class:`~gcs_core.sim.config.MissionConfig` flying ``plan`` exactly:
    the sensors of ``spec`` (data book = truth), the ``[trade.orbit]`` elements, the
    nominal attitude (roll/pitch/yaw of the plan or zeros) and its maneuvers (Eq 4-36,
    with :data:`RAMP_S` ramps), no wobble, no auxiliary channels."""
    from gcs_core.predictor.synth import cadence_of
    from gcs_core.sim.config import MissionConfig, OrbitElements, SensorConfig, Slew, ThreeAxisProfile
    from gcs_core.units import DEG

    orbit = (cfg.trade or {}).get("orbit")
    if not orbit:
        raise InputError(
            "Monte Carlo needs the orbit: give a [trade.orbit] table (a_km, e, i_deg, "
            "raan_deg, argp_deg, mean_anomaly_deg)",
            key="trade.orbit",
        )
    if spec.attitude_mode == "spinning":
        raise InputError("Monte Carlo of spinning missions is not supported", key="analysis.mission")
    sensors = []
    for s in spec.sensors:
        book: dict[str, Any] = {"alignment_deg": list(s.alignment_deg or (0.0, 0.0, 0.0))}
        if s.noise is not None:
            book["noise"] = float(s.noise)
        book.update({k: (list(v) if isinstance(v, tuple) else v) for k, v in s.book.items()})
        sensors.append(SensorConfig(s.name, s.type, float(cadence_of(s, None, plan)), book))
    r0, p0, y0 = (float(a) / DEG for a in plan.rpy0) if plan.rpy0 is not None else (0.0, 0.0, 0.0)
    rpy0 = (r0, p0, y0)
    slews = [Slew(m.start, m.duration, m.axis, m.rate_deg_s, ramp_s=RAMP_S) for m in plan.maneuvers]
    profile = ThreeAxisProfile(rpy0_deg=rpy0, wobble_amp_deg=(0.0, 0.0, 0.0), slews=slews)
    epoch = spec.epoch.strftime("%Y-%m-%dT%H:%M:%SZ")
    return MissionConfig(
        name=spec.name,
        epoch=epoch,
        attitude_mode=spec.attitude_mode,
        duration_s=float(plan.end) + 1.0,
        orbit=OrbitElements(**{k: float(v) for k, v in orbit.items()}),
        attitude=profile,
        sensors=sensors,
        aux=None,
        onboard=None,
        seed=int(seed),
    )


def _restricted(mission, plan):
    """The imported mission with the frames outside the plan span or inside its gaps removed."""
    from gcs_core.predictor.synth import _subset

    tel = {}
    for name, tab in mission.telemetry.items():
        keep = plan.in_span(tab.t) & ~plan.in_gap(tab.t, name)
        if mission.spec.sensor(name).type == "gyro":  # the gyro runs through the gaps
            keep = (tab.t >= plan.start - 1e-9) & (tab.t <= plan.end + 1e-9)
        tel[name] = _subset(tab, keep)
    return replace(mission, telemetry=tel)


def _truth(truth: dict, problem, values_book: dict, method: str = "batch") -> dict[str, float]:
    """Element -> true value (module docstring)."""
    from gcs_core.sim.config import MissionConfig, OrbitElements, Slew, ThreeAxisProfile
    from gcs_core.sim.truth import World

    out = dict(values_book)
    att = problem.attitude
    gyro = att.gyro
    if gyro and "gyro_bias_history" in truth and gyro in truth["gyro_bias_history"]:
        h = np.asarray(truth["gyro_bias_history"][gyro], float)
        t0, t1 = float(att.knots[0]), float(att.knots[-1])
        sel = (h[:, 0] >= t0 - 1e-9) & (h[:, 0] <= t1 + 1e-9)
        A = np.column_stack([np.ones(int(sel.sum())), h[sel, 0] - 0.5 * (t0 + t1)])
        coef, *_ = np.linalg.lstsq(A, h[sel, 1:], rcond=None)
        b_ref = np.array([np.interp(att.t_ref, h[:, 0], h[:, 1 + i]) for i in range(3)])
        book_slope = np.array([float(values_book.get(f"{gyro}.bias_rate_{c}", 0.0)) for c in "xyz"])
        # what the estimator's static bias elements are of the true walk (its own model)
        b_mid, slope = estimator(method).bias_elements(
            coef[0], coef[1], b_ref, book_slope, float(att.t_ref), 0.5 * (t0 + t1)
        )
        for i, c in enumerate("xyz"):
            out[f"{gyro}.bias_{c}"] = float(b_mid[i])
            out[f"{gyro}.bias_rate_{c}"] = float(slope[i])
    a = dict(truth["attitude"])
    slews = [Slew(**s) for s in a.pop("slews", [])]
    prof = ThreeAxisProfile(**{k: tuple(v) for k, v in a.items()}, slews=slews)
    world = World(
        MissionConfig(
            name=truth["mission"],
            epoch=truth["epoch"],
            attitude_mode=truth["attitude_mode"],
            duration_s=float(truth["duration_s"]),
            orbit=OrbitElements(**truth["orbit"]),
            attitude=prof,
        )
    )
    t_ref = att.t_ref
    if t_ref is None:
        t_ref = float(min(sd.t[0] for sd in problem.sensors if sd.n))
    ref = att.ref
    C = world.attitude(np.array([t_ref]))[0]
    out["att.roll"], out["att.pitch"], out["att.yaw"] = ref.rpy_from_dcm(C, t_ref)
    return out


def one_run(mc: MonteCarlo, i: int) -> dict:
    """Simulate and fit run ``i``: a JSON-ready record (seed, names, x̂, truth, P, status)."""
    from gcs_core.io.importer import load_mission
    from gcs_core.session import Analysis
    from gcs_core.sim.writer import write_mission

    cfg, spec, plan = _context(mc)
    seed, key = mc.run_seed(i)
    t0 = time.perf_counter()
    rec = {"index": i, "seed": seed, "entropy": mc.seed, "spawn_key": key}
    with tempfile.TemporaryDirectory(prefix="gcs-mc-") as d:
        try:
            folder = Path(d)
            path = write_mission(simulation(cfg, spec, plan, seed), folder / "m", truth_path=folder / "truth.json")
            mission = _restricted(load_mission(path), plan)
            a = Analysis(cfg.with_changes(mission=path, diagnosis={"holdout_fraction": 0.0}), mission=mission)
            book = {e.name: e.value for e in a.problem.state}
            truth = _truth(json.loads((folder / "truth.json").read_text()), a.problem, book, cfg.method)
            drawn = draw_prior(a.problem.state, truth, np.random.default_rng([seed, PRIOR_STREAM]), mc.draw)
            a.problem = a.problem.with_state(a.problem.state.with_values(drawn))
            res = a.fit(holdout=False)
        except (GcsError, np.linalg.LinAlgError) as err:
            rec.update(status=" ".join(str(err).split()), seconds=time.perf_counter() - t0)
            return rec
    names = list(res.solve_for)
    e = np.array([res.x[k] - truth[n] for k, n in enumerate(names)])
    for k, n in enumerate(names):
        if n.startswith("att."):
            e[k] = (e[k] + math.pi) % (2 * math.pi) - math.pi
    rec.update(
        status=res.status,
        names=names,
        x_hat=[float(x) for x in res.x],
        error=e.tolist(),
        P=np.asarray(res.P_consider).tolist(),
        chi2=float(res.chi2),
        seconds=time.perf_counter() - t0,
    )
    return rec


#: the second stream of a run's seed: its a-priori draw (the first is the simulator's noise)
PRIOR_STREAM = 1


#: a solve-for element's draw is capped at this many predicted σ (:func:`draw_sigmas`)
DRAW_CAP = 10.0


def draw_sigmas(pred) -> dict[str, float]:
    """Solve-for element -> σ of its a-priori draw, ``min(σ̄, DRAW_CAP σ)`` with σ̄ its a
    priori and σ its predicted σ (a consider element is drawn with its σ̄: what the fit
    holds it wrong by). The cap keeps the draws inside the region the predictor
    linearizes (a sensor's transfer function drawn over its whole, wide a priori tests
    its nonlinearity, not the plan); where it binds, ``σ < σ̄ / DRAW_CAP``. The element's
    own a priori's share of its error variance is then small, but through the correlations
    of the covariance another element's can be too (the two tracker scales), so the
    summary's predicted σ counts every share as drawn
    (:func:`~gcs_core.trade.mc_summary.drawn_sigma`)."""
    out = {}
    prior = pred.prior if pred.prior is not None else np.full(len(pred.names), np.inf)
    for n, s0, s in zip(pred.names, prior, pred.sigma[-1]):
        if math.isfinite(s0) and s0 > 0:
            out[n] = float(min(s0, DRAW_CAP * s)) if math.isfinite(s) else float(s0)
    return out


def draw_prior(state, truth: dict[str, float], rng: np.random.Generator, sigmas=None) -> dict[str, float]:
    """The run's a-priori means (module docstring): ``x̄ = x_true + σ_d z`` for every
    solve-for element with a finite a-priori σ̄ and every consider element (drawn in state
    order); ``σ_d`` from ``sigmas`` (:func:`draw_sigmas`), else σ̄."""
    from gcs_core.problem.state import CONSIDER, SOLVE_FOR

    out = {}
    for el in state:
        if el.role not in (SOLVE_FOR, CONSIDER) or el.name not in truth:
            continue
        if not (math.isfinite(el.sigma0) and el.sigma0 > 0):
            continue
        s = el.sigma0 if sigmas is None else sigmas.get(el.name, el.sigma0)
        out[el.name] = float(truth[el.name] + s * rng.standard_normal())
    return out


def _runs(mc: MonteCarlo, batch: list) -> list[dict]:
    return [one_run(mc, i) for i in batch]


# ---------------------------------------------------------------------------- prediction
def predicted(mc: MonteCarlo):
    """The predictor's result for the plan (:func:`~gcs_core.predictor.source.predict_source`),
    the trackers' stars from the simulator's catalog."""
    from gcs_core.predictor.stars import read_catalog
    from gcs_core.sim.writer import write_mission

    src = mc.with_source().source
    cfg, spec, plan = src.config, src.spec, src.plan
    if not any(s.type == "star_tracker" for s in spec.sensors):
        return src.predict()
    short = replace(plan, start=plan.start, end=min(plan.end, plan.start + 60.0), gaps=(), maneuvers=())
    with tempfile.TemporaryDirectory(prefix="gcs-mc-") as d:
        sim = simulation(cfg, spec, short, 0)
        path = write_mission(replace(sim, duration_s=min(sim.duration_s, 120.0)), Path(d) / "m")
        catalog = read_catalog(Path(path) / "star_catalog.csv")
    return replace(src, catalog=catalog).predict(replace(plan, stars="catalog", catalog=None))


# ---------------------------------------------------------------------------- summary
def prepared(mc: MonteCarlo):
    """(``mc`` with its plan read and its draw σ set, the prediction): what every run needs,
    computed once here and shipped to the workers. A config the runs cannot use fails
    here, before any run is written."""
    mc = mc.with_source()
    cfg, spec, plan = _context(mc)
    simulation(cfg, spec, plan, 0)
    pred = predicted(mc)
    if mc.draw is None:
        mc = replace(mc, draw=draw_sigmas(pred))
    return mc, pred


def run_montecarlo(
    mc: MonteCarlo,
    output=None,
    *,
    workers=None,
    scheduler=None,
    resume=False,
    overwrite=False,
    batch=None,
    progress: Callable[[int, int], None] | None = None,
) -> MonteCarloResult:
    """All runs (those already in ``output`` skipped with ``resume``), then the summary."""
    if mc.runs < 2:
        raise InputError(f"need at least 2 runs, not {mc.runs}", key="montecarlo.runs")
    mc, pred = prepared(mc)
    digest = mc.digest()
    skip = (
        store.prepare_output(output, store.MONTECARLO, digest, resume=resume, overwrite=overwrite)
        if output is not None
        else set()
    )
    records: list[dict] = []

    def on_batch(recs: list[dict]) -> None:
        records.extend(recs)
        if output is not None and recs:
            store.append_batch(output, store.MONTECARLO, study=mc.as_json(), digest=digest, records=recs)

    items = [i for i in range(mc.runs) if i not in skip]
    prog = None if progress is None else (lambda d, _n: progress(len(skip) + d, mc.runs))
    # a run (simulation and fit) takes seconds, far over Dask's per-task overhead: one
    # run per task balances the load and loses at most one run per worker to a Ctrl-C
    engine.run_jobs(
        _runs, mc, items, on_batch=on_batch, workers=workers, scheduler=scheduler, batch=batch or 1, progress=prog
    )
    if output is not None:
        _, records = store.read(output, store.MONTECARLO)
        records = [r for r in records if int(r["index"]) < mc.runs]
    return summarize(pred, sorted(records, key=lambda r: r["index"]), draw=mc.draw)


def replay(output, i: int) -> list[str]:
    """Recompute run ``i`` of a results file from its stored seed and compare."""
    head, records = store.read(output, store.MONTECARLO)
    d = json.loads(head["study"])
    mc, _ = prepared(MonteCarlo(d["config_path"], int(d["runs"]), int(d["seed"])))
    old = next((r for r in records if int(r["index"]) == i), None)
    if old is None:
        raise InputError(f"run {i} is not in the file", file=output)
    new = one_run(mc, i)
    same = old.get("x_hat") == new.get("x_hat")
    return [
        f"run {i}: seed {new['seed']} (entropy {mc.seed}, spawn key {new['spawn_key']}), status {new['status']}",
        "estimates identical to the stored run" if same else "estimates DIFFER from the stored run",
    ]


__all__ = [
    "ALPHA",
    "CONVERGED",
    "MATCH_FRACTION",
    "MonteCarlo",
    "MonteCarloResult",
    "draw_prior",
    "draw_sigmas",
    "one_run",
    "predicted",
    "prepared",
    "ratio_band",
    "replay",
    "run_montecarlo",
    "simulation",
    "summarize",
    "summary_lines",
]
