"""BROAD: where the magnetometer's disagreement between halves and trials comes from.

Data: D. Laidig, M. Caruso, A. Cereatti, T. Seel, "BROAD - A Benchmark for Robust Inertial
Orientation Estimation", Data 6(7), 2021, doi:10.3390/data6070072 (CC BY 4.0), trials 02
(slow rotation) and 09 (fast rotation with breaks) as published in ``../shared/real/broad``
(or the folder given as the first argument). Each experiment fits the whole trial, its
halves (t < T/2, t ≥ T/2) and, as a check of the σ themselves, two interleaved sets of
alternate :data:`INTERLEAVE_S` blocks (the same span and motions), and compares them as
``z = (x_A − x_B) / sqrt(σ_A² + σ_B²)``, with σ from the batch-means sandwich over
contiguous :data:`BLOCK_S` windows (the residuals are correlated over seconds):
``cov = H⁻¹ (Σ_b g_b g_bᵀ) H⁻¹``, ``H = JᵀJ``, ``g_b = J_bᵀ r_b`` the score of window b.

The magnetometer model is ``R P (y − b) = C_BL(t + δ) B(p)``: ``b`` the bias [µT], ``P`` a
symmetric matrix (the magnetometer's scale and non-orthogonality, its common scale fixed by
the field's magnitude :data:`F0` at :data:`P_REF`), ``R`` the rotation of the magnetometer's
frame into the frame it is referenced to, ``B(p) = B_0 + G (p − P_REF)`` the lab field with
its gradient (``G`` symmetric and trace-free: curl- and divergence-free) at the optical
position ``p``. (``M⁻¹ = R P`` is the polar decomposition of the inverse of the usual
3×3 matrix.)

1. ``ellipsoid``: attitude-independent, from the magnitude alone, ``|P (y − b)| = F0 + g·(p −
   P_REF)`` (``g = Gᵀ B_0/|B_0|``, the gradient of |B|, fitted from the optical position, or
   neglected); no optical attitude, no gyro. Also with a linear bias drift ``b + ḃ (t − t_mid)``.
2. ``optical``: the same ``P``, ``b`` plus ``R`` (against the optical body frame), ``B_0``
   (direction), ``G`` and the time offset ``δ``, fitted against the optical attitude, residuals
   in the magnetometer's frame: the whole-span fit's magnetometer part, outside GCS. Variants:
   one δ per axis, a first-order low-pass after δ, one δ per place of a sample after the last
   held one (``phased``: the stream's time stamps step 1.5 ms off per sample), and a response
   of second degree in the field's direction (``quadratic``).
3. ``gyro``: ``R`` (against the gyro's frame), ``b``, ``P`` (its trace fixed: the equation is
   homogeneous in P) and ``δ`` (or δ by place) from how the measured field turns with the gyro
   over :data:`WINDOW_S`: ``R P (y(t₂) − b) = Φ(t₂, t₁) R P (y(t₁) − b)``, ``Φ`` the gyro's
   integrated rotation (its bias the mean rate at rest, t = 1–6 s); no optical attitude.
4. ``gyro→optical``: the gyro's 3×3 matrix against the optical frame from the rotation
   vectors of the same windows, ``θ_opt = K θ_gyro`` (at the best optical time offset),
   ``K = R_og S`` by polar decomposition, σ of R_og by drawing K from its covariance (seeded).
5. the whole-trial fit's mean residual at each rest, the optical fit with the bias wandering
   (``wander_s``: linear between knots every :data:`WANDER_S` s), and the per-fit
   floor ``s`` that would bring each comparison within 3σ, ``|Δ| = 3 sqrt(σ_A² + σ_B² + 2 s²)``.

The last table gives the change of each rotation between halves, interleaved sets and trials:
if the magnetometer turns alike against the gyro and against the optical frame while the
optical frame stands still against the gyro, the magnetometer (not the optical reference)
is what moves.

The magnetometer's exact repeats of its previous sample (29 % of ``imu_mag``: a
sample-and-hold on the unit's bus, an old value at a new time stamp) are left out, or kept
with a second argument ``keep_held`` (then without the δ-by-place fits). Usage:
``broad_magnetometer_sources.py [FOLDER [keep_held]]``; about a minute per trial
(numpy/scipy on the HDF5, run under ``nice``). ``broad_magnetometer_sources.py selfcheck``
runs each estimator on simulated trials of known truth (:mod:`_broad_mag_sim`); the
estimators are in :mod:`_broad_mag_fits`.
"""

from __future__ import annotations

import sys
import time
from pathlib import Path
from typing import Any

import numpy as np

from _broad_mag_fits import (
    PHASES,
    TRACE,
    WANDER_S,
    WINDOW_S,
    ellipsoid,
    gyro_attitude,
    gyro_optical,
    gyro_ref,
    load,
    optical,
    rot_sigma,
    segments,
)
from _broad_mag_sim import selfcheck

TRIALS = ("02_undisturbed_slow_rotation_B", "09_undisturbed_fast_rotation_with_breaks_B")

# -- reporting --------------------------------------------------------------------------------

NAMES_E = ["P_xx", "P_yy", "P_zz", "P_xy", "P_xz", "P_yz", "b_x", "b_y", "b_z"]


def zline(label: str, names: list[str], a, b, sa, sb, scale: list[float]) -> str:
    """One comparison: the worst |z|, and the per-fit floor s that brings every element within
    3σ, |x_A − x_B| = 3 sqrt(σ_A² + σ_B² + 2 s²), then each element as A/B(z)."""
    sig = np.sqrt(sa**2 + sb**2)
    z = (a - b) / sig
    worst = int(np.argmax(np.abs(z)))
    floor = np.sqrt(np.maximum(0.0, ((a - b) ** 2 / 9 - sig**2) / 2)) * np.asarray(scale)
    f_worst = int(np.argmax(floor))
    cells = " ".join(f"{n}:{x * s:+.3f}/{y * s:+.3f}({zz:+.1f})" for n, x, y, zz, s in zip(names, a, b, z, scale))
    return (
        f"  {label:<14} worst |z| {abs(z[worst]):5.1f} ({names[worst]}), 3σ floor {floor[f_worst]:.3g} "
        f"({names[f_worst]})  {cells}"
    )


def compare(title: str, fits: dict[str, dict[str, Any]], sl: slice, names: list[str], scale: list[float]) -> None:
    print(title)
    for tr in TRIALS:
        if tr in fits:
            h1, h2 = fits[tr]["h1"], fits[tr]["h2"]
            print(zline(tr[:2] + " halves", names, h1["x"][sl], h2["x"][sl], h1["ss"][sl], h2["ss"][sl], scale))
            if "A" in fits[tr]:
                a, b = fits[tr]["A"], fits[tr]["B"]
                print(zline(tr[:2] + " interleaved", names, a["x"][sl], b["x"][sl], a["ss"][sl], b["ss"][sl], scale))
    if all(tr in fits for tr in TRIALS):
        a, b = fits[TRIALS[0]]["whole"], fits[TRIALS[1]]["whole"]
        print(zline("02 vs 09", names, a["x"][sl], b["x"][sl], a["ss"][sl], b["ss"][sl], scale))


def rest_residuals(d: dict[str, Any], o: dict[str, Any]) -> list[tuple[float, float, np.ndarray, np.ndarray]]:
    """The fit's mean residual over each rest of at least 4 s (the gyro's rate, smoothed over
    0.5 s, below 0.03 rad/s) with its batch-means σ over 0.5-s windows [µT]."""
    w = np.linalg.norm(d["gyr"] - d["gyr"][(d["t"] > 1.0) & (d["t"] < 6.0)].mean(axis=0), axis=1)
    still = np.convolve(w, np.ones(143) / 143, mode="same") < 0.03
    edges = np.flatnonzero(np.diff(np.r_[0, still.astype(int), 0]))
    out = []
    for a, b in zip(edges[::2], edges[1::2]):
        ta, tb = d["t"][a] + 0.5, d["t"][b - 1] - 0.5
        if tb - ta < 3.0:
            continue
        sel = (o["t"] > ta) & (o["t"] < tb)
        blk = np.floor((o["t"][sel] - ta) / 0.5).astype(int)
        bm = np.array([o["res"][sel][blk == k].mean(axis=0) for k in np.unique(blk)])
        out.append((ta, tb, o["res"][sel].mean(axis=0), bm.std(axis=0, ddof=1) / np.sqrt(len(bm))))
    return out


def run_trial(folder: Path, tr: str, keep_held: bool) -> dict[str, Any]:
    t0 = time.perf_counter()
    d = load(folder / f"{tr}.hdf5", keep_held)
    segs = segments(d)
    att = gyro_attitude(d)
    out: dict[str, Any] = {"d": d}
    out["ell"] = {s: ellipsoid(d, m, True) for s, m in segs.items()}
    out["ell0"] = {s: ellipsoid(d, m, False) for s, m in segs.items()}
    out["drift"] = {s: ellipsoid(d, m, True, drift=True) for s, m in segs.items()}
    e = out["ell"]["whole"]
    out["opt"] = {s: optical(d, m, e) for s, m in segs.items()}
    out["gyr"] = {s: gyro_ref(d, m, att, TRACE) for s, m in segs.items()}
    out["go"] = {s: gyro_optical(d, m, att) for s, m in segs.items()}
    for q in out["go"].values():
        q["x"] = q["rot"]
        q["ss"] = rot_sigma(q)
    if not keep_held:
        out["optp"] = {s: optical(d, m, e, phased=True) for s, m in segs.items()}
        out["gyrp"] = {s: gyro_ref(d, m, att, TRACE, phased=True) for s, m in segs.items()}
        out["optq"] = {s: optical(d, m, e, phased=True, quadratic=True) for s, m in segs.items()}
        out["optw"] = {s: optical(d, m, e, phased=True, wander_s=WANDER_S) for s, m in segs.items()}
        out["rests"] = rest_residuals(d, out["optp"]["whole"])
    whole = segs["whole"]
    out["per_axis"] = optical(d, whole, e, per_axis=True)
    out["lowpass"] = optical(d, whole, e, lowpass=True)
    out["seconds"] = time.perf_counter() - t0
    return out


def fmt(v: np.ndarray, scale: float = 1e3, nd: int = 1) -> str:
    return "(" + ", ".join(f"{x * scale:.{nd}f}" for x in v) + ")"


def report_trial(tr: str, o: dict[str, Any], keep_held: bool) -> None:
    d = o["d"]
    phased = "optp" in o
    print(
        f"{tr}: {d['held_frac']:.1%} held magnetometer samples {'kept' if keep_held else 'left out'}; "
        f"{o['seconds']:.0f} s"
    )
    for s in ("whole", "h1", "h2", "A", "B"):
        e, e0, op, g, q = o["ell"][s], o["ell0"][s], o["opt"][s], o["gyr"][s], o["go"][s]
        keys = ["ell", "ell0", "drift", "opt", "gyr"] + (["optp", "gyrp"] if phased else [])
        bad = [k for k in keys if not o[k][s]["ok"]]
        line = (
            f"  {s:<5} RMS [µT]: ellipsoid {e['rms']:.3f} (uniform {e0['rms']:.3f}; the gradient moves |B| by "
            f"{e['path_dB']:.2f} µT over the path), optical {op['rms']:.3f}, gyro pairs {g['rms']:.3f}"
        )
        if phased:
            line += (
                f"; phased δ: optical {o['optp'][s]['rms']:.3f}, gyro pairs {o['gyrp'][s]['rms']:.3f}; "
                f"optical with Q {o['optq'][s]['rms']:.3f}"
            )
        print(line)
        print(
            f"        δ [ms]: MAG−optical {op['x'][19]:.2f} ± {op['ss'][19]:.2f}, MAG−gyro {g['x'][6]:.2f} ± "
            f"{g['ss'][6]:.2f}, optical−gyro {q['delta_ms']:.2f}; gyro→optical {q['rms'] * 1e3:.2f} mrad RMS per "
            f"{WINDOW_S:g}-s window; not converged or at a bound: {bad or 'none'}"
        )
        if phased:
            print(
                f"        δ by place after a held sample [ms]: optical {fmt(o['optp'][s]['x'][19:], 1, 2)}, "
                f"gyro {fmt(o['gyrp'][s]['x'][12:], 1, 2)}"
            )
            wx = o["optw"][s]["x"][19 + PHASES :].reshape(-1, 3)
            wrms = fmt(np.sqrt(np.mean(wx**2, axis=0)), 1e3, 0)
            print(f"        the bias's wander (knots every {WANDER_S:g} s): RMS {wrms} nT")
            qx, qs = o["optq"][s]["x"][19 + PHASES :], o["optq"][s]["ss"][19 + PHASES :]
            print(f"        Q [nT] (rows x, y, z; n_x², n_y², n_x n_y, n_x n_z, n_y n_z): {fmt(qx, 1e3, 0)}")
            print(f"          z: {fmt(qx / qs, 1, 1)}")
    pa, lp = o["per_axis"], o["lowpass"]
    print(
        f"  whole, a δ per axis: RMS {pa['rms']:.4f} µT, δ {fmt(pa['x'][19:22], 1, 2)} ± "
        f"{fmt(pa['ss'][19:22], 1, 2)} ms; "
        f"a first-order low-pass after δ: RMS {lp['rms']:.4f} µT, δ {lp['x'][19]:.2f}, τ {lp['x'][20]:.2f} ± "
        f"{lp['ss'][20]:.2f} ms (one δ: {o['opt']['whole']['rms']:.4f} µT)"
    )
    if phased:
        print("  the whole-trial optical fit (phased δ) at the rests: mean residual ± batch-means σ (0.5 s) [nT]")
        for ta, tb, mean, sig in o["rests"]:
            print(f"    {ta:6.1f}–{tb:6.1f} s: {fmt(mean, 1e3, 0)} ± {fmt(sig, 1e3, 0)}")


def halves_rotation(runs: dict[str, Any]) -> None:
    """The magnetometer's rotation change between halves (and trials) against the optical frame,
    against the gyro, and the gyro's against the optical frame, each with its σ."""
    key_o, key_g = ("optp", "gyrp") if "optp" in runs[TRIALS[0]] else ("opt", "gyr")
    print(f"\nRotation changes [mrad] (h2 − h1; 09 − 02), {key_o}/{key_g} fits, σ the sandwich's:")
    rows = [(tr[:2] + " halves", runs[tr], "h1", runs[tr], "h2") for tr in TRIALS]
    rows += [(tr[:2] + " B − A", runs[tr], "A", runs[tr], "B") for tr in TRIALS]
    rows.append(("09 − 02", runs[TRIALS[0]], "whole", runs[TRIALS[1]], "whole"))
    for label, ra, sa, rb, sb in rows:
        cells = []
        keys = [(key_o, slice(9, 12)), (key_g, slice(0, 3)), ("go", slice(0, 3))]
        if "optq" in ra:
            keys.append(("optq", slice(9, 12)))
        for key, sl in keys:
            a, b = ra[key][sa], rb[key][sb]
            dx = (b["x"][sl] - a["x"][sl]) * 1e3
            sg = np.sqrt(a["ss"][sl] ** 2 + b["ss"][sl] ** 2) * 1e3
            cells.append(f"{fmt(dx, 1, 1)} ± {fmt(sg, 1, 1)}")
        extra = f"; MAG→optical with Q {cells[3]}" if len(cells) > 3 else ""
        print(f"  {label:<10} MAG→optical {cells[0]}; MAG→gyro {cells[1]}; gyro→optical {cells[2]}{extra}")


def main() -> None:
    if len(sys.argv) > 1 and sys.argv[1] == "selfcheck":
        selfcheck()
        return
    folder = Path(sys.argv[1]) if len(sys.argv) > 1 and sys.argv[1] else Path("../shared/real/broad")
    keep_held = len(sys.argv) > 2 and sys.argv[2] == "keep_held"
    runs = {tr: run_trial(folder, tr, keep_held) for tr in TRIALS}
    for tr, o in runs.items():
        report_trial(tr, o, keep_held)
    kinds = ("ell", "ell0", "drift", "opt", "gyr", "go") + (() if keep_held else ("optp", "gyrp", "optq", "optw"))
    fits = {k: {tr: o[k] for tr, o in runs.items()} for k in kinds}
    pscale = [1e3] * 9
    rot = ["φ_x", "φ_y", "φ_z"]
    gnames = rot + ["b_x", "b_y", "b_z", "δ", "P_xx", "P_yy", "P_xy", "P_xz", "P_yz"]
    gscale = [1e3] * 6 + [1] + [1e3] * 5
    print("\nz = (A − B)/sqrt(σ_A² + σ_B²), σ the batch-means sandwich (4-s windows); P in 10⁻³, b in nT, φ in mrad\n")
    compare("1. ellipsoid, gradient of |B| from the optical position", fits["ell"], slice(0, 9), NAMES_E, pscale)
    compare("1'. ellipsoid, uniform field", fits["ell0"], slice(0, 9), NAMES_E, pscale)
    compare("1''. ellipsoid with a bias drift: b at mid-span", fits["drift"], slice(0, 9), NAMES_E, pscale)
    compare("    and the drift ḃ [nT/s]", fits["drift"], slice(12, 15), ["ḃ_x", "ḃ_y", "ḃ_z"], [1e3] * 3)
    compare("2. optical-referenced, one δ: P, b", fits["opt"], slice(0, 9), NAMES_E, pscale)
    compare("2. optical-referenced, one δ: R (MAG→optical)", fits["opt"], slice(9, 12), rot, [1e3] * 3)
    compare("3. gyro-referenced, one δ: R (MAG→gyro), b, δ, P", fits["gyr"], slice(0, 12), gnames, gscale)
    if not keep_held:
        compare(
            "2p. optical-referenced, δ by place after a held sample: P, b", fits["optp"], slice(0, 9), NAMES_E, pscale
        )
        compare("2p. optical-referenced, phased δ: R (MAG→optical)", fits["optp"], slice(9, 12), rot, [1e3] * 3)
        pnames = rot + ["b_x", "b_y", "b_z", "-", "P_xx", "P_yy", "P_xy", "P_xz", "P_yz"]
        sl = np.r_[0:6, 7:12]
        names = [pnames[i] for i in sl]
        sub = {tr: {s: {"x": f["x"][sl], "ss": f["ss"][sl]} for s, f in v.items()} for tr, v in fits["gyrp"].items()}
        compare("3p. gyro-referenced, phased δ: R (MAG→gyro), b, P", sub, slice(0, 11), names, [1e3] * 11)
        compare(
            "2q. optical-referenced, phased δ, response of second degree: P, b",
            fits["optq"],
            slice(0, 9),
            NAMES_E,
            pscale,
        )
        compare("2q. the same: R (MAG→optical)", fits["optq"], slice(9, 12), rot, [1e3] * 3)
        title = f"2w. optical-referenced, phased δ, the bias wandering (knots every {WANDER_S:g} s): P, b(t₀)"
        compare(title, fits["optw"], slice(0, 9), NAMES_E, pscale)
        compare("2w. the same: R (MAG→optical)", fits["optw"], slice(9, 12), rot, [1e3] * 3)
        qn = [f"Q_{a}{k}" for a in "xyz" for k in ("xx", "yy", "xy", "xz", "yz")]
        q0 = 19 + PHASES
        compare("2q. the same: Q [nT]", fits["optq"], slice(q0, q0 + 15), qn, [1e3] * 15)
    compare("4. gyro→optical rotation (polar part of K)", fits["go"], slice(0, 3), rot, [1e3] * 3)
    print("   K − I [10⁻³]:")
    for tr in TRIALS:
        for s, q in runs[tr]["go"].items():
            print(f"     {tr[:2]} {s:<5} " + np.array2string((q["K"] - np.eye(3)) * 1e3, precision=2).replace("\n", ""))
    halves_rotation(runs)


if __name__ == "__main__":
    main()
