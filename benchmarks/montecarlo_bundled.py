"""Monte Carlo of every bundled study's plan against its predicted σ (issue 24).

For each ``sample_data/trade/*.toml`` (or the studies named), ``gcs montecarlo`` flies the
config's ``[prediction]`` plan ``--runs`` times (default 200) with the config's estimator
(the default whole span), the truth's a priori drawn per run, and prints the summary of
:func:`gcs_core.trade.montecarlo.summary_lines`: each element's scatter / predicted σ with
its χ² sampling band widened by 15 %, and the NEES with its 95 % band. Exits 1 when a study
does not match.

Usage::

    python benchmarks/montecarlo_bundled.py [--runs 200] [--seed 20261204] [--workers 2]
        [--study smm-tam-bias --study smm-gyro ...]

CPU: a run is a simulation and a fit; 200 runs of all five studies took 1 min 50 s on two
workers (3 min 11 s of CPU, 2026-12-05; 12 s for the TAM-bias plan, 21–26 s for each of
the others).
"""

from __future__ import annotations

import argparse
import sys
import time
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT))

from gcs_core.trade.montecarlo import MonteCarlo, run_montecarlo, summary_lines


def main() -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--runs", type=int, default=200)
    ap.add_argument("--seed", type=int, default=20261204)
    ap.add_argument("--workers", type=int, default=0)
    ap.add_argument("--study", action="append", default=[], help="a study name (smm-gyro) or file; repeatable")
    args = ap.parse_args()
    studies = [Path(s) if s.endswith(".toml") else ROOT / "sample_data" / "trade" / f"{s}.toml" for s in args.study]
    studies = studies or sorted((ROOT / "sample_data" / "trade").glob("*.toml"))
    failed = []
    for path in studies:
        t0 = time.perf_counter()
        res = run_montecarlo(MonteCarlo(str(path), args.runs, args.seed), workers=args.workers or None)
        print(f"== {path.name} ({time.perf_counter() - t0:.0f} s)")
        print("\n".join(summary_lines(res)))
        print()
        if not res.consistent:
            failed.append(path.name)
    print("every study matches" if not failed else f"do NOT match: {', '.join(failed)}")
    return 1 if failed else 0


if __name__ == "__main__":
    sys.exit(main())
