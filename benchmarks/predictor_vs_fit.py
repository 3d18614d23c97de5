"""Predicted σ (no data, seed Eq 3-2) against post-fit σ (batch calibration) on simulated data.

For each attitude mode and seed, the truth simulator flies the data plan's attitude
exactly (constant roll/pitch/yaw, four constant-rate maneuvers of Eq 4-36, no wobble);
the calibration fits the simulated files and the predictor predicts the same plan from
the mission description and ephemeris only. The predictor runs with each star model
(:mod:`gcs_core.predictor.stars`) on the same fit: ``catalog`` (the mission's
``star_catalog.csv``, the catalog the simulator's trackers see), ``telemetry`` (the
distinct stars of the mission's own FHST files), and the old ``sky`` (a synthetic sky)
for comparison. Prints, per case, the frame counts, the worst ratio predicted/post-fit
over all solve-for elements per star model and the elements outside ±15 %; then, per
mode and model, the worst ratio over the seeds. For an element outside the band it also
prints the ratio when the same plan (catalog stars) is linearized at the *fitted* state
instead of the nominal one: a ratio near 1 there says the difference is the
linearization point (an element whose information depends on the estimate of another),
not the data modeling. Elements the plan does not determine at all
(:attr:`~gcs_core.predictor.predict.PredictionResult.undetermined`: predicted σ = the a
priori, e.g. an FSS sine frequency whose amplitude is nominally zero) are listed apart
with their ratio: their post-fit σ mirrors the a priori and the noise in the fitted
amplitude, not the plan.

Usage: ``python benchmarks/predictor_vs_fit.py [--hours 1] [--seeds 5] [--stars catalog,sky]``
"""

from __future__ import annotations

import argparse
import sys
import tempfile
import time
from dataclasses import replace
from pathlib import Path

import numpy as np

REPO = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(REPO))

from gcs_core.config_schema import AnalysisConfig, Maneuver
from gcs_core.ephem.ephemeris import Ephemeris
from gcs_core.predictor.plan import DataPlan
from gcs_core.predictor.predict import predict
from gcs_core.predictor.synth import plan_problem
from gcs_core.session import Analysis
from gcs_core.sim.config import Slew, ThreeAxisProfile
from gcs_core.sim.scenarios import nominal_threeaxis
from gcs_core.sim.writer import write_mission
from gcs_core.units import DEG

TOLERANCE = 0.15
OFFSETS_DEG = {"sun_pointing": (1.0, 3.0, -2.0), "inertial": (0.0, 0.0, 0.0), "earth_pointing": (0.0, 0.0, 0.0)}


STAR_MODELS = ("catalog", "telemetry", "sky")


def case(mode: str, seed: int, span: float, folder: Path, stars=STAR_MODELS):
    """Fit one simulated mission and predict its plan with each star model in ``stars``:
    (fit, {model: (prediction, ratio predicted/post-fit σ)}, fit time, predict times)."""
    cfg = nominal_threeaxis(mode, seed=seed, duration_s=span)
    slews = [
        Slew(0.22 * span, 600.0, "roll", 0.04, ramp_s=0.0),
        Slew(0.45 * span, 300.0, "pitch", 0.02, ramp_s=0.0),
        Slew(0.60 * span, 300.0, "yaw", -0.02, ramp_s=0.0),
        Slew(0.75 * span, 600.0, "roll", -0.04, ramp_s=0.0),
    ]
    rpy0 = tuple(np.add(cfg.attitude.rpy0_deg, OFFSETS_DEG[mode]))
    cfg.attitude = ThreeAxisProfile(rpy0_deg=rpy0, wobble_amp_deg=(0.0, 0.0, 0.0), slews=slews)
    mdir = write_mission(cfg, folder / f"{mode}-{seed}")
    t0 = time.perf_counter()
    analysis = Analysis(AnalysisConfig(mission=mdir).with_changes(diagnosis={"holdout_fraction": 0.0}))
    fit = analysis.fit(holdout=False)
    t_fit = time.perf_counter() - t0
    maneuvers = tuple(Maneuver(s.t_start, s.duration_s, s.axis, s.rate_deg_s) for s in slews)
    out, t_pred = {}, {}
    for model in stars:
        plan = DataPlan(0.0, span, step=60.0, rpy0=tuple(a * DEG for a in rpy0), stars=model, maneuvers=maneuvers)
        t0 = time.perf_counter()
        pred = predict(analysis.mission, plan=plan)
        t_pred[model] = time.perf_counter() - t0
        out[model] = (pred, pred.noise_only / np.sqrt(np.diag(fit.P)))
    return fit, out, t_fit, t_pred, (analysis, plan)


def at_fitted_state(analysis, fit, plan) -> np.ndarray:
    """Ratio predicted/post-fit σ for the plan's frames linearized at the fitted state."""
    m = analysis.mission
    planned = plan_problem(
        m.spec,
        Ephemeris.from_table(m.ephemeris_table),
        replace(plan, stars="catalog"),
        telemetry=m.telemetry,
        aux=m.aux,
        onboard=m.onboard,
    )
    problem = planned.problem
    problem = problem.with_state(problem.state.with_values(dict(zip(fit.solve_for, map(float, fit.x)))))
    return predict(problem, plan=plan).noise_only / np.sqrt(np.diag(fit.P))


def main() -> None:
    ap = argparse.ArgumentParser()
    ap.add_argument("--hours", type=float, default=1.0)
    ap.add_argument("--seeds", type=int, default=5)
    ap.add_argument("--stars", default=",".join(STAR_MODELS), help="star models, comma separated")
    ap.add_argument("--modes", default="sun_pointing,inertial", help="attitude modes, comma separated")
    args = ap.parse_args()
    span = args.hours * 3600.0
    models = tuple(args.stars.split(","))
    worst_of: dict = {}
    undetermined_of: dict = {}
    outside_total = {m: 0 for m in models}
    with tempfile.TemporaryDirectory() as tmp:
        for mode in args.modes.split(","):
            for seed in range(1, args.seeds + 1):
                fit, preds, t_fit, t_pred, (analysis, plan) = case(mode, seed, span, Path(tmp), models)
                refit = None
                pred0 = preds[models[0]][0]
                frames = {k: (pred0.frames[k], r.n) for k, r in fit.residuals.items()}
                print(
                    f"{mode:14s} seed {seed}: fit {t_fit:5.2f} s, predict {t_pred[models[0]]:5.2f} s; "
                    f"frames ({models[0]}, fitted) {frames}"
                )
                for model, (pred, ratio) in preds.items():
                    # the elements the plan does not determine (σ = a priori) are listed apart
                    und = set(pred.undetermined)
                    if und:
                        ratio = np.where([n in und for n in pred.names], 1.0, ratio)
                        post = np.sqrt(np.diag(fit.P))
                        for i, n in enumerate(pred.names):
                            if n in und:
                                undetermined_of.setdefault((mode, model), {}).setdefault(
                                    n, [pred.noise_only[i]]
                                ).append(post[i])
                    worst = int(np.argmax(np.abs(ratio - 1.0)))
                    outside = [f"{n} {r:.2f}" for n, r in zip(pred.names, ratio) if abs(r - 1.0) > TOLERANCE]
                    outside_total[model] += len(outside)
                    for group, sel in (
                        ("all", range(len(ratio))),
                        ("FHST", [i for i, n in enumerate(pred.names) if n.startswith("FHST")]),
                    ):
                        w = max(sel, key=lambda i: abs(ratio[i] - 1.0))
                        prev = worst_of.get((mode, model, group))
                        if prev is None or abs(ratio[w] - 1.0) > abs(prev[1] - 1.0):
                            worst_of[(mode, model, group)] = (pred.names[w], float(ratio[w]), seed)
                    print(
                        f"    {model:9s} worst {pred.names[worst]:15s} {ratio[worst]:.3f}"
                        + (f"; outside ±15 %: {outside}" if outside else "")
                    )
                    if outside and model == "catalog":
                        refit = at_fitted_state(analysis, fit, plan) if refit is None else refit
                        print(
                            "              linearized at the fitted state: "
                            + ", ".join(
                                f"{n} {refit[i]:.3f}"
                                for i, n in enumerate(pred.names)
                                if abs(ratio[i] - 1.0) > TOLERANCE
                            )
                        )
    print("\nworst predicted/post-fit σ over the seeds (every element; FHST elements only):")
    print(f"  {'mode':20s} " + " ".join(f"{m:>32s}" for m in models))
    for mode in args.modes.split(","):
        for group in ("all", "FHST"):
            cells = [worst_of[(mode, m, group)] for m in models]
            print(f"  {mode + ' ' + group:20s} " + " ".join(f"{f'{n} {r:.3f} (seed {sd})':>32s}" for n, r, sd in cells))
    print(
        "elements outside ±15 %: "
        + ", ".join(f"{m} {outside_total[m]}" for m in models)
        + " (the elements the plan determines)"
    )
    for (mode, model), items in undetermined_of.items():
        print(
            f"undetermined by the plan ({mode}, {model}): "
            + "; ".join(
                f"{n} predicted {v[0]:.3g} (the a priori), post-fit {min(v[1:]):.3g}–{max(v[1:]):.3g}"
                for n, v in items.items()
            )
        )


if __name__ == "__main__":
    main()
