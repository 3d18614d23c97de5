"""BROAD: the magnetometer's residual at rest and in motion, once its held repeats and
interpolated samples are flagged (``gcs convert broad``, :mod:`gcs_core.convert.holds`).

Data: D. Laidig, M. Caruso, A. Cereatti, T. Seel, "BROAD - A Benchmark for Robust Inertial
Orientation Estimation", Data 6(7), 2021, doi:10.3390/data6070072 (CC BY 4.0), the trials in
``../shared/real/broad`` (or the folder given as the first argument).

Each trial is converted whole and fitted as ``broad_consistency.py`` fits it (whole_span,
constant lab field with its gradient, the magnetometer's bias, (I + D) M and time offset,
the optical time offset). Printed per trial: the magnetometer's residual RMS [nT] and
normalized, at rest and in motion (BROAD's ``movement``), and in motion by the bus interval
before each measurement (2 or 4 bus intervals: after an interpolated sample, or after a
held value and an interpolated one), with the mean of the residual projected on the
direction the field turns, ``(ω × B)/|ω × B|`` (a time-tag error δt of a class shows as
a mean ``|ω × B| δt`` there; ω from the gyro, B the measurement); and the fitted
``MAG.time_offset`` against the held repeats' mean age. Usage:
``broad_mag_motion.py [FOLDER [TRIAL,TRIAL...]]``. Run under ``nice``: about a minute per trial.
"""

from __future__ import annotations

import sys
import tempfile
import time
from pathlib import Path

import numpy as np

sys.path.insert(0, str(Path(__file__).resolve().parent))
from broad_consistency import EFFECTS, MEMS_PRIORS, TRIALS
from gcs_core.config import default_config
from gcs_core.convert import convert
from gcs_core.io.importer import load_mission
from gcs_core.session import Analysis


def line(label, m, residual, unit, speed, sigma) -> None:
    """One row: the residual's RMS over the samples ``m``, normalized, and the time-tag
    error δt [ms] that best explains its component along the direction the field turns."""
    rr = residual[m]
    rms = np.sqrt(np.mean(rr**2, axis=0))
    along = np.einsum("ij,ij->i", rr, unit[m])
    dt_ms = 1e3 * np.sum(along * speed[m]) / np.sum(speed[m] ** 2)  # least squares
    print(
        f"  {label:<28} n {int(m.sum()):6d}  RMS [nT] {np.array2string(rms, precision=0)}"
        f"  normalized {np.sqrt(np.mean(rr**2)) / sigma:.3f}  along ω×B: δt {dt_ms:+.2f} ms"
    )


def main() -> int:
    root = Path(sys.argv[1]) if len(sys.argv) > 1 else Path(__file__).resolve().parents[2] / "shared/real/broad"
    trials = sys.argv[2].split(",") if len(sys.argv) > 2 and sys.argv[2] else TRIALS[:2]
    with tempfile.TemporaryDirectory() as tmp:
        for trial in trials:
            out = Path(tmp) / trial
            rep = convert("broad", root / f"{trial}.hdf5", out)
            for note in rep.notes:
                if note.startswith("repeats: magnetometer"):
                    print(f"  {note}")
            mv = np.loadtxt(out / "extra/movement.csv", delimiter=",", skiprows=1)
            mission = load_mission(out)
            cfg = default_config(out)
            cfg = cfg.with_changes(
                physics={"field_model": "constant"},
                state={"effects": tuple(EFFECTS), "elements": {**cfg.state.elements, **MEMS_PRIORS}},
            )
            a = Analysis(cfg, mission=mission)
            t0 = time.perf_counter()
            res = a.fit(holdout=False)
            r = res.residuals["MAG"]
            used = r.used
            sigma = float(np.ravel(r.sigma)[0])
            moving = np.interp(r.t, mv[:, 0], mv[:, 1]) > 0.5
            dt_bus = float(np.median(np.diff(mv[:, 0])))
            gap = np.r_[0, np.rint(np.diff(r.t) / dt_bus).astype(int)]
            g = mission.telemetry["GYR"]
            w = np.column_stack([np.interp(r.t, g.t, g.columns[c]) for c in ("wx", "wy", "wz")])
            turn = np.cross(w, r.y)  # the direction the measured field turns, |ω × B| [nT/s]
            speed = np.linalg.norm(turn, axis=1)
            unit = turn / np.maximum(speed, 1e-9)[:, None]
            print(f"{trial}: fitted in {time.perf_counter() - t0:.0f} s ({res.status}); noise {sigma:.0f} nT")

            for label, m in (
                ("at rest", ~moving),
                ("in motion", moving),
                ("in motion, after 2 intervals", moving & (gap == 2)),
                ("in motion, after 4 intervals", moving & (gap == 4)),
            ):
                line(label, m & used, r.residual, unit, speed, sigma)
            v = res.state.values()
            print(
                f"  MAG.time_offset {1e3 * v['MAG.time_offset']:.2f} ± {1e3 * res.sigma['MAG.time_offset']:.2f} ms,"
                f" OPT.time_offset {1e3 * v['OPT.time_offset']:.3f} ± {1e3 * res.sigma['OPT.time_offset']:.3f} ms",
                flush=True,
            )
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
