"""Ranking every candidate effect by its score against refitting with each one added.

Problem: a simulated three-axis mission (``nominal_threeaxis("sun_pointing")``: TAM, IRU,
two FHSTs, FSS, CSS; 2 h by default, ``--hours 24`` for a day) with two hidden effects
the default state lacks: a TAM contamination by the torquer channel ``mtb_x`` and a
rotation of FHST1 about its boresight. The analysis is the default one
(``Analysis(AnalysisConfig(mission=...))``: k-σ editing on), fitted once.

The question an analyst asks next is "what is missing?". Two ways to answer it, same
fit, one run:

1. the ranking, :meth:`~gcs_core.session.Analysis.rank`
   (:func:`~gcs_core.diagnosis.ranking.rank_candidates`): one linearization at the
   solution with every candidate's columns, then each candidate's score statistic
   ``Δχ² = gᵀ S⁻¹ g`` (Rao), no refit;
2. the naive alternative: for each candidate, add it to the state and refit (warm-started
   from the solution, as :meth:`~gcs_core.session.Analysis.add_effect` does, without
   its held-out refit), and read the χ² it removed (likelihood-ratio form).

Both are timed against one batch iteration (:func:`~gcs_core.estimators.batch.least_squares.normal_equations`
at the solution, the gyro propagation not cached, as in ``batch_vs_least_squares.py``)
and one full fit. ``--method`` chooses the estimator: the default whole-span fit (gyro
noise as process noise; the candidates' partials go through the same knot elimination, and
Δχ² counts the data and process terms of the cost) or the batch. Prints the number of
candidates; the ranking's time, also in units of
batch iterations; the refit-all time and the ratio refit-all / ranking; and, per
candidate, the score Δχ² against the refit Δχ². The score test is the local form of the
likelihood-ratio test: for a model linear in the state and the candidate they agree. The
table says when they need not: ``edits`` counts the frames the refit's editing adds (+) or
takes back (−), and ``step σ`` how far the refit lands from the ranking's one-step
prediction of the candidate, in its predicted σ (0 for a linear model). Over a day the
batch's exact-gyro model leaves the trackers at about three times their noise (the session
warns); the FSS transfer-function elements then move far in the refits and the
FSS candidates' two Δχ² part, while the others still agree.

Timings are the best of a few repeats (the machine may be shared); the refits are timed
once each unless ``--refit-repeats``. OpenBLAS runs on one thread unless
``OPENBLAS_NUM_THREADS`` says otherwise: on a busy machine its threads wait for a core, and
one ``Hᵀ H`` of a few tens of columns then takes ten to fifty times its time, by turns.

Usage: ``python benchmarks/ranking_vs_refit.py [--hours 2] [--seed 11] [--repeats 5]
[--refit-repeats 1] [--top 0] [--cache DIR] [--electronic 3.9e-5]`` (``--cache`` keeps the
simulated mission between runs; ``--top N`` prints only the N strongest candidates;
``--electronic`` gives the gyro a read-out noise σ_e, carried by the fit, its score tests and
refits alike: :mod:`gcs_core.estimators.whole_span.readout`).
"""

from __future__ import annotations

import os

os.environ.setdefault("OPENBLAS_NUM_THREADS", "1")  # a shared machine: threads only contend

import argparse
import copy
import logging
import math
import sys
import tempfile
import time
from pathlib import Path

import numpy as np

REPO = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(REPO))

from _timing import best_of
from gcs_core.config_schema import AnalysisConfig
from gcs_core.estimators.batch.least_squares import normal_equations
from gcs_core.session import Analysis
from gcs_core.sim.scenarios import nominal_threeaxis, with_effect
from gcs_core.sim.writer import write_mission

#: the hidden effects: (catalogue id, magnitude in the unit of ``gcs_core.sim.EFFECTS``, options)
HIDDEN = (("TAM1.contamination_mtb_x", 0.3, {}), ("FHST1.alignment", math.radians(0.02), {"axis": (1.0, 0.0, 0.0)}))
#: a refit landing within this many σ of the ranking's one-step prediction of the candidate
#: stays in the neighbourhood of the solution where the score test reads the χ² surface
LOCAL_SIGMA = 1.0


def make_mission(hours: float, folder: Path, seed: int, electronic: float = 0.0) -> Path:
    """The benchmark mission with its hidden effects, simulated once per folder (with a gyro
    read-out noise σ_e [rad] in the data book when ``electronic`` > 0)."""
    tag = f"-e{electronic:g}" if electronic > 0 else ""
    out = folder / f"ranking-mission-{hours:g}h-seed{seed}{tag}"
    if (out / "mission.toml").exists():
        return out
    cfg = nominal_threeaxis("sun_pointing", seed=seed, duration_s=hours * 3600.0)
    for eid, magnitude, kw in HIDDEN:
        cfg = with_effect(cfg, eid, magnitude, **kw)
    for s in cfg.sensors:
        if s.type == "gyro" and electronic > 0:
            s.book["electronic"] = electronic
    return write_mission(cfg, out, truth_path=folder / f"ranking-truth-{hours:g}h-seed{seed}{tag}.json")


def n_edited(result) -> int:
    return int(sum(np.count_nonzero(r.edited) for r in result.residuals.values()))


def refit_with(base: Analysis, cand, repeats: int) -> dict:
    """Add one candidate to a copy of the session and refit, warm-started from the
    solution (the a priori stays the configured one), as ``add_effect`` does without its
    held-out refit. The copy shares the imported mission (read-only) and rebuilds its
    own problem. ``step``: the largest distance, in the ranking's predicted σ, between the
    refit's value of an element of the candidate and the ranking's one-step prediction
    (0 for a model linear in the state and the candidate)."""
    effect_id = cand.id
    warm_all = base.result.state.values()
    t_build = t_fit = np.inf
    for _ in range(repeats):
        work = copy.copy(base)
        t0 = time.perf_counter()
        work._set_effect(effect_id, True)  # new config, problem rebuilt
        t1 = time.perf_counter()
        warm = {k: v for k, v in warm_all.items() if k in work.problem.state}
        res = work.fit(holdout=False, initial=warm)
        t2 = time.perf_counter()
        t_build, t_fit = min(t_build, t1 - t0), min(t_fit, t2 - t1)
    step = max(
        (
            abs(res.state[n].value - v) / cand.sigma[n]
            for n, v in cand.estimate.items()
            if n in res.state and 0 < cand.sigma.get(n, 0.0) < np.inf
        ),
        default=float("nan"),
    )
    return {
        "delta_chi2": base.result.chi2 - res.chi2,
        "iterations": res.iterations,
        "status": res.status,
        "t_build": t_build,
        "t_fit": t_fit,
        "edits": n_edited(res) - n_edited(base.result),
        "step": step,
    }


def run(
    hours: float,
    folder: Path,
    *,
    seed: int,
    repeats: int,
    refit_repeats: int,
    top: int,
    method: str = "whole_span",
    electronic: float = 0.0,
) -> dict:
    t0 = time.perf_counter()
    mission = make_mission(hours, folder, seed, electronic)
    t_sim = time.perf_counter() - t0
    t0 = time.perf_counter()
    a = Analysis(AnalysisConfig(mission=mission, method=method))
    problem = a.problem
    n_meas = sum(s.n * s.y.shape[1] for s in problem.sensors)
    print(f"method: {method}")
    print(
        f"problem: {hours:g} h, sensors {[s.name for s in problem.sensors]}, {n_meas} measurements; "
        f"hidden: {', '.join(e for e, _, _ in HIDDEN)} (simulated in {t_sim:.1f} s, "
        f"set-up {time.perf_counter() - t0:.1f} s)"
    )

    # one full fit from the a priori (no held-out refit)
    t_fit = best_of(lambda: a.fit(holdout=False), max(2, repeats // 2))
    res = a.result
    names = list(res.solve_for)
    print(
        f"full fit: {t_fit:.3f} s, {res.iterations} iterations, {res.status}; "
        f"{len(names)} solve-for elements, χ² = {res.chi2:.1f} on {res.dof} dof, "
        f"{n_edited(res)} frames edited"
    )
    print("normalized RMS: " + ", ".join(f"{k} {r.rms_normalized:.2f}" for k, r in res.residuals.items()))

    # one batch iteration at the solution, the propagation recomputed (as in a fit's pass)
    values = res.state.values()
    edits = {k: r.edited for k, r in res.residuals.items()}
    att = problem.attitude
    work: dict = {}

    def iteration():
        if hasattr(att, "clear_cache"):
            att.clear_cache()
        normal_equations(problem, values, names, edits, work=work)

    t_iter = best_of(iteration, repeats)
    print(f"one batch iteration: {t_iter:.4f} s")

    # the ranking: every candidate's Δχ² from one linearization
    cands = a.candidate_effects()

    def rank():
        if hasattr(att, "clear_cache"):
            att.clear_cache()
        a.rank()

    t_rank = best_of(rank, repeats)
    ranked = a.candidates
    print(f"ranking: {len(cands)} candidates in {t_rank:.4f} s")
    print(f"RATIO ranking costs {t_rank / t_iter:.2f} batch iterations ({t_rank / t_fit:.2f} of one full fit)")

    # the naive alternative: one refit per candidate
    refits = {}
    t0 = time.perf_counter()
    for c in ranked:
        refits[c.id] = refit_with(a, c, refit_repeats)
    t_wall = time.perf_counter() - t0
    t_refit = sum(r["t_build"] + r["t_fit"] for r in refits.values())
    t_refit_fit = sum(r["t_fit"] for r in refits.values())
    iters = sum(r["iterations"] for r in refits.values())
    print(
        f"refit all: {t_refit:.2f} s ({t_refit_fit:.2f} s fitting, {iters} iterations in all; "
        f"{t_refit - t_refit_fit:.2f} s rebuilding the problem; wall {t_wall:.1f} s)"
    )
    print(f"RATIO refit-all / ranking = {t_refit / t_rank:.0f}× (fitting alone {t_refit_fit / t_rank:.0f}×)")

    # score Δχ² (no refit) against the refit's likelihood-ratio Δχ²
    rows = ranked if top <= 0 else ranked[:top]
    alpha = a.config.diagnosis.significance
    # "edits": frames the refit's editing adds (+) or takes back (−); "step σ": how far the
    # refit lands from the ranking's one-step prediction of the candidate (the score test is
    # local: it reads the χ² surface at the solution)
    print(
        f"\n{'candidate':28s} {'dof':>3s} {'score Δχ²':>12s} {'refit Δχ²':>12s} {'score/refit':>11s} "
        f"{'adj. p':>8s} {'iters':>5s} {'edits':>5s} {'step σ':>7s} {'refit s':>7s}"
    )
    for c in rows:
        r = refits[c.id]
        ratio = c.delta_chi2 / r["delta_chi2"] if r["delta_chi2"] > 0 else float("nan")
        flag = "" if c.identifiable else "  (not identifiable)"
        print(
            f"{c.id:28s} {c.dof:3d} {c.delta_chi2:12.2f} {r['delta_chi2']:12.2f} {ratio:11.4f} "
            f"{c.p_adjusted:8.1e} {r['iterations']:5d} {r['edits']:+5d} {r['step']:7.2f} "
            f"{r['t_build'] + r['t_fit']:7.2f}{flag}"
        )

    def worst(cs):
        dev = [abs(c.delta_chi2 / refits[c.id]["delta_chi2"] - 1.0) for c in cs]
        return f"{max(dev):.2%} (median {np.median(dev):.2%}, {len(dev)} candidates)" if dev else "n/a"

    sig = [c for c in ranked if c.p_adjusted < alpha and refits[c.id]["delta_chi2"] > 0]
    local = [c for c in sig if refits[c.id]["edits"] == 0 and refits[c.id]["step"] <= LOCAL_SIGMA]
    top_refit = max(refits, key=lambda k: refits[k]["delta_chi2"]) if refits else None
    print(
        f"\nsignificant at family-wise α = {alpha:g}: {len(sig)}; |score/refit − 1| at most {worst(sig)}; "
        f"where the refit edits the same frames and lands within {LOCAL_SIGMA:g} σ of the one-step "
        f"prediction: {worst(local)}"
    )
    print(f"strongest by score {ranked[0].id if ranked else None}, by refit {top_refit}")
    return {
        "hours": hours,
        "candidates": len(cands),
        "t_iter": t_iter,
        "t_fit": t_fit,
        "t_rank": t_rank,
        "t_refit": t_refit,
        "t_refit_fit": t_refit_fit,
    }


def main() -> None:
    ap = argparse.ArgumentParser()
    ap.add_argument("--hours", type=float, default=2.0)
    ap.add_argument("--seed", type=int, default=11)
    ap.add_argument("--repeats", type=int, default=5, help="best of this many (iteration, ranking)")
    ap.add_argument("--refit-repeats", type=int, default=1, help="best of this many per candidate refit")
    ap.add_argument("--top", type=int, default=0, help="table rows (0: every candidate)")
    ap.add_argument("--cache", type=Path, default=None, help="keep the simulated mission here")
    ap.add_argument(
        "--method",
        default="whole_span",
        choices=("whole_span", "batch"),
        help="the estimator (default: the default config's, whole_span)",
    )
    ap.add_argument("--electronic", type=float, default=0.0, help="the gyro's read-out noise σ_e [rad] (0: none)")
    args = ap.parse_args()
    # the session warns (once per fit) that the batch's σ are optimistic; not this benchmark's point
    logging.getLogger("gcs_core").setLevel(logging.ERROR)
    kw = dict(
        seed=args.seed,
        repeats=args.repeats,
        refit_repeats=args.refit_repeats,
        top=args.top,
        method=args.method,
        electronic=args.electronic,
    )
    if args.cache is not None:
        args.cache.mkdir(parents=True, exist_ok=True)
        run(args.hours, args.cache, **kw)
        return
    with tempfile.TemporaryDirectory() as tmp:
        run(args.hours, Path(tmp), **kw)


if __name__ == "__main__":
    main()
