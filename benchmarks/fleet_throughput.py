"""``gcs fleet`` throughput on a simulated fleet (gcs_core.fleet.simulate): spacecraft-days
per minute, the 2-worker speed-up over 1 worker for one fleet-day, and the memory per
worker against the fleet's size.

Steps (each run on its own LocalCluster of single-threaded workers on 127.0.0.1):

1. simulate N spacecraft × D days of ``--span`` seconds each (varied orbits and modes,
   hidden effects, a moving bias, malformed files: see the simulator's docstring);
2. day 1 of the whole fleet on 1 worker, then again (fresh output) on 2 workers: the
   speed-up is the ratio of their compute times (cluster start excluded, printed apart);
3. the remaining days on the 2-worker output: spacecraft-days per minute over the run;
4. day 1 of the first N/5 spacecraft on 2 fresh workers: the peak memory per worker for a
   fifth of the fleet beside the whole fleet's (flat when the tasks free what they held).

The machine's other load disturbs every time here (developers and CI share two cores):
the load average is printed, and so is what two plain processes get at that moment (a
pure-Python loop serially and on 2 processes, :func:`trade_scaling.parallel_ceiling`),
the ceiling any scale-out can reach then.

Usage: ``python benchmarks/fleet_throughput.py [--spacecraft 50] [--days 3] [--span 900]``
"""

from __future__ import annotations

import os

os.environ.setdefault("OPENBLAS_NUM_THREADS", "1")

import argparse
import json
import shutil
import sys
import tempfile
import time
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT))

from dataclasses import replace

from gcs_core.fleet.manifest import read_manifest
from gcs_core.fleet.report import build_report
from gcs_core.fleet.run import run_fleet
from gcs_core.fleet.simulate import simulate_fleet

#: the acceptance target of the 2-worker speed-up
TARGET = 1.7


def _peak(run) -> float:
    return max((w["peak_mb"] for w in run.worker_memory_mb.values()), default=float("nan"))


def _states(run) -> str:
    states = [e.state for e in run.entries]
    return ", ".join(f"{states.count(s)} {s}" for s in sorted(set(states)))


def _expected_moves(truth: dict) -> set:
    """(spacecraft, day) where the bias has moved since the last good day without the move."""
    out = set()
    for sc, r in truth.items():
        base = False  # a good day before the move was seen
        for day, rec in r["days"].items():
            if rec["malformed"]:
                continue
            if any(i.get("moved") for i in rec["injected"]):
                if base:
                    out.add((sc, day))
                break
            base = True
    return out


def _against_truth(report: dict, root: Path) -> str:
    """What the report names against what the simulator injected (truth.json)."""
    truth = json.loads((root / "truth.json").read_text())["spacecraft"]
    days = {(sc, d): rec for sc, r in truth.items() for d, rec in r["days"].items()}
    bad = {k for k, rec in days.items() if rec["malformed"]}
    effect = {sc for (sc, _), rec in days.items() if any(not i.get("moved") for i in rec["injected"])}
    moves = _expected_moves(truth)
    injected = effect | {sc for sc, _ in moves}
    r_bad = {(x["spacecraft"], x["day"]) for x in report["errors"]}
    r_eff = {d["spacecraft"] for d in report["discovered"]}
    r_moved = {(x["spacecraft"], x["day"]) for x in report["moved"]}
    outliers = {o.split("/")[0] for k in report["distributions"].values() for d in k.values() for o in d["outliers"]}
    return (
        f"against the truth: malformed {len(r_bad & bad)}/{len(bad)} listed ({len(r_bad - bad)} others); "
        f"hidden effect {len(r_eff & effect)}/{len(effect)} spacecraft discovered ({len(r_eff - effect)} others); "
        f"moved bias {len(r_moved & moves)}/{len(moves)} named (others: {sorted(r_moved - moves)}); "
        f"outliers: {len(outliers & injected)} injected spacecraft, others {sorted(outliers - injected)}"
    )


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--spacecraft", type=int, default=50)
    ap.add_argument("--days", type=int, default=3)
    ap.add_argument("--span", type=float, default=900.0, help="seconds of data per spacecraft-day")
    ap.add_argument("--keep", help="simulate into this folder and keep it (default: a temporary one)")
    a = ap.parse_args()
    from trade_scaling import parallel_ceiling

    root = Path(a.keep) if a.keep else Path(tempfile.mkdtemp(prefix="gcs-fleet-bench-"))
    t = time.perf_counter()
    manifest = simulate_fleet(root, a.spacecraft, a.days, duration_s=a.span, seed=7)
    print(
        f"simulated {a.spacecraft} spacecraft × {a.days} days of {a.span:g} s "
        f"in {time.perf_counter() - t:.0f} s ({root})"
    )
    m = read_manifest(manifest)
    day1 = [m.days[0]]

    print(f"load average {os.getloadavg()[0]:.2f}; two plain processes reach ×{parallel_ceiling():.2f} now")
    one = run_fleet(replace(m, output=root / "out-1worker"), days=day1, workers=1)
    two = run_fleet(replace(m, output=root / "out"), days=day1, workers=2)
    speed = one.compute_s / two.compute_s
    print(
        f"day 1, {a.spacecraft} spacecraft: 1 worker {one.compute_s:.1f} s "
        f"(+{one.wall_s - one.compute_s:.1f} s start), "
        f"2 workers {two.compute_s:.1f} s (+{two.wall_s - two.compute_s:.1f} s start) [{_states(two)}]"
    )
    print(f"load average {os.getloadavg()[0]:.2f} after")

    rest = run_fleet(m, workers=2)  # days 2.. on the 2-worker output (day 1 is already done)
    report = build_report(m, rest)
    done = [e for e in two.entries + rest.entries if e.state == "calibrated"]
    errors = {(e.spacecraft, e.day) for e in two.entries + rest.entries if e.state == "error"}
    minutes = (rest.compute_s + two.compute_s) / 60.0
    print(
        f"whole fleet, 2 workers: {len(done)} spacecraft-days calibrated and {len(errors)} refused "
        f"in {minutes * 60:.0f} s of compute"
    )
    print(_against_truth(report, root))
    small = [sc.name for sc in m.spacecraft[: max(1, a.spacecraft // 5)]]
    fifth = run_fleet(replace(m, output=root / "out-fifth"), days=day1, spacecraft=small, workers=2)
    print(
        f"peak memory per worker: {len(small)} spacecraft-days {_peak(fifth):.0f} MB, "
        f"{a.spacecraft} spacecraft-days {_peak(two):.0f} MB (1 worker: {_peak(one):.0f} MB)"
    )
    print(
        f"2 workers / 1 worker for one fleet-day: ×{speed:.2f} (target ×{TARGET}); "
        f"spacecraft-days calibrated per minute: {len(done) / minutes:.1f} on 2 workers, "
        f"{sum(e.state == 'calibrated' for e in one.entries) / (one.compute_s / 60.0):.1f} on 1 (day 1)"
    )
    if not a.keep:
        shutil.rmtree(root, ignore_errors=True)


if __name__ == "__main__":
    main()
