"""BROAD trials: are the estimated σ honest? Halves of a trial against each other, and
trials against each other, as z-scores ``(x_a − x_b) / sqrt(σ_a² + σ_b²)``.

Data: D. Laidig, M. Caruso, A. Cereatti, T. Seel, "BROAD - A Benchmark for Robust Inertial
Orientation Estimation", Data 6(7), 2021, doi:10.3390/data6070072 (CC BY 4.0), three
trials as published in ``../shared/real/broad`` (or the folder given as the first argument).
Each trial (and each half, t < T/2 and t ≥ T/2) is converted with ``gcs convert broad`` into a
temporary directory and fitted (the second argument: the method, default whole_span) with the constant lab field,
the magnetometer's bias and 3×3 matrix ((I + D) M), the gyro's bias and matrix, and the time
offsets of the magnetometer and of the optical reference (against the gyro-carried attitude).
Prints one table per comparison; |z| ≤ 3 is the acceptance. Usage:
``broad_consistency.py [FOLDER [METHOD [TRIAL,TRIAL... [uniform]]]]`` (an empty TRIAL list:
all three). Run under ``nice``: each fit takes 6–180 s on the shared 2-core machine
(whole_span), about 10 minutes for the nine fits.

The residuals are not white on the time scale of the hand motions (the magnetometer's own
slow wander, ≈0.1 µT over seconds at rest; the optical reference interpolated between its
camera frames), so σ computed for white noise of the stated σ are optimistic. Each table
also gives ``z_s``: the σ of the magnetometer's, the field's and the optical reference's
elements scaled by the batch-means sandwich of :mod:`gcs_core.noise.correlation`
(windows of :data:`BLOCK_S`), which measures from the residuals how much information they
really carry.

The gyro's bias is not a constant in the whole-span fit: ``b(t) = bias + ḃ (t − t_mid) + β(t)``
with the knots' random walk β (:mod:`gcs_core.estimators.gyro_bias`), and the static ``bias`` is
its value at the span's first knot carried to the middle by the drift. Two halves' static
biases are therefore at different epochs; the halves are compared at the epoch where they
meet (``GYR.b_*(T/2)``, each σ with the walk the data leave open there), and each whole
trial's ``b(t)`` at its rests against the rest's own mean rate ``G⁻¹ ȳ`` (an independent
measurement: at rest the lab-relative rate is zero). Three times: with the book's rate random
walk (read off the unit's own rests); refitted with the σ_u the data support (marked
``*``), the best of :data:`RRW_SCALES` by the fit's evidence
(:mod:`gcs_core.estimators.whole_span.process_likelihood`); and refitted with the optical reference
weighted by its effective noise (marked ``†``, every element): its stated σ times the
long-run factor of its residuals over :data:`REF_BLOCK_S` windows, the product's
``[filter] noise_weighting = "long_run"`` for the sensor ``OPT``
(:mod:`gcs_core.noise.weighting`), since its error in motion is
correlated over 35–100 ms and a white-noise weight lets the knots follow it. Trials are
compared on their first rest's bias less the Earth's rate there, fitted and as the rest's
own mean. Fitting the
field gradient (``MAG.field_gradient``, aux ``pos_x/y/z`` from the optical position) is the
default; a fourth argument ``uniform`` leaves it out, for comparison.
"""

from __future__ import annotations

import sys
import tempfile
import time
from pathlib import Path
from typing import Any

import numpy as np

from gcs_core.config import default_config
from gcs_core.config_schema import ElementConfig
from gcs_core.convert import convert
from gcs_core.convert.broad import LAB_LATITUDE_DEG
from gcs_core.estimators.gyro_bias import gyro_bias_at
from gcs_core.estimators.whole_span.process_likelihood import rrw_profile
from gcs_core.frames.rotations import quat_to_dcm
from gcs_core.io.importer import load_mission
from gcs_core.models.gyro import g_matrix
from gcs_core.noise.correlation import sigma_scale
from gcs_core.session import Analysis
from gcs_core.units import OMEGA_EARTH

TRIALS = (
    "02_undisturbed_slow_rotation_B",
    "09_undisturbed_fast_rotation_with_breaks_B",
    "36_disturbed_attached_magnet_5cm",
)
EFFECTS = (
    "MAG.scale",
    "MAG.nonorthogonality",
    "MAG.alignment",
    "MAG.time_offset",
    "OPT.time_offset",
    "MAG.field_gradient",
)
#: the field's gradient about the file's mean position (aux pos_x/y/z from the optical position)
GRADIENT = tuple(f"field.G_{ab}" for ab in ("xx", "xy", "xz", "yy", "yz"))
#: a MEMS gyro's bias wanders by ~1e-4 rad/s over a minute (its Allan bias instability):
#: the linear drift of the batch gets an a priori to match, not the flight default 1e-9 rad/s²
BIAS_DRIFT = {f"GYR.bias_rate_{a}": ElementConfig(role="solve-for", sigma=1e-5) for a in "xyz"}
#: a-priori σ of a MEMS unit (the flight defaults, 1e-5 rad/s of gyro bias and 1e-3 of its
#: matrix, are a navigation-grade IRU's): the gyro bias and matrix free, the magnetometer's
#: non-orthogonality a few percent (as in tests/statistical/test_ground_mission.py)
MEMS_PRIORS = {
    **{f"GYR.bias_{a}": ElementConfig(sigma=1e-1) for a in "xyz"},
    **{f"GYR.G_{i}{j}": ElementConfig(sigma=0.05) for i in (1, 2, 3) for j in (1, 2, 3)},
    **{f"MAG.nonorth_{p}": ElementConfig(sigma=0.1) for p in ("xy", "xz", "yz")},
    **BIAS_DRIFT,
}
#: factors on the book's rate random walk over which the evidence is profiled
RRW_SCALES = (1.0, 10.0, 100.0, 300.0, 1000.0)
#: the window of the reference's long-run noise factor [s]: longer than its error's
#: correlation (35–100 ms), shorter than the gyro's knots need it to be trusted over
REF_BLOCK_S = 0.5
#: the sandwich's window [s]: longer than the hand motions' time scale (about a second)
BLOCK_S = 4.0
SHOWN = (
    tuple(f"MAG.bias_{a}" for a in "xyz")
    + tuple(f"MAG.scale_{a}" for a in "xyz")
    + ("MAG.nonorth_xy", "MAG.nonorth_xz", "MAG.nonorth_yz")
    + tuple(f"MAG.align_{k}" for k in (1, 2, 3))
    + ("MAG.time_offset", "OPT.time_offset")
    + GRADIENT
)


def fit(source: Path, work: Path, label: str, span=None, method="whole_span", effects=EFFECTS, epochs=None):
    """Convert and fit one trial (or its span); the shown elements as name -> (x, σ, sandwich
    scale), the gyro's bias ``b(t)`` at each of ``epochs`` (label -> t [s]) as
    ``GYR.b_<axis>(<label>)`` (σ with the walk, :mod:`gcs_core.estimators.gyro_bias`), the same
    refitted with the rate random walk the data support (the evidence over :data:`RRW_SCALES`,
    :mod:`gcs_core.estimators.whole_span.process_likelihood`) as ``GYR.b_<axis>(<label>)*``, and the fitted
    gyro matrix ``G`` under ``"_G"``."""
    out = work / label
    convert("broad", source, out, span=span)
    mission = load_mission(out)
    cfg = default_config(out)
    cfg = cfg.with_changes(
        method=method,
        physics={"field_model": "constant"},
        state={"effects": tuple(effects), "elements": {**cfg.state.elements, **MEMS_PRIORS}},
    )
    a = Analysis(cfg, mission=mission)
    t0 = time.perf_counter()
    res = a.fit(holdout=False)
    vals = res.state.values()
    rms = {s: round(float(v), 3) for s, v in a.rms().items()}
    sc = sigma_scale(a.problem, res, block_s=BLOCK_S).scale
    worst = max((n for n in sc if not n.startswith("GYR.")), key=lambda n: sc[n])
    print(
        f"  {label}: fitted in {time.perf_counter() - t0:.0f} s ({res.status}), normalized RMS {rms}, "
        f"sandwich σ scale ({BLOCK_S:g} s windows) {min(sc.values()):.2f} to {sc[worst]:.2f} ({worst}); "
        f"gyro rrw {next(s.book.get('rrw', 0.0) for s in mission.spec.sensors if s.type == 'gyro'):.3g} rad/s^1.5",
        flush=True,
    )
    row: dict[str, Any] = {
        n: (vals[n], res.sigma.get(n, np.nan), 1.0 if n.startswith("GYR.") else max(1.0, sc.get(n, 1.0)))
        for n in SHOWN
        if n in vals
    }
    if epochs and res.carries_process_noise:
        t1 = time.perf_counter()
        prof = rrw_profile(a.problem, res, RRW_SCALES)
        v = prof.neg2_log_evidence - prof.neg2_log_evidence.min()
        print(
            f"    the data's rrw: −2 log p over σ_u × {RRW_SCALES}: {np.round(v, 1).tolist()}, best × {prof.best:g} "
            f"= {prof.best * prof.sigma_u[0] / RRW_SCALES[0]:.3g} rad/s^1.5 ({time.perf_counter() - t1:.0f} s)",
            flush=True,
        )
        best = prof.results[int(np.argmin(prof.neg2_log_evidence))]
        # the reference weighted by its effective (long-run) noise: σ_OPT × s
        long_run = {"noise_weighting": "long_run", "noise_window": REF_BLOCK_S, "noise_sensors": ("OPT",)}
        a2 = Analysis(cfg.with_changes(filter=long_run), mission=mission)
        res2 = a2.fit(holdout=False)
        sc2 = sigma_scale(a2.problem, res2, block_s=BLOCK_S).scale
        vals2 = res2.state.values()
        assert a2.noise is not None
        print(
            f"    the reference at its long-run noise ({a2.noise.summary()}): {res2.status}, "
            f"normalized RMS { ({s: round(float(x), 3) for s, x in a2.rms().items()}) }",
            flush=True,
        )
        for n in SHOWN:
            if n in vals2 and not n.startswith("GYR."):
                row[f"{n}†"] = (vals2[n], res2.sigma.get(n, np.nan), max(1.0, sc2.get(n, 1.0)))
        for fitted, problem, mark in ((res, a.problem, ""), (best, a.problem, "*"), (res2, a2.problem, "†")):
            gb = gyro_bias_at(problem, fitted, list(epochs.values()))
            for k, lab in enumerate(epochs):
                for i, ax in enumerate("xyz"):
                    row[f"GYR.b_{ax}({lab}){mark}"] = (float(gb.b[k, i]), float(gb.sigma[k, i]), 1.0)
    row["_G"] = g_matrix({n.split(".", 1)[1]: v for n, v in vals.items() if n.startswith("GYR.G_")})
    return row


def table(title: str, a: dict, b: dict) -> int:
    print(f"\n{title}")
    print(f"{'element':<20}{'A':>14}{'σ_A':>11}{'s_A':>6}{'B':>14}{'σ_B':>11}{'s_B':>6}{'z':>8}{'z_s':>8}")
    worst: dict[str, list] = {}
    for n in a:
        if n.startswith("_") or n not in b:
            continue
        (xa, sa, ka), (xb, sb, kb) = a[n], b[n]
        z = (xa - xb) / np.hypot(sa, sb)
        zk = (xa - xb) / np.hypot(ka * sa, kb * sb)
        w = worst.setdefault(n[-1] if n[-1] in "*†" else "", [0.0, 0.0, ""])
        if abs(zk) > w[1]:
            w[1], w[2] = abs(zk), n
        w[0] = max(w[0], abs(z))
        print(f"{n:<20}{xa:>14.6g}{sa:>11.3g}{ka:>6.2f}{xb:>14.6g}{sb:>11.3g}{kb:>6.2f}{z:>8.2f}{zk:>8.2f}")
    for mark, (wz, wk, wn) in worst.items():
        what = {"": "the fits", "*": "σ_u the data's (*)", "†": "the reference at its long-run noise (†)"}[mark]
        print(
            f"worst |z|, {what}: {wz:.2f} with the fit's σ; {wk:.2f} with the sandwich's ({wn}; "
            f"{'within' if wk <= 3 else 'beyond'} 3σ)"
        )
    return int(worst.get("", [0.0, 0.0])[1] > 3)


#: batch-means window of a rest's mean gyro rate [s]
REST_BLOCK_S = 0.5


def rests(source: Path) -> list[dict]:
    """The trial's rest runs of at least 3 s (BROAD's ``movement`` false), each's middle
    half: its middle time, the raw gyro mean with a batch-means σ, and the Earth's rate
    in the unit's frame there (from the optical attitude)."""
    import h5py

    with h5py.File(source) as f:
        fs = float(f.attrs["sampling_rate"])
        y, moving, q = f["imu_gyr"][:], f["movement"][:], f["opt_quat"][:]
    edges = np.flatnonzero(np.diff(np.r_[0, (~moving).astype(int), 0]))
    lat = np.radians(LAB_LATITUDE_DEG)
    w_enu = OMEGA_EARTH * np.array([0.0, np.cos(lat), np.sin(lat)])
    out = []
    for i0, i1 in zip(edges[::2], edges[1::2], strict=True):
        if (i1 - i0) / fs < 3.0:
            continue
        a, b = i0 + (i1 - i0) // 4, i1 - (i1 - i0) // 4
        k = int(REST_BLOCK_S * fs)
        nb = (b - a) // k
        means = y[a : a + nb * k].reshape(nb, k, 3).mean(axis=1)
        qm = np.nanmean(q[a:b], axis=0)
        C_BI = quat_to_dcm(np.r_[qm[1:], qm[0]] / np.linalg.norm(qm))
        out.append(
            {
                "t": 0.5 * (a + b) / fs,
                "span": (i0 / fs, i1 / fs),
                "y": y[a:b].mean(axis=0),
                "sigma": means.std(axis=0, ddof=1) / np.sqrt(nb),
                "earth": C_BI @ w_enu,
            }
        )
    return out


def rest_table(title: str, row: dict, rest: list[dict], mark: str = "") -> int:
    """The fitted bias b(t) at each rest against the rest's own mean rate G⁻¹ ȳ less the
    Earth's rate there (at rest the lab-relative rate is zero; the converted mission states
    the lab's latitude, so the fit removes the Earth's rate from the gyro)."""
    print(f"\n{title}")
    print(f"{'rest [s]':<16}{'axis':>5}{'fitted b':>12}{'σ':>10}{'G⁻¹ȳ−Ω⊕':>12}{'σ':>10}{'z':>8}")
    worst = 0.0
    Ginv = np.linalg.inv(row["_G"])
    for k, r in enumerate(rest):
        yb = Ginv @ r["y"] - r["earth"]
        sy = np.abs(Ginv) @ r["sigma"]
        for i, ax in enumerate("xyz"):
            b, sb, _ = row[f"GYR.b_{ax}(rest {k + 1}){mark}"]
            z = (b - yb[i]) / np.hypot(sb, sy[i])
            worst = max(worst, abs(z))
            lab = f"{r['span'][0]:.0f}–{r['span'][1]:.0f}" if i == 0 else ""
            print(f"{lab:<16}{ax:>5}{b:>12.5g}{sb:>10.2g}{yb[i]:>12.5g}{sy[i]:>10.2g}{z:>8.2f}")
    print(f"worst |z| = {worst:.2f} ({'within' if worst <= 3 else 'beyond'} 3σ)")
    return int(worst > 3)


def first_rest(row: dict, rest: list[dict]) -> dict:
    """A whole trial's row for comparison with another trial: the static elements, and the
    gyro bias at the first rest less the Earth's rate there (the attitudes at rest differ
    between trials), fitted and as the rest's own mean rate."""
    out = {n: v for n, v in row.items() if "(rest " not in n}
    if not rest:
        return out
    r = rest[0]
    Ginv = np.linalg.inv(row["_G"])
    yb, sy = Ginv @ r["y"] - r["earth"], np.abs(Ginv) @ r["sigma"]
    for mark in ("", "*", "†"):
        for ax in "xyz":
            b, sb, _ = row[f"GYR.b_{ax}(rest 1){mark}"]
            out[f"GYR.b_{ax}(rest 1)−Ω⊕{mark}"] = (b, sb, 1.0)  # the fit's bias is without the Earth's rate
    for i, ax in enumerate("xyz"):
        out[f"rest_{ax}(1) G⁻¹ȳ−Ω⊕"] = (float(yb[i]), float(sy[i]), 1.0)
    return out


def main() -> int:
    root = Path(sys.argv[1]) if len(sys.argv) > 1 else Path(__file__).resolve().parents[2] / "shared/real/broad"
    method = sys.argv[2] if len(sys.argv) > 2 else "whole_span"
    trials = sys.argv[3].split(",") if len(sys.argv) > 3 and sys.argv[3] else TRIALS
    effects = EFFECTS[:-1] if len(sys.argv) > 4 and sys.argv[4] == "uniform" else EFFECTS
    bad = 0
    with tempfile.TemporaryDirectory() as tmp:
        work = Path(tmp)
        full = {}
        for trial in trials:
            src = root / f"{trial}.hdf5"
            print(f"{trial}:", flush=True)
            import h5py

            with h5py.File(src) as f:
                T = f["imu_gyr"].shape[0] / float(f.attrs["sampling_rate"])
            rest = rests(src)
            epochs = {f"rest {k + 1}": r["t"] for k, r in enumerate(rest)}
            whole = fit(src, work, trial, method=method, effects=effects, epochs=epochs)
            title = f"{trial}: the fitted gyro bias at each rest against the rest's mean rate"
            bad += rest_table(title + " (the book's rrw)", whole, rest)
            bad += rest_table(title + " (the data's rrw)", whole, rest, "*")
            bad += rest_table(title + " (the reference at its long-run noise)", whole, rest, "†")
            full[trial] = first_rest(whole, rest)
            half = {"T/2": T / 2}
            h1 = fit(src, work, trial + "-h1", span=(0.0, T / 2), method=method, effects=effects, epochs=half)
            h2 = fit(src, work, trial + "-h2", span=(T / 2, T), method=method, effects=effects, epochs=half)
            bad += table(f"{trial}: first half (A) against second half (B)", h1, h2)
        if all(t in full for t in TRIALS):
            bad += table("trial 02 (A) against trial 09 (B)", full[TRIALS[0]], full[TRIALS[1]])
            bad += table("trial 36, magnet attached (A), against trial 02 (B)", full[TRIALS[2]], full[TRIALS[0]])
    print(f"\n{bad} comparison(s) beyond 3σ")
    return 0


if __name__ == "__main__":
    sys.exit(main())
