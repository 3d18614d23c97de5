"""Whole-span convergence on a whole BROAD trial: iterations, wall time and final cost with
and without the knots re-solved at a step's statics (``BatchOptions.knot_correction``,
:mod:`gcs_core.estimators.whole_span.fit`).

Data: D. Laidig, M. Caruso, A. Cereatti, T. Seel, "BROAD - A Benchmark for Robust Inertial
Orientation Estimation", Data 6(7), 2021, doi:10.3390/data6070072 (CC BY 4.0), as published
in ``../shared/real/broad``. The trial (first argument, default trial 02, 186 s) is converted
with ``gcs convert broad`` (the lab's latitude written, so the fit removes the Earth's rate)
and fitted with the state of ``benchmarks/broad_consistency.py`` (the time offsets, the
magnetometer's matrix and alignment, the field's gradient, MEMS a priori) at an iteration
limit of :data:`LIMIT`. Prints, per fit: status, Gauss–Newton iterations, seconds, the final
cost, and how far the two solutions lie apart in σ. Usage:
``broad_convergence.py [HDF5 [LIMIT]]``; run under ``nice`` (a few minutes).
"""

from __future__ import annotations

import sys
import tempfile
import time
from dataclasses import replace
from pathlib import Path

import numpy as np

from broad_consistency import EFFECTS, MEMS_PRIORS, rests
from gcs_core.config import default_config
from gcs_core.convert import convert
from gcs_core.estimators.gyro_bias import gyro_bias_at
from gcs_core.estimators.whole_span.fit import whole_span_fit
from gcs_core.io.importer import load_mission
from gcs_core.models.gyro import g_matrix
from gcs_core.session import Analysis

#: the iteration limit per editing pass (the product's default is 20)
LIMIT = 60


def main() -> int:
    root = Path(__file__).resolve().parents[2] / "shared/real/broad"
    src = Path(sys.argv[1]) if len(sys.argv) > 1 else root / "02_undisturbed_slow_rotation_B.hdf5"
    limit = int(sys.argv[2]) if len(sys.argv) > 2 else LIMIT
    with tempfile.TemporaryDirectory() as tmp:
        out = Path(tmp) / "trial"
        convert("broad", src, out)
        cfg = default_config(out).with_changes(
            physics={"field_model": "constant"},
            state={"effects": EFFECTS, "elements": MEMS_PRIORS},
            filter={"max_iterations": limit},
        )
        a = Analysis(cfg, mission=load_mission(out))
        fits = {}
        for corrected in (False, True):
            opts = replace(a.batch_options(), knot_correction=corrected)
            t0 = time.perf_counter()
            res = whole_span_fit(a.problem, opts)
            dt = time.perf_counter() - t0
            fits[corrected] = res
            print(
                f"knots re-solved: {corrected!s:5}  {res.status:15} {res.iterations:3d} iterations "
                f"{dt:6.0f} s  cost {res.cost_history[-1]:.7g}  ({res.message})",
                flush=True,
            )
            # the gyro bias b(t) at each rest against the rest's own mean rate (broad_consistency)
            vals = res.state.values()
            Ginv = np.linalg.inv(g_matrix({n.split(".", 1)[1]: v for n, v in vals.items() if n.startswith("GYR.G_")}))
            rest = rests(src)
            gb = gyro_bias_at(a.problem, res, [r["t"] for r in rest])
            z = [
                (gb.b[k] - (Ginv @ r["y"] - r["earth"])) / np.hypot(gb.sigma[k], np.abs(Ginv) @ r["sigma"])
                for k, r in enumerate(rest)
            ]
            print(
                "    b(t) at the rests against their mean rate, z: "
                + "; ".join(np.array2string(x, precision=2) for x in z)
            )
        a_, b_ = fits[False], fits[True]
        va, vb = a_.state.values(), b_.state.values()
        z = {n: (va[n] - vb[n]) / b_.sigma[n] for n in b_.solve_for if b_.sigma.get(n, 0) > 0}
        worst = sorted(z, key=lambda n: -abs(z[n]))[:5]
        print("largest differences, in the corrected fit's σ: " + ", ".join(f"{n} {z[n]:+.2f}" for n in worst))
        others = [abs(z[n]) for n in z if not n.startswith(("GYR.", "att."))]
        print(f"every element but the gyro's and the attitude's within {max(others):.2f} σ")
    return 0


if __name__ == "__main__":
    sys.exit(main())
