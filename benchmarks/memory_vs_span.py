"""Peak memory against the span of data (issue 5): one day, three days, one week.

For each span, one child process imports the three-axis sample mission (every sensor:
TAM, IRU, two FHSTs, FSS, CSS; ``nominal_threeaxis("sun_pointing", duration_s=span)``),
fits it with the default estimator (:func:`~gcs_core.estimators.whole_span.fit.whole_span_fit`:
the batch, then the whole-span fit with the gyro noise as process noise, whose knots are
eliminated as the data pass them; default options: k-σ editing on) and
diagnoses it (:func:`~gcs_core.diagnosis.ranking.rank_candidates` over every candidate
effect), then reports its peak resident set size (``ru_maxrss``). The acceptance is a
week/day ratio below 1.5: the estimator streams the data by chunks, so only the data
themselves (and the post-fit residuals) grow with the span.

The missions are simulated once, each in its own process before the measured one (the
simulator writes long missions in chunks), and kept in ``--cache`` between runs. The
measured child drops the imported mission once the problem is built (the problem keeps
what estimation needs). The child also prints the resident set after each stage and the
bytes per frame the prepared data keep, which is the floor of the growth.

Usage: ``python benchmarks/memory_vs_span.py [--days 1 3 7] [--cache DIR] [--seed 7]``
"""

from __future__ import annotations

import argparse
import json
import subprocess
import sys
import tempfile
from pathlib import Path

REPO = Path(__file__).resolve().parents[1]
LIMIT = 1.5


def simulate(days: float, seed: int, cache: Path) -> Path:
    out = cache / f"threeaxis-{days:g}d-seed{seed}"
    if (out / "mission.toml").exists():
        return out
    truth = str(out) + "-truth.json"
    code = (
        f"import sys; from pathlib import Path; sys.path.insert(0, {str(REPO)!r})\n"
        "from gcs_core.sim.scenarios import nominal_threeaxis\n"
        "from gcs_core.sim.writer import write_mission\n"
        f"cfg = nominal_threeaxis('sun_pointing', seed={seed:d}, duration_s={days * 86400.0!r})\n"
        f"write_mission(cfg, Path({str(out)!r}), truth_path=Path({truth!r}))\n"
    )
    subprocess.run([sys.executable, "-c", code], check=True)
    return out


def child(mission_dir: str) -> None:
    """The measured process: import, fit, rank; prints one JSON line."""
    import gc
    import resource
    import time

    sys.path.insert(0, str(REPO))
    import numpy as np

    from gcs_core.diagnosis.catalogue import mission_catalogue
    from gcs_core.diagnosis.ranking import rank_candidates
    from gcs_core.estimators.batch.least_squares import BatchOptions
    from gcs_core.estimators.whole_span.fit import whole_span_fit
    from gcs_core.io.importer import load_mission
    from gcs_core.problem.build import build_problem
    from gcs_core.problem.prepare import PHYSICS_EFFECTS
    from gcs_core.problem.state import HELD

    def peak_mb() -> float:
        return resource.getrusage(resource.RUSAGE_SELF).ru_maxrss / 1024.0

    stages = {"start": peak_mb()}
    t0 = time.perf_counter()
    mission = load_mission(mission_dir)
    stages["import"] = peak_mb()
    problem = build_problem(mission)
    del mission
    gc.collect()
    stages["prepare"] = peak_mb()
    result = whole_span_fit(problem, BatchOptions())
    stages["fit"] = peak_mb()
    physics = problem.builder.physics.as_dict()
    effects = [
        e
        for e in mission_catalogue(problem, problem.builder.physics)
        if (e.physics and physics[e.effect] != PHYSICS_EFFECTS[e.effect][0])
        or (not e.physics and e.effect != "attitude" and all(problem.state[n].role == HELD for n in e.elements))
    ]
    cands = rank_candidates(problem, result, effects)
    stages["rank"] = peak_mb()
    frames = sum(sd.n for sd in problem.sensors)
    seen: set[int] = set()

    def size(a) -> int:
        if not isinstance(a, np.ndarray):
            return 0
        base = a if a.base is None else a.base
        if id(base) in seen:
            return 0
        seen.add(id(base))
        return base.nbytes

    data = 0
    for sd in problem.sensors:
        g = sd.geom
        data += sum(size(x) for x in (sd.t, sd.y, sd.lines, g.sun_I, g.B_I, g.star_I, g.r_I, g.v_I))
        data += sum(size(x) for x in g.extra.values())
    att = problem.attitude
    data += sum(size(getattr(att, k, None)) for k in ("y", "knots"))
    res = 0
    for r in result.residuals.values():
        res += sum(size(x) for x in (r.y_pred_, r.residual, r.normalized_, r.used, r.valid, r.edited))
    print(
        json.dumps(
            {
                "stages": stages,
                "seconds": time.perf_counter() - t0,
                "frames": frames,
                "iterations": result.iterations,
                "status": result.status,
                "candidates": len(cands),
                "data_mb": data / 1e6,
                "residuals_mb": res / 1e6,
            }
        )
    )


def measure(mission: Path) -> dict:
    out = subprocess.run(
        [sys.executable, str(Path(__file__).resolve()), "--child", str(mission)],
        check=True,
        capture_output=True,
        text=True,
    )
    return json.loads(out.stdout.strip().splitlines()[-1])


def main() -> None:
    ap = argparse.ArgumentParser()
    ap.add_argument("--days", type=float, nargs="+", default=[1.0, 3.0, 7.0])
    ap.add_argument("--cache", type=Path, default=None, help="keep the simulated missions here")
    ap.add_argument("--seed", type=int, default=7)
    ap.add_argument("--child", default=None, help=argparse.SUPPRESS)
    args = ap.parse_args()
    if args.child:
        child(args.child)
        return
    tmp = None
    cache = args.cache
    if cache is None:
        tmp = tempfile.TemporaryDirectory()
        cache = Path(tmp.name)
    cache.mkdir(parents=True, exist_ok=True)
    rows = {}
    print(
        f"{'span':>6} {'frames':>9} {'import':>7} {'prepare':>8} {'fit':>7} {'rank':>7} {'data':>7} "
        f"{'resid':>7} {'time':>7}   (peak RSS so far, MB; data/resid: MB kept)"
    )
    for d in args.days:
        r = measure(simulate(d, args.seed, cache))
        s = r["stages"]
        rows[d] = r
        print(
            f"{d:5g}d {r['frames']:9d} {s['import']:7.0f} {s['prepare']:8.0f} {s['fit']:7.0f} "
            f"{s['rank']:7.0f} {r['data_mb']:7.1f} {r['residuals_mb']:7.1f} {r['seconds']:6.0f}s "
            f"({r['iterations']} iterations, {r['status']}, {r['candidates']} candidates)"
        )
    if 1.0 in rows and 7.0 in rows:
        day, week = rows[1.0], rows[7.0]
        ratio = week["stages"]["rank"] / day["stages"]["rank"]
        per_day = (week["data_mb"] + week["residuals_mb"] - day["data_mb"] - day["residuals_mb"]) / 6.0
        print(f"kept per day of data: {per_day:.1f} MB (prepared data + post-fit residuals)")
        print(f"RATIO peak RSS week/day = {ratio:.2f} (limit {LIMIT}) -> {'met' if ratio < LIMIT else 'NOT met'}")
    if tmp is not None:
        tmp.cleanup()


if __name__ == "__main__":
    main()
