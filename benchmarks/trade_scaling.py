"""A trade study of ≥ 200 plans serially and on a 2-worker Dask LocalCluster.

The gyro study of seed §2.3.2 (``sample_data/trade/smm-gyro.toml``: one hour of
trackers, Sun sensor and gyro) over slew axis × slew angle × slew start: 3 × 12 × 6 = 216
plans. Prints the serial time, the LocalCluster time (cluster start included, and
without it), their ratio, and checks that both give identical numbers.

The machine's other load disturbs the ratio (two workers compete with every other
process for two cores): the load average is printed with it, and so is what the machine
gives two plain processes at that moment (a pure-Python loop, serially and on a 2-process
``multiprocessing`` pool): the ceiling any scale-out can reach then. "Running cluster"
times the study on a LocalCluster whose workers have already imported GCS (one plan
each); "cold" includes starting the cluster, the workers' imports, and stopping it.

It also prints where the time goes: a plan's own time serially and on a worker (the
same on idle cores; longer on a worker when the workers compete for cores with other
jobs) and how busy the workers were (the rest is the engine's overhead and the wait for
the last task). The last line holds the ratio.

Usage: ``python benchmarks/trade_scaling.py [--workers 2] [--angles 12] [--starts 6]``
"""

from __future__ import annotations

import os

os.environ.setdefault("OPENBLAS_NUM_THREADS", "1")

import argparse
import sys
import time
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT))

from gcs_core.config import load_config
from gcs_core.trade.engine import connect
from gcs_core.trade.run import run_study
from gcs_core.trade.study import definition_from_config

CONFIG = ROOT / "sample_data" / "trade" / "smm-gyro.toml"
#: the speed-up the scale-out must reach on two idle cores
TARGET = 1.6
T_START = time.perf_counter()


def _spin(n: int) -> float:
    t = time.perf_counter()
    x = 0.0
    for i in range(n):
        x += (i % 7) * 0.5
    return time.perf_counter() - t


def parallel_ceiling(n: int = 10_000_000) -> float:
    """Serial time / 2-process time of a pure-Python loop, now, on this machine."""
    from multiprocessing import get_context

    t = time.perf_counter()
    _spin(n)
    _spin(n)
    serial = time.perf_counter() - t
    with get_context("spawn").Pool(2) as pool:
        pool.map(_spin, [1, 1])  # the workers' start and imports, untimed
        t = time.perf_counter()
        pool.map(_spin, [n, n])
        return serial / (time.perf_counter() - t)


def main() -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--workers", type=int, default=2)
    ap.add_argument("--angles", type=int, default=12)
    ap.add_argument("--starts", type=int, default=6)
    args = ap.parse_args()
    angles = tuple(round(2.0 + i * (88.0 / max(1, args.angles - 1)), 3) for i in range(args.angles))
    vary = {
        "maneuver.axis": ("roll", "pitch", "yaw"),
        "maneuver.angle_deg": angles,
        "maneuver.rate_deg_s": (0.1,),
        "maneuver.start_min": tuple(range(5, 5 + 5 * args.starts, 5)),
        "maneuver.back": (True,),
    }
    defn = definition_from_config(load_config(CONFIG), vary)
    n = len(defn.combos())
    print(
        f"{n} plans; load average before: {os.getloadavg()[0]:.2f}; two plain processes run "
        f"{parallel_ceiling():.2f}× faster than one now"
    )
    run_study(definition_from_config(load_config(CONFIG), {"maneuver.axis": ("roll",)}))  # warm the caches
    t0 = time.perf_counter()
    serial = run_study(defn)
    t_serial = time.perf_counter() - t0
    print(f"serial: {t_serial:.1f} s ({t_serial / n * 1000:.0f} ms a plan)")

    t0 = time.perf_counter()
    client, cluster = connect(args.workers, None)
    address = cluster.scheduler_address
    t_start = time.perf_counter() - t0
    try:
        warm = definition_from_config(load_config(CONFIG), {"maneuver.axis": ("roll", "yaw")})
        run_study(warm, scheduler=address, batch=1)  # every worker imports GCS once
        t1 = time.perf_counter()
        dask_rows = run_study(defn, scheduler=address)
        t_dask = time.perf_counter() - t1
    finally:
        client.close()
        cluster.close()
    t0 = time.perf_counter()
    cold = run_study(defn, workers=args.workers)
    t_cold = time.perf_counter() - t0
    same = all(
        a.sigma == b.sigma == c.sigma and a.noise_only == b.noise_only == c.noise_only
        for a, b, c in zip(serial, dask_rows, cold)
    )
    print(
        f"LocalCluster of {args.workers} workers: {t_dask:.1f} s on a running cluster "
        f"(started in {t_start:.1f} s); {t_cold:.1f} s with its start and stop"
    )
    print(f"identical numbers serially and on the cluster: {'yes' if same else 'NO'}")
    # where the time goes: a plan's own time (PlanRow.seconds, wall clock in its process)
    # serially and on the workers, and how busy the workers were during the study
    busy_serial = sum(r.seconds for r in serial)
    busy_dask = sum(r.seconds for r in dask_rows)
    print(
        f"a plan: {busy_serial / n * 1000:.0f} ms serially, {busy_dask / n * 1000:.0f} ms on a worker "
        f"({busy_dask / busy_serial:.2f}×: the cores the workers share with everything else); workers busy "
        f"{100 * busy_dask / (args.workers * t_dask):.0f} % of the running-cluster time (the engine's "
        f"scheduling, transfer and the last task's wait are the rest)"
    )
    ceiling = parallel_ceiling()
    print(
        f"load average after: {os.getloadavg()[0]:.2f} (cores: {os.cpu_count()}); two plain processes "
        f"{ceiling:.2f}× faster than one"
    )
    print(
        f"\nRATIO serial / LocalCluster of {args.workers} workers, {n} plans: "
        f"{t_serial / t_dask:.2f}× on a running cluster (target ≥ {TARGET:g}×: "
        f"{'met' if t_serial / t_dask >= TARGET else 'NOT met'}); {t_serial / t_cold:.2f}× with the "
        f"cluster started and stopped by the study; the machine's ceiling now {ceiling:.2f}×"
    )
    print(f"benchmark: {time.perf_counter() - T_START:.0f} s")
    return 0 if same else 1


if __name__ == "__main__":
    sys.exit(main())
