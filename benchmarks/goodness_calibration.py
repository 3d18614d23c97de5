"""Are the goodness-of-fit p-values honest? Uniform on a correct model.

A χ² test on the right degrees of freedom gives p-values uniform on [0, 1] when the model
is right. This runs ``--runs`` seeds of a nominal three-axis mission on which the chosen
estimator's model *is* right (by default the batch with a noiseless gyro, ``--gyro-noise``
to keep the flight-typical IRU), fits each with its held-out span, and tests the
p-values of every χ² test of :mod:`gcs_core.diagnosis.goodness` (whole fit, each sensor,
fitted and held-out) for uniformity (Kolmogorov–Smirnov), with the share below 0.05 and
0.01 and how many final verdicts read "model inadequate" (expected: α = 0.1 % of fits).

Usage::

    nice -n 10 python benchmarks/goodness_calibration.py [--runs 40] [--hours 1]
        [--mode sun_pointing] [--method batch] [--gyro-noise]
"""

from __future__ import annotations

import os

os.environ.setdefault("OPENBLAS_NUM_THREADS", "1")

import argparse
import logging
import sys
import tempfile
import time
from pathlib import Path

import numpy as np
from scipy import stats

ROOT = Path(__file__).resolve().parents[1]
sys.path[:0] = [str(ROOT), *(str(p) for p in sorted((ROOT / "tests").iterdir()) if p.is_dir())]

import honesty_cases as hc

from gcs_core.config_schema import AnalysisConfig
from gcs_core.session import Analysis
from gcs_core.sim.writer import write_mission


def main() -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--runs", type=int, default=40)
    ap.add_argument("--hours", type=float, default=1.0)
    ap.add_argument("--mode", default="sun_pointing", choices=hc.MODES)
    ap.add_argument("--method", default="batch")
    ap.add_argument("--gyro-noise", action="store_true", help="keep the flight-typical IRU noise")
    ap.add_argument("--entropy", type=int, default=20261204)
    args = ap.parse_args()
    logging.getLogger("gcs_core").setLevel(logging.ERROR)
    t0 = time.perf_counter()
    pv: dict[str, list[float]] = {}
    inadequate = 0
    seeds = np.random.SeedSequence(args.entropy).generate_state(args.runs, dtype=np.uint32)
    for k, seed in enumerate(seeds):
        cfg = hc.nominal(args.mode, int(seed), args.hours)
        if not args.gyro_noise:
            cfg.sensor("IRU").true.update(arw=0.0, rrw=0.0)
        with tempfile.TemporaryDirectory(prefix="gcs-gof-") as d:
            mission = write_mission(cfg, Path(d) / "mission", truth_path=Path(d) / "truth.json")
            a = Analysis(AnalysisConfig(mission=mission, method=args.method))
            a.fit()
            g = a.goodness()
        inadequate += not g.adequate
        for span, t in g.tests:
            key = f"{span} {'all' if t.label == 'all sensors' else t.label}"
            pv.setdefault(key, []).append(t.p_value)
        print(f"  {k + 1}/{args.runs}: χ²/dof {g.fit.reduced:.4f}, p {g.fit.p_value:.3f}", flush=True)
    print(
        f"\n{args.runs} runs, {args.mode}, {args.hours:g} h, method {args.method}, "
        f"gyro noise {'on' if args.gyro_noise else 'off'}"
    )
    print(f"{'test':22s} {'n':>4s} {'KS p':>7s} {'p<0.05':>7s} {'p<0.01':>7s} {'mean p':>7s}")
    allp = []
    for key, v in sorted(pv.items()):
        v = np.asarray(v)
        allp += list(v)
        print(
            f"{key:22s} {v.size:4d} {stats.kstest(v, 'uniform').pvalue:7.3f} {np.mean(v < 0.05):7.3f} "
            f"{np.mean(v < 0.01):7.3f} {np.mean(v):7.3f}"
        )
    allp = np.asarray(allp)
    print(
        f"{'every test':22s} {allp.size:4d} {'':>7s} {np.mean(allp < 0.05):7.3f} {np.mean(allp < 0.01):7.3f} "
        f"{np.mean(allp):7.3f}"
    )
    print(f"verdict 'model inadequate' on {inadequate} of {args.runs} fits (expected ≈ 0.1 %)")
    print(f"{time.perf_counter() - t0:.0f} s")
    return 0


if __name__ == "__main__":
    sys.exit(main())
