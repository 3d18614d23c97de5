"""Predicted σ against Monte-Carlo scatter: the estimator's covariance, checked on 200+ seeds.

One fixed scenario (three-axis, 30 minutes by default, data book = truth; ``--hours 8`` or
``--hours 24`` for the long spans of issue 10) is simulated once per seed with the noise
re-drawn, and fitted with ``--method`` (passed through to the analysis config: ``batch``,
``kalman`` or the estimator a config names). For each headline element (attitude, TAM bias,
gyro bias, star-tracker scales) the table compares

* predicted σ: ``sqrt(mean over runs of P_ii)``, the fit's own 1-sigma;
* MC σ: the sample standard deviation of ``x̂ − x_true`` over the runs;
* ratio MC σ / predicted σ, and whether it is within 15 % of 1;
* mean error in units of the predicted σ, with its 1 % two-sided t bound
  ``2.6/sqrt(N)`` (an unbiased estimator stays inside it).

With N = 200 runs the sample σ itself is uncertain by ``1/sqrt(2(N−1)) ≈ 5 %``, so the 15 %
criterion is a 3-sigma statement. The headline NEES (13 elements) is also printed against
its 95 % χ² band, with the runs' own tail (how many under p = 0.05 and 0.001, against the
binomial, and a KS test of their p-values).

``--elements`` adds rows after the headline: comma-separated names (``IRU.G_21,
IRU.bias_rate_z``) or ``all-calibrated`` (every other solve-for element with a truth, those
a run flags "not determined" left out), with the truth of
:func:`honesty_cases.truth_all` in the estimator's own form (for the whole-span fit the
gyro's ``bias_rate`` is the simulator's deterministic drift, the walk being the knots').
The NEES is then also printed for the gyro's ``G_*`` and ``bias_rate_*`` blocks, for both
together, and for every row checked (correlations included).

Truth and headline definitions: ``tests/statistical/test_consistency_batch.py`` (:func:`headline`)
and ``tests/statistical/test_truth_recovery.py`` (:func:`truth_values`).

``--electronic σ_e`` [rad] gives the gyro a read-out (electronic) noise, written to its data
book; ``--ignore-electronic`` fits as if the book said 0 (the estimator's σ then leave the
read-out error out). The attitude headline's truth is the simulator's attitude at ``t_ref``,
which differs from the gyro-carried trajectory's reference by that epoch's read-out error:
its predicted covariance gets ``σ_e² I`` (:mod:`gcs_core.estimators.whole_span.readout`).

Usage::

    python benchmarks/monte_carlo_consistency.py [--runs 200] [--minutes 30 | --hours 8]
        [--method batch|kalman|...] [--bias-form batch|kalman] [--mode sun_pointing]
        [--electronic 3.9e-5 [--ignore-electronic]] [--processes 2]
        [--elements all-calibrated | NAME,NAME,...]

``--bias-form`` says how the estimator parametrizes the gyro bias, for its truth: ``batch``
(``bias + bias_rate (t − t_mid)``, the line through the simulated random walk) or
``kalman`` (the random-walk bias at ``t_ref``); by default ``batch`` for the batch and
``kalman`` for any estimator that carries the gyro's process noise.

Exits with status 1 when a ratio is outside 15 %.

Runs on the same seeds are not independent samples: the simulator seeds each sensor's noise
by seed and name only, so seed ``s`` draws the same TAM and IRU noise in every mode, and a
longer mission's first hours are the shorter one's (the attitude headline, at the first
knot, is pinned by them). To pool modes or spans, give each its own ``--first-seed``
(docs/benchmarks.md, "Predicted σ against Monte-Carlo scatter").

References
----------
Bar-Shalom, Li & Kirubarajan, *Estimation with Applications to Tracking and Navigation*,
Wiley 2001, §5.4.2 (Monte-Carlo consistency tests).
"""

from __future__ import annotations

import os

os.environ.setdefault("OPENBLAS_NUM_THREADS", "1")  # small matrices: threads only contend

import argparse
import logging
import math
import sys
import tempfile
import time
from multiprocessing import get_context
from pathlib import Path

import numpy as np

ROOT = Path(__file__).resolve().parents[1]
sys.path[:0] = [str(ROOT), *(str(p) for p in sorted((ROOT / "tests").iterdir()) if p.is_dir())]

from honesty_cases import truth_all
from scipy import stats
from test_consistency_batch import HEADLINE, headline, headline_rows, nees_band
from test_truth_recovery import simulate, threeaxis, truth_values

#: a predicted σ within this fraction of the Monte-Carlo σ "matches" (issue 6)
match_fraction = 0.15


def one_run(
    seed: int,
    folder: Path,
    minutes: float,
    method: str,
    mode: str,
    bias_form: str,
    extra=(),
    electronic: float = 0.0,
    ignore_electronic: bool = False,
):
    """Simulate and fit one seed (no held-out fit); returns (names, error (k,), covariance
    (k, k), not-determined names): the headline rows, then the ``extra`` elements (or,
    for ``extra = ("all-calibrated",)``, every other solve-for element with a truth)."""
    from gcs_core.config_schema import AnalysisConfig
    from gcs_core.session import Analysis

    cfg = threeaxis(mode, seed, 60.0 * minutes)
    for s in cfg.sensors:
        if s.type == "gyro" and electronic > 0:
            # the truth; the data book the estimator reads says so unless it is to be ignored
            (s.true if ignore_electronic else s.book)["electronic"] = electronic
    mission, truth = simulate(cfg, folder)
    a = Analysis(AnalysisConfig(mission=mission, method=method))
    res = a.fit(holdout=False)
    names, e, P = headline(a, res, truth_values(truth, a.problem, bias_form), bias_form)
    readout = electronic**2 if electronic > 0 and not ignore_electronic else 0.0
    if not extra:
        P = P.copy()
        P[:3, :3] += readout * np.eye(3)  # the truth at t_ref carries that epoch's read-out error
        return list(names), e, P, []
    # the extra rows: the truth in the estimator's own form (for the whole-span fit the
    # gyro's bias_rate is the simulator's deterministic drift, the walk in the knots)
    form = "whole_span" if method not in ("batch", "kalman") else bias_form
    tv = truth_all(truth, a.problem, form)
    sf = list(res.solve_for)
    want = [n for n in sf if n in tv and n not in names] if "all-calibrated" in extra else list(extra)
    unknown = [n for n in want if n not in sf or n not in tv]
    if unknown:
        raise ValueError(f"--elements: not solve-for or without a truth: {', '.join(unknown)}")
    # one selection matrix for headline and extra rows (correlations across them kept)
    Th, T_h_truth = headline_rows(a, res, truth_values(truth, a.problem, bias_form), bias_form)
    Tx = np.zeros((len(want), len(sf)))
    for r, n in enumerate(want):
        Tx[r, sf.index(n)] = 1.0
    T = np.vstack([Th, Tx])
    x_true = np.concatenate([T_h_truth, [tv[n] for n in want]])
    e = T @ res.x - x_true
    e[:3] = (e[:3] + np.pi) % (2 * np.pi) - np.pi
    P = T @ res.P @ T.T
    P[:3, :3] += readout * np.eye(3)  # the attitude rows come first (HEADLINE)
    return [*names, *want], e, P, sorted(a.not_determined())


def _worker(job):
    logging.getLogger("gcs_core").setLevel(logging.ERROR)  # the per-run method warnings
    seed, minutes, method, mode, bias_form, extra, electronic, ignore = job
    with tempfile.TemporaryDirectory(prefix="gcs-mc-") as d:
        out = one_run(seed, Path(d), minutes, method, mode, bias_form, extra, electronic, ignore)
    return (seed, *out)


def run(
    runs: int,
    minutes: float,
    method: str,
    mode: str,
    processes: int,
    first_seed: int,
    bias_form: str = "batch",
    extra: tuple[str, ...] = (),
    electronic: float = 0.0,
    ignore_electronic: bool = False,
):
    """Fit ``runs`` seeds; returns (names, errors (N, k), covariances (N, k, k)) over the
    rows every run has and no run flagged "not determined"."""
    jobs = [
        (s, minutes, method, mode, bias_form, extra, electronic, ignore_electronic)
        for s in range(first_seed, first_seed + runs)
    ]
    out = {}
    with get_context("spawn").Pool(processes) as pool:
        for k, (seed, names, e, P, nd) in enumerate(pool.imap_unordered(_worker, jobs, chunksize=4)):
            out[seed] = (names, e, P, nd)
            if (k + 1) % 25 == 0:
                print(f"  {k + 1}/{runs} runs", flush=True)
    seeds = sorted(out)
    skip = set().union(*(out[s][3] for s in seeds))
    keep = [n for n in out[seeds[0]][0] if n not in skip and all(n in out[s][0] for s in seeds)]
    if skip & set(out[seeds[0]][0]):
        print(f"left out (not determined in some run): {', '.join(sorted(skip & set(out[seeds[0]][0])))}")
    E, Ps = [], []
    for s in seeds:
        names, e, P, _ = out[s]
        idx = [names.index(n) for n in keep]
        E.append(e[idx])
        Ps.append(P[np.ix_(idx, idx)])
    return keep, np.array(E), np.array(Ps)


def _nees(E: np.ndarray, Ps: np.ndarray, idx: list[int]) -> np.ndarray:
    """Per run ``eᵀ P⁻¹ e`` for the rows ``idx`` (correlations included), on the
    correlation matrix (scale-free: the rows span 1e-9 to 1e-1)."""
    out = np.empty(len(E))
    for k, (e, P) in enumerate(zip(E, Ps)):
        ei, Pi = e[idx], P[np.ix_(idx, idx)]
        d = np.sqrt(np.diag(Pi))
        L = np.linalg.cholesky(Pi / np.outer(d, d))
        u = np.linalg.solve(L, ei / d)
        out[k] = float(u @ u)
    return out


def table(names: list[str], E: np.ndarray, Ps: np.ndarray) -> bool:
    """Print the per-element table and the NEES of the headline, the gyro's extra blocks
    and everything checked; True when every ratio is within :data:`match_fraction`."""
    N = E.shape[0]
    pred = np.sqrt(np.mean(np.einsum("kii->ki", Ps), axis=0))
    mc = np.std(E, axis=0, ddof=1)
    mean_z = np.mean(E, axis=0) / pred
    t_bound = 2.576 / math.sqrt(N)
    ok_all = True
    print(f"\n{'parameter':<17}{'predicted σ':>13}{'MC σ':>13}{'ratio':>8}  {'within 15%?':<12}{'mean/σ':>8}")
    for j, name in enumerate(names):
        ratio = mc[j] / pred[j]
        ok = abs(ratio - 1.0) <= match_fraction
        ok_all &= ok
        flag = "" if abs(mean_z[j]) <= t_bound else " (biased)"
        print(
            f"{name:<17}{pred[j]:>13.4g}{mc[j]:>13.4g}{ratio:>8.3f}  {'yes' if ok else 'NO':<12}"
            f"{mean_z[j]:>+8.3f}{flag}"
        )
    print(f"\na sample σ of {N} runs is uncertain by ±{100 / math.sqrt(2 * (N - 1)):.1f} % (1σ)")
    print(f"mean |t| bound for 'mean/σ' at 1 %: {t_bound:.3f}")
    blocks = {"headline": [names.index(n) for n in HEADLINE if n in names]}
    blocks["IRU.G_*"] = [j for j, n in enumerate(names) if n.startswith("IRU.G_")]
    blocks["IRU.bias_rate_*"] = [j for j, n in enumerate(names) if n.startswith("IRU.bias_rate_")]
    blocks["gyro (G, bias_rate)"] = blocks["IRU.G_*"] + blocks["IRU.bias_rate_*"]
    blocks["all checked"] = list(range(len(names)))
    seen = set()
    for label, idx in blocks.items():
        if not idx or tuple(idx) in seen:
            continue
        seen.add(tuple(idx))
        per_run = _nees(E, Ps, idx)
        nees, dof = float(per_run.sum()), N * len(idx)
        lo, hi = nees_band(dof, 0.95)
        p_hi = float(stats.chi2.sf(nees, dof))
        print(
            f"NEES {label} ({len(idx)} elements × {N} runs): {nees:.1f} on {dof}, 95 % band "
            f"[{lo:.1f}, {hi:.1f}], {nees / dof:.3f} per element, P(χ² ≥) = {p_hi:.3g}"
        )
        # the runs' own p-values: the tail (binomial p of as many under 0.05) and uniformity
        p_run = stats.chi2.sf(per_run, len(idx))
        n05 = int(np.sum(p_run < 0.05))
        print(
            f"     runs with p < 0.05: {n05} of {N} ({0.05 * N:.1f} expected, binomial P(≥) = "
            f"{float(stats.binom.sf(n05 - 1, N, 0.05)):.3g}); p < 0.001: {int(np.sum(p_run < 1e-3))}; "
            f"KS p {float(stats.kstest(p_run, 'uniform').pvalue):.3g}; smallest p {float(p_run.min()):.2g}"
        )
    return ok_all


def main() -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--runs", type=int, default=200)
    ap.add_argument("--minutes", type=float, default=30.0)
    ap.add_argument("--hours", type=float, default=None, help="the span in hours (overrides --minutes)")
    ap.add_argument("--method", default="batch")
    ap.add_argument("--bias-form", choices=("batch", "kalman"), default=None)
    ap.add_argument("--mode", choices=("sun_pointing", "inertial", "earth_pointing"), default="sun_pointing")
    ap.add_argument("--processes", type=int, default=2)
    ap.add_argument("--first-seed", type=int, default=1)
    ap.add_argument(
        "--elements",
        default="",
        help="extra elements after the headline: comma-separated names (IRU.G_21,IRU.bias_rate_z,...) "
        "or all-calibrated (every solve-for element with a truth the fits determine)",
    )
    ap.add_argument("--electronic", type=float, default=0.0, help="gyro read-out noise σ_e [rad]")
    ap.add_argument("--ignore-electronic", action="store_true", help="fit as if the data book had no σ_e")
    args = ap.parse_args()
    if args.hours is not None:
        args.minutes = 60.0 * args.hours
    bias_form = args.bias_form or ("batch" if args.method == "batch" else "kalman")
    t0 = time.perf_counter()
    print(
        f"{args.runs} runs, {args.mode}, {args.minutes:g} min, method {args.method}, "
        f"gyro bias as in the {bias_form} form, {args.processes} processes"
        + (
            f", gyro read-out noise σ_e {args.electronic:g} rad"
            + (" (ignored by the fit)" if args.ignore_electronic else "")
            if args.electronic
            else ""
        )
    )
    extra = tuple(n.strip() for n in args.elements.split(",") if n.strip())
    try:
        names, E, Ps = run(
            args.runs,
            args.minutes,
            args.method,
            args.mode,
            args.processes,
            args.first_seed,
            bias_form,
            extra,
            args.electronic,
            args.ignore_electronic,
        )
    except ValueError as exc:  # an unknown --elements name, raised in the worker
        print(exc, file=sys.stderr)
        return 2
    ok = table(names, E, Ps)
    print(
        f"\n{time.perf_counter() - t0:.1f} s; predicted σ {'matches' if ok else 'does NOT match'} "
        f"the Monte-Carlo σ within {100 * match_fraction:g} % for every element checked"
    )
    return 0 if ok else 1


if __name__ == "__main__":
    sys.exit(main())
