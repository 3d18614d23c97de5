"""Predicted σ (no data, seed Eq 3-2) against post-fit σ (batch calibration) on simulated data.

For each attitude mode and seed, the truth simulator flies the data plan's attitude
exactly (constant roll/pitch/yaw, four constant-rate maneuvers of Eq 4-36, no wobble);
the calibration fits the simulated files and the predictor predicts the same plan from
the mission description and ephemeris only. Prints, per case, the frame counts, the
worst ratio predicted/post-fit over all solve-for elements, the elements outside ±15 %,
and the times of both. A last block repeats one case with the predictor's two star
models (synthetic sky, evenly spread stars) to show what the sky does to the tracker
scale factors.

Usage: ``python benchmarks/predictor_vs_fit.py [--hours 1] [--seeds 5]``
"""

from __future__ import annotations

import argparse
import sys
import tempfile
import time
from pathlib import Path

import numpy as np

REPO = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(REPO))

from gcs_core.config import AnalysisConfig, Maneuver  # noqa: E402
from gcs_core.predictor import DataPlan, predict  # noqa: E402
from gcs_core.session import Analysis  # noqa: E402
from gcs_core.sim import nominal_threeaxis, write_mission  # noqa: E402
from gcs_core.sim.config import Slew, ThreeAxisProfile  # noqa: E402
from gcs_core.units import DEG  # noqa: E402

TOLERANCE = 0.15
OFFSETS_DEG = {"sun_pointing": (1.0, 3.0, -2.0), "inertial": (0.0, 0.0, 0.0), "earth_pointing": (0.0, 0.0, 0.0)}


def case(mode: str, seed: int, span: float, folder: Path, stars: str = "sky"):
    cfg = nominal_threeaxis(mode, seed=seed, duration_s=span)
    slews = [Slew(0.22 * span, 600.0, "roll", 0.04, ramp_s=0.0), Slew(0.45 * span, 300.0, "pitch", 0.02, ramp_s=0.0),
             Slew(0.60 * span, 300.0, "yaw", -0.02, ramp_s=0.0), Slew(0.75 * span, 600.0, "roll", -0.04, ramp_s=0.0)]
    rpy0 = tuple(np.add(cfg.attitude.rpy0_deg, OFFSETS_DEG[mode]))
    cfg.attitude = ThreeAxisProfile(rpy0_deg=rpy0, wobble_amp_deg=(0.0, 0.0, 0.0), slews=slews)
    mdir = write_mission(cfg, folder / f"{mode}-{seed}")
    t0 = time.perf_counter()
    analysis = Analysis(AnalysisConfig(mission=mdir, holdout_fraction=0.0))
    fit = analysis.fit(holdout=False)
    t_fit = time.perf_counter() - t0
    plan = DataPlan(0.0, span, step=60.0, rpy0=tuple(a * DEG for a in rpy0), stars=stars,
                    maneuvers=tuple(Maneuver(s.t_start, s.duration_s, s.axis, s.rate_deg_s) for s in slews))
    t0 = time.perf_counter()
    pred = predict(analysis.mission, plan=plan)
    t_pred = time.perf_counter() - t0
    ratio = pred.noise_only / np.sqrt(np.diag(fit.P))
    return fit, pred, ratio, t_fit, t_pred


def main() -> None:
    ap = argparse.ArgumentParser()
    ap.add_argument("--hours", type=float, default=1.0)
    ap.add_argument("--seeds", type=int, default=5)
    args = ap.parse_args()
    span = args.hours * 3600.0
    outside_total = 0
    with tempfile.TemporaryDirectory() as tmp:
        for mode in ("sun_pointing", "inertial"):
            for seed in range(1, args.seeds + 1):
                fit, pred, ratio, t_fit, t_pred = case(mode, seed, span, Path(tmp))
                worst = int(np.argmax(np.abs(ratio - 1.0)))
                outside = [f"{n} {r:.2f}" for n, r in zip(pred.names, ratio) if abs(r - 1.0) > TOLERANCE]
                outside_total += len(outside)
                frames = {k: (pred.frames[k], r.n) for k, r in fit.residuals.items()}
                print(f"{mode:14s} seed {seed}: fit {t_fit:5.2f} s, predict {t_pred:5.2f} s; "
                      f"worst {pred.names[worst]} {ratio[worst]:.3f}; frames (predicted, fitted) {frames}"
                      + (f"; outside ±15 %: {outside}" if outside else ""))
        print("\nstar models, sun_pointing seed 2 (tracker scale factors, predicted/post-fit):")
        for stars in ("sky", "uniform"):
            _, pred, ratio, _, _ = case("sun_pointing", 2, span, Path(tmp) / stars, stars)
            sel = [i for i, n in enumerate(pred.names) if ".scale_" in n and n.startswith("FHST")]
            print(f"  {stars:8s} " + ", ".join(f"{pred.names[i]} {ratio[i]:.3f}" for i in sel))
    print(f"\nelements outside ±15 %: {outside_total}")


if __name__ == "__main__":
    main()
