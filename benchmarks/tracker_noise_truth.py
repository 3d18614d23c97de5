"""A star tracker's χ² at the truth: is a fit's excess the estimator's or the noise's?

When a fit reads "model inadequate" on a simulated mission whose model is right, either the
estimator (or its goodness test) is wrong, or the simulated noise itself is that far from
its σ. This tells the two apart for the star trackers: it simulates one mission
(:func:`honesty_cases.nominal`), fits it with the default config, and recomputes each
tracker's noise-free measurement with the simulator's own physics (:mod:`gcs_core.sim`:
the true attitude at ``t + time_offset``, the catalogue star of the row, stellar
aberration, Eq 4-29 and 4-30 with the true alignment and scale), so that

    e = y − h_true,     χ²_truth = Σ e² / σ²   on the fitted frames     (χ²_n under the noise model)

is the noise the simulator drew. Printed per tracker: the fit's χ² on its effective dof
with its p-value (:mod:`gcs_core.diagnosis.goodness`), ``χ²_truth`` on ``n`` with its
p-value, the RMS prediction error ``(ŷ − h_true)/σ``, and the truth χ²/n in twelve time
blocks and per focal-plane component. A fit whose χ² tracks ``χ²_truth`` (and a truth χ²
as far out as the fit's) says the draw, not the estimator, is unusual.

Usage::

    nice -n 10 python benchmarks/tracker_noise_truth.py [--mode sun_pointing] [--hours 24]
        [--seed 787181557] [--method whole_span]

The default case is the 24 h Sun-pointing seed of ``false_alarms_vs_span.py`` whose FHST2
read χ²/dof 1.061 on 11478 dof (p 2.9e-6): docs/benchmarks.md, "Long spans".
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
from gcs_core.sim import astro
from gcs_core.sim._rot import rpy_to_dcm
from gcs_core.sim.stars import aberrate
from gcs_core.sim.truth import World
from gcs_core.sim.writer import write_mission

BLOCKS = 12


def noise_free(cfg, sensor, tel: np.ndarray) -> np.ndarray:
    """The simulator's noise-free ``(h, v)`` of each telemetry row, (N, 2) [rad]
    (:class:`gcs_core.sim.stars.StarTrackerSim` without its noise draw)."""
    w = World(cfg)
    tt = tel["t"] + float(sensor.value("time_offset_s", 0.0))
    r, v = w.orbit(tt)
    a = np.radians(np.asarray(sensor.value("alignment_deg"), float))
    C_SI = rpy_to_dcm(a[0], a[1], a[2])[None] @ w.attitude(tt, r, v, w.sun(tt))
    ra, dec = np.radians(tel["ra"]), np.radians(tel["dec"])
    F_I = np.stack([np.cos(dec) * np.cos(ra), np.cos(dec) * np.sin(ra), np.sin(dec)], axis=-1)
    if cfg.physics.get("stellar_aberration", True):
        F_I = aberrate(F_I, (astro.earth_velocity_km_s(w.jd0, tt) + v) / astro.C_KM_S)
    F_S = np.einsum("nij,nj->ni", C_SI, F_I)
    scale = np.asarray(sensor.value("scale", (1.0, 1.0)), float)
    return np.stack([np.arcsin(np.clip(F_S[:, 2], -1, 1)), np.arctan2(F_S[:, 1], F_S[:, 0])], axis=-1) / scale


def main() -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--mode", default="sun_pointing", choices=hc.MODES)
    ap.add_argument("--hours", type=float, default=24.0)
    ap.add_argument("--seed", type=int, default=787181557)
    ap.add_argument("--method", default="whole_span")
    args = ap.parse_args()
    logging.getLogger("gcs_core").setLevel(logging.ERROR)
    t0 = time.perf_counter()
    cfg = hc.nominal(args.mode, args.seed, args.hours)
    with tempfile.TemporaryDirectory(prefix="gcs-tn-") as d:
        mission = write_mission(cfg, Path(d) / "mission", truth_path=Path(d) / "truth.json")
        a = Analysis(AnalysisConfig(mission=mission, method=args.method))
        a.fit()
        g = a.goodness()
        assert a.result is not None and g is not None  # a fit ran
        tels = {
            s.name: np.genfromtxt(mission / "telemetry" / f"{s.name}.csv", delimiter=",", names=True)
            for s in cfg.sensors
            if s.type == "star_tracker"
        }
    print(f"{args.mode}, {args.hours:g} h, seed {args.seed}, method {args.method}: {g.verdict}\n")
    for s in cfg.sensors:
        if s.type != "star_tracker":
            continue
        tel, res = tels[s.name], a.result.residuals[s.name]
        sigma = float(s.value("noise"))
        e = (np.column_stack([tel["h"], tel["v"]]) - noise_free(cfg, s, tel)) / sigma
        used = np.asarray(res.used, bool)
        err = e - res.normalized  # (ŷ − h_true)/σ: the fit's prediction error
        q = e[used] ** 2
        n = q.size
        fit = g.sensors[s.name]
        print(
            f"{s.name}: fit χ²/dof {fit.reduced:.4f} on {fit.dof:.0f} (p {fit.p_value:.2g}); "
            f"truth χ²/n {q.mean():.4f} on {n} (p {stats.chi2.sf(q.sum(), n):.2g}); "
            f"per component {q.mean(axis=0)[0]:.4f}, {q.mean(axis=0)[1]:.4f}; "
            f"prediction error RMS {np.sqrt(np.mean(err[used] ** 2)):.3f} σ"
        )
        t = res.t[used]
        edges = np.linspace(t.min(), t.max() + 1e-9, BLOCKS + 1)
        blocks = [q[(t >= lo) & (t < hi)] for lo, hi in zip(edges[:-1], edges[1:])]
        print(
            "    truth χ²/n in 12 time blocks: "
            + " ".join(f"{b.mean():.3f}" for b in blocks if b.size)
            + f" (each ± {np.sqrt(2.0 / np.mean([b.size for b in blocks])):.3f});"
            + f" KS of e against N(0, 1): h p {stats.kstest(e[used, 0], 'norm').pvalue:.2g},"
            + f" v p {stats.kstest(e[used, 1], 'norm').pvalue:.2g}"
        )
    print(f"\n{time.perf_counter() - t0:.0f} s")
    return 0


if __name__ == "__main__":
    sys.exit(main())
