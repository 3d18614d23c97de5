"""Batch calibration against scipy.optimize.least_squares, and against the roofline.

Problem: one simulated day (default) of 1 Hz data — gyro + TAM + two FHSTs + FSS — Sun-
pointing with slews; solve-for: attitude, TAM bias, gyro G and bias, FHST scales, FSS
transfer-function parameters. Three timings, same problem, same answer, one run:

1. ``gcs`` batch least squares (analytic partials, streamed by chunks, Eq 3-1/3-2);
2. ``scipy.optimize.least_squares`` (trf) on the same residuals and a priori, with
   finite-difference Jacobians (the obvious peer: no analytic partials needed), run to
   the same minimum (its answer is compared with ours in units of our σ);
3. the roofline: one bare ``Hᵀ W H`` accumulation of the same size (a GEMM of the
   whitened Jacobian, every measurement row × every solve-for column), against one GCS
   batch iteration — :func:`~gcs_core.filtr.batch.normal_equations` at a new state:
   the gyro propagation, every sensor's predictions and partials, the accumulation.

Timings are the best of a few repeats (the machine may be shared). Prints the ratios.

Usage: ``python benchmarks/batch_vs_least_squares.py [--hours 24] [--skip-scipy]
[--cache DIR]`` (``--cache`` keeps the simulated mission between runs).
"""

from __future__ import annotations

import argparse
import sys
import tempfile
import time
from pathlib import Path

import numpy as np
from scipy.optimize import least_squares

REPO = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(REPO))

from gcs_core.filtr.batch import BatchOptions, batch_fit, normal_equations  # noqa: E402
from gcs_core.filtr.problem import build_problem, iter_blocks  # noqa: E402
from gcs_core.sidp.importer import load_mission  # noqa: E402
from gcs_core.sim.scenarios import nominal_threeaxis  # noqa: E402
from gcs_core.sim.writer import write_mission  # noqa: E402


def make_mission(hours: float, folder: Path) -> Path:
    """The benchmark mission (no coarse Sun sensor), simulated once per folder."""
    out = folder / f"bench-mission-{hours:g}h"
    if (out / "mission.toml").exists():
        return out
    cfg = nominal_threeaxis("sun_pointing", seed=11, duration_s=hours * 3600.0)
    cfg.sensors = [s for s in cfg.sensors if s.type != "coarse_sun"]
    return write_mission(cfg, out, truth_path=folder / f"truth-{hours:g}h.json")


def best_of(fn, repeats: int) -> float:
    best = np.inf
    for _ in range(repeats):
        t0 = time.perf_counter()
        fn()
        best = min(best, time.perf_counter() - t0)
    return best


def run(hours: float, folder: Path, skip_scipy: bool) -> dict:
    t0 = time.perf_counter()
    mission = load_mission(make_mission(hours, folder))
    problem = build_problem(mission)
    del mission
    n_meas = sum(s.n * s.y.shape[1] for s in problem.sensors)
    print(f"problem: {hours:g} h, sensors {[s.name for s in problem.sensors]}, {n_meas} measurements, "
          f"{len(problem.state.solve_for)} solve-for elements (set-up {time.perf_counter() - t0:.1f} s)")

    opts = BatchOptions(edit_k=None, tol_step_sigma=1e-3)
    res = None

    def fit():
        nonlocal res
        res = batch_fit(problem, opts)

    t_gcs = best_of(fit, 2)
    print(f"gcs batch: {t_gcs:.2f} s, {res.iterations} iterations, {res.status}")
    names = list(res.solve_for)
    out = {"hours": hours, "measurements": n_meas, "n": len(names), "t_gcs": t_gcs}

    # one batch iteration at a new state (the propagation is not cached) vs the roofline
    values = res.state.values()
    att = problem.attitude

    def iteration():
        if hasattr(att, "clear_cache"):
            att.clear_cache()
        return normal_equations(problem, values, names, {})

    _, _, _, m = iteration()
    t_iter = best_of(iteration, 5)
    H = np.random.default_rng(0).standard_normal((m, len(names)))
    t_roof = best_of(lambda: H.T @ H, 7)
    del H
    print(f"one gcs iteration: {t_iter:.3f} s; bare HᵀWH ({m}×{len(names)}): {t_roof:.3f} s; "
          f"ratio {t_iter / t_roof:.1f}× the roofline")
    out.update(t_iter=t_iter, t_roof=t_roof, rows=m)
    if skip_scipy:
        return out

    state = problem.state
    x0 = np.array([state[n].value for n in names])
    s0 = np.array([state[n].sigma0 for n in names])
    work = state.values()
    n_fun = [0]

    def fun(x):
        n_fun[0] += 1
        for j, nm in enumerate(names):
            work[nm] = x[j]
        parts = [np.where(b.valid[:, None], b.r / b.sensor.sigma, 0.0).ravel()
                 for b in iter_blocks(problem, work, jacobian=False)]
        parts.append((x - x0) / s0)
        return np.concatenate(parts)

    sig = np.sqrt(np.diag(res.P))
    t0 = time.perf_counter()
    ls = least_squares(fun, x0, jac="2-point", method="trf", x_scale=sig, xtol=1e-12, ftol=1e-12,
                       gtol=1e-12)
    t_ls = time.perf_counter() - t0
    dx = float(np.max(np.abs(ls.x - res.x) / sig))
    cost_ls = float(ls.fun @ ls.fun)
    cost_gcs = float(res.cost_history[-1])
    print(f"scipy least_squares (2-point FD Jacobian): {t_ls:.1f} s, {n_fun[0]} residual evaluations "
          f"({ls.nfev} steps); cost {cost_ls:.3f} against gcs {cost_gcs:.3f}; max |Δx|/σ = {dx:.3f}")
    print(f"RATIO gcs batch is {t_ls / t_gcs:.0f}× faster than least_squares on the same answer")
    out.update(t_ls=t_ls, dx_sigma=dx, cost_ls=cost_ls, cost_gcs=cost_gcs)
    return out


def main() -> None:
    ap = argparse.ArgumentParser()
    ap.add_argument("--hours", type=float, default=24.0)
    ap.add_argument("--skip-scipy", action="store_true")
    ap.add_argument("--cache", type=Path, default=None, help="keep the simulated mission here")
    args = ap.parse_args()
    if args.cache is not None:
        args.cache.mkdir(parents=True, exist_ok=True)
        run(args.hours, args.cache, args.skip_scipy)
        return
    with tempfile.TemporaryDirectory() as tmp:
        run(args.hours, Path(tmp), args.skip_scipy)


if __name__ == "__main__":
    main()
