"""Monte Carlo of a data plan: simulate, fit, and compare the scatter with the predicted σ.

The plan of an analysis config (``[prediction]``: span, gaps, maneuvers) is flown by the
project's truth simulator (:mod:`gcs_core.sim`, independent physics) with the data book
as truth, once per run with the noise re-drawn, and each run is fitted with the
configured method (:meth:`gcs_core.session.Analysis.fit`). Per run ``i`` the simulator's
seed comes from ``numpy.random.SeedSequence(seed).spawn(runs)[i]`` (entropy and spawn
key stored with the run: ``--replay i`` recomputes that run alone).

For each solve-for element the summary compares

* predicted σ: the predictor's noise-only σ for the same plan (Eq 3-2/3-4, no data), with
  the trackers' stars from the simulator's catalog;
* Monte-Carlo σ: the sample standard deviation of ``x̂ − x_true`` over the runs;
* the ratio (1 ± 15 % is the acceptance), the mean error in σ and the fit's own σ;

and the NEES ``Σ_runs eᵀ P⁻¹ e`` over the elements the plan determines, with its 95 %
χ² band (Bar-Shalom, Li & Kirubarajan 2001, §5.4.2). With N runs the sample σ itself is
uncertain by about ``1/sqrt(2(N−1))`` (7 % at 100 runs).

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
"""

from __future__ import annotations

import json
import math
import tempfile
import time
from collections.abc import Callable, Sequence
from dataclasses import dataclass, replace
from pathlib import Path
from typing import Any

import numpy as np

from gcs_core.errors import GcsError, InputError
from gcs_core.estimators.registry import estimator
from gcs_core.trade import engine, store

#: the acceptance band of predicted against Monte-Carlo σ
MATCH_FRACTION = 0.15
#: raised-cosine ramps of the simulated maneuvers [s] (the turn is still rate × duration):
#: body rates stay continuous, as a real slew's do
RAMP_S = 20.0


@dataclass(frozen=True)
class MonteCarlo:
    """``runs`` simulations of the plan of the config at ``config_path``, seeded by ``seed``."""

    config_path: str
    runs: int
    seed: int

    def as_json(self) -> str:
        return json.dumps({"config_path": self.config_path, "runs": self.runs, "seed": self.seed})

    def digest(self) -> str:
        import hashlib

        from gcs_core.config import load_config

        cfg = load_config(self.config_path)
        d = {"config": cfg.digest(), "orbit": cfg.trade.get("orbit"), "seed": self.seed}
        return hashlib.sha256(json.dumps(d, sort_keys=True).encode()).hexdigest()[:16]

    def run_seed(self, i: int) -> tuple[int, list[int]]:
        """(simulator seed, spawn key) of run ``i``."""
        child = np.random.SeedSequence(self.seed).spawn(i + 1)[i]
        return int(child.generate_state(1, dtype=np.uint32)[0]), list(child.spawn_key)


# ---------------------------------------------------------------------------- one run
_CTX: dict = {}


def _context(mc: MonteCarlo):
    key = mc.config_path
    if key not in _CTX:
        from gcs_core.config import load_config
        from gcs_core.io.mission import read_mission_spec
        from gcs_core.predictor.plan import DataPlan

        cfg = load_config(mc.config_path)
        spec = read_mission_spec(cfg.mission)
        start = 0.0 if cfg.prediction.start is None else cfg.prediction.start
        plan = DataPlan.from_config(cfg, span=(start, start + 1800.0))
        _CTX.clear()
        _CTX[key] = (cfg, spec, plan)
    return _CTX[key]


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
        keep = plan.in_span(tab.t) & ~plan.in_gap(tab.t)
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
            res = a.fit(holdout=False)
            truth = _truth(json.loads((folder / "truth.json").read_text()), a.problem, book, cfg.method)
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
        P=np.asarray(res.P).tolist(),
        chi2=float(res.chi2),
        seconds=time.perf_counter() - t0,
    )
    return rec


def _runs(mc: MonteCarlo, batch: list) -> list[dict]:
    return [one_run(mc, i) for i in batch]


# ---------------------------------------------------------------------------- prediction
def predicted(mc: MonteCarlo):
    """The predictor's result for the plan, the trackers' stars from the simulator's catalog."""
    from gcs_core.io.mission import read_mission_spec
    from gcs_core.predictor.predict import predict
    from gcs_core.sim.writer import write_mission

    cfg, spec, plan = _context(mc)
    short = replace(plan, start=plan.start, end=min(plan.end, plan.start + 60.0), gaps=(), maneuvers=())
    with tempfile.TemporaryDirectory(prefix="gcs-mc-") as d:
        sim = simulation(cfg, spec, short, 0)
        path = write_mission(replace(sim, duration_s=min(sim.duration_s, 120.0)), Path(d) / "m")
        sim_spec = read_mission_spec(path)
        trackers = any(s.type == "star_tracker" for s in spec.sensors)
        p = replace(plan, stars="catalog", catalog=Path(path) / "star_catalog.csv") if trackers else plan
        from gcs_core.trade.study import make_orbit

        return predict(
            cfg,
            mission=replace(spec, root=sim_spec.root, ephemeris_file=None),
            plan=p,
            orbit=make_orbit(cfg.trade.get("orbit"), spec.epoch),
        )


# ---------------------------------------------------------------------------- summary
@dataclass(frozen=True)
class MonteCarloResult:
    """Scatter against prediction (module docstring); arrays over ``names``."""

    runs: int
    failed: int
    names: tuple[str, ...]
    units: tuple[str, ...]
    predicted: np.ndarray
    scatter: np.ndarray
    ratio: np.ndarray
    mean_z: np.ndarray
    fit_sigma: np.ndarray
    determined: np.ndarray
    nees: float
    nees_band: tuple[float, float]
    nees_dof: int

    @property
    def consistent(self) -> bool:
        r = self.ratio[self.determined]
        return bool(np.all(np.abs(r - 1.0) <= MATCH_FRACTION))


def summarize(pred, records: Sequence[dict]) -> MonteCarloResult:
    from scipy import stats

    ok = [r for r in records if r.get("status") in ("converged", "max_passes")]
    if not ok:
        raise InputError("no run converged", key="montecarlo")
    names = tuple(ok[0]["names"])
    E = np.array([r["error"] for r in ok])
    Ps = np.array([r["P"] for r in ok])
    pi = [pred.names.index(n) if n in pred.names else None for n in names]
    psig = np.array([pred.noise_only[i] if i is not None else np.nan for i in pi])
    und = set(pred.undetermined)
    det = np.array([n not in und and np.isfinite(s) for n, s in zip(names, psig)])
    scat = np.std(E, axis=0, ddof=1) if len(ok) > 1 else np.full(len(names), np.nan)
    units = tuple(pred.units[i] if i is not None else "" for i in pi)
    idx = np.flatnonzero(det)
    nees = float(sum(e[idx] @ np.linalg.solve(P[np.ix_(idx, idx)], e[idx]) for e, P in zip(E, Ps)))
    dof = len(ok) * idx.size
    band = (float(stats.chi2.ppf(0.025, dof)), float(stats.chi2.ppf(0.975, dof))) if dof else (0.0, 0.0)
    return MonteCarloResult(
        len(ok),
        len(records) - len(ok),
        names,
        units,
        psig,
        scat,
        scat / psig,
        np.mean(E, axis=0) / psig,
        np.sqrt(np.mean(np.einsum("kii->ki", Ps), axis=0)),
        det,
        nees,
        band,
        dof,
    )


def summary_lines(res: MonteCarloResult) -> list[str]:
    from gcs_core.trade.report import sigma_display

    out = [
        f"{res.runs} runs fitted"
        + (f", {res.failed} failed" if res.failed else "")
        + f"; predicted σ against the Monte-Carlo scatter (±{100 * MATCH_FRACTION:g} %)",
        f"{'element':<16}{'predicted σ':>13}{'MC σ':>11}{'ratio':>8}{'fit σ':>11}{'mean/σ':>8}  unit",
    ]
    for k, n in enumerate(res.names):
        p, u = sigma_display(res.predicted[k], res.units[k])
        s, _ = sigma_display(res.scatter[k], res.units[k])
        f, _ = sigma_display(res.fit_sigma[k], res.units[k])
        flag = "" if res.determined[k] else "  (not determined by the plan)"
        if res.determined[k] and abs(res.ratio[k] - 1.0) > MATCH_FRACTION:
            flag = "  OUTSIDE ±15 %"
        out.append(f"{n:<16}{p:>13.4g}{s:>11.4g}{res.ratio[k]:>8.3f}{f:>11.4g}{res.mean_z[k]:>+8.2f}  {u}{flag}")
    lo, hi = res.nees_band
    out.append(
        f"NEES over the determined elements: {res.nees:.1f} on {res.nees_dof} dof, 95 % band "
        f"[{lo:.1f}, {hi:.1f}] — {'inside' if lo <= res.nees <= hi else 'OUTSIDE'}"
    )
    out.append(
        "predicted σ "
        + ("match" if res.consistent else "do NOT match")
        + f" the scatter within {100 * MATCH_FRACTION:g} % for every determined element"
    )
    return out


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
    return summarize(predicted(mc), sorted(records, key=lambda r: r["index"]))


def replay(output, i: int) -> list[str]:
    """Recompute run ``i`` of a results file from its stored seed and compare."""
    head, records = store.read(output, store.MONTECARLO)
    d = json.loads(head["study"])
    mc = MonteCarlo(d["config_path"], int(d["runs"]), int(d["seed"]))
    old = next((r for r in records if int(r["index"]) == i), None)
    if old is None:
        raise InputError(f"run {i} is not in the file", file=output)
    new = one_run(mc, i)
    same = old.get("x_hat") == new.get("x_hat")
    return [
        f"run {i}: seed {new['seed']} (entropy {mc.seed}, spawn key {new['spawn_key']}), status {new['status']}",
        "estimates identical to the stored run" if same else "estimates DIFFER from the stored run",
    ]
