"""BROAD: does discovery find the magnet fixed to the unit as a magnetometer bias?

Data: D. Laidig, M. Caruso, A. Cereatti, T. Seel, "BROAD - A Benchmark for Robust Inertial
Orientation Estimation", Data 6(7), 2021, doi:10.3390/data6070072 (CC BY 4.0), the trials in
``../shared/real/broad`` (or the folder given as the first argument).

The magnetometer is calibrated on the undisturbed trial 02 (bias, the 3×3 matrix (I + D) M,
time offset; the field of the lab and its gradient over the optical position estimated
with them). That calibration, the room's gradient with it, becomes the data book of the
other trials, with the magnetometer's bias held at it, and ``discover`` runs on
trial 09 (undisturbed, fast) and trial 36 (a magnet attached 5 cm from the unit). Printed:
the steps discovery takes on each, with their Δχ² and the held-out RMS. The magnet should
show as the bias effect added first on trial 36 and be far weaker or absent on trial 09.
Run under ``nice``: about two minutes.
"""

from __future__ import annotations

import sys
import tempfile
from pathlib import Path

from gcs_core.config import default_config
from gcs_core.config_schema import ElementConfig
from gcs_core.convert import convert
from gcs_core.io.importer import load_mission
from gcs_core.session import Analysis

sys.path.insert(0, str(Path(__file__).resolve().parent))
from broad_consistency import MEMS_PRIORS

CAL = ("MAG.scale", "MAG.nonorthogonality", "MAG.alignment", "MAG.time_offset", "OPT.time_offset", "MAG.field_gradient")
#: the room's field gradient [nT/m] (the same in every trial; B_0 is each trial's own, at its
#: mean position)
GRADIENT = tuple(f"field.G_{ab}" for ab in ("xx", "xy", "xz", "yy", "yz"))
MAG_ELEMENTS = tuple(
    f"MAG.{p}"
    for p in (
        "bias_x",
        "bias_y",
        "bias_z",
        "scale_x",
        "scale_y",
        "scale_z",
        "nonorth_xy",
        "nonorth_xz",
        "nonorth_yz",
        "align_1",
        "align_2",
        "align_3",
        "time_offset",
    )
)


def analysis(src: Path, out: Path, *, effects=(), exclude=(), elements=None) -> Analysis:
    convert("broad", src, out)
    cfg = default_config(out)
    cfg = cfg.with_changes(
        physics={"field_model": "constant"},
        state={"effects": tuple(effects), "exclude": tuple(exclude), "elements": {**MEMS_PRIORS, **(elements or {})}},
    )
    return Analysis(cfg, mission=load_mission(out))


def _r(d) -> dict:
    return {k: round(float(x), 3) for k, x in d.items()}


def main() -> int:
    root = Path(sys.argv[1]) if len(sys.argv) > 1 else Path(__file__).resolve().parents[2] / "shared/real/broad"
    with tempfile.TemporaryDirectory() as tmp:
        tmp = Path(tmp)
        a = analysis(root / "02_undisturbed_slow_rotation_B.hdf5", tmp / "02", effects=CAL)
        res = a.fit(holdout=False)
        v = res.state.values()
        print("calibration from trial 02:")
        for n in MAG_ELEMENTS:
            print(f"  {n:<18}{v[n]:>14.6g} ± {res.sigma[n]:.3g}", flush=True)
        # trial 02's values as the data book (roles by default: the matrix and time offset
        # held as extended physics, the bias held by ``exclude``; discovery may add them)
        for n in GRADIENT:
            print(f"  {n:<18}{v[n]:>14.6g} ± {res.sigma[n]:.3g}", flush=True)
        book = {n: ElementConfig(value=float(v[n])) for n in MAG_ELEMENTS + GRADIENT}
        for trial in ("36_disturbed_attached_magnet_5cm", "09_undisturbed_fast_rotation_with_breaks_B"):
            b = analysis(
                root / f"{trial}.hdf5", tmp / trial, effects=("OPT.time_offset",), exclude=("MAG.bias",), elements=book
            )
            first = b.first_step()
            print(
                f"\n{trial}: magnetometer held at trial 02's calibration; first fit normalized "
                f"RMS {_r(first.rms_after)}, held-out {_r(first.holdout_after)}"
            )
            top = b.rank()[:3]
            print(
                "  ranked: "
                + "; ".join(
                    f"{c.id} Δχ² {c.delta_chi2:.4g}" + ("" if c.identifiable else " (not identifiable)") for c in top
                ),
                flush=True,
            )
            for step in b.discover(max_steps=2)[1:]:
                print(
                    f"  {step.action} {step.effect}: Δχ² {step.delta_chi2:.4g}, normalized RMS "
                    f"{_r(step.rms_after)}, held-out {_r(step.holdout_after)}"
                )
                if step.effect == "MAG.bias":
                    print("    estimates: " + ", ".join(f"{n} {x:.5g}" for n, x in step.estimates.items()))
            print(f"  stopped: {b.stop_reason}")
    return 0


if __name__ == "__main__":
    sys.exit(main())
