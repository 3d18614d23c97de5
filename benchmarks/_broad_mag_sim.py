"""A simulated BROAD-like trial with known truth, and each estimator of
``_broad_mag_fits.py`` against it (``broad_magnetometer_sources.py selfcheck``)."""

from __future__ import annotations

from typing import Any

import numpy as np
from scipy.spatial.transform import Rotation, Slerp

from _broad_mag_fits import (
    F0,
    P_REF,
    PHASES,
    ellipsoid,
    grad,
    gyro_attitude,
    gyro_optical,
    gyro_ref,
    optical,
    rot_sigma,
    segments,
    sym,
)

#: the simulated magnetometer: its rotation into the body frame [rad], P and b [µT]
SIM_R = np.array([0.010, -0.005, -0.012])
SIM_P = np.array([1.004, 0.998, 0.998, -0.010, 0.005, 0.008])
SIM_B = np.array([-0.35, 0.25, 0.20])
#: the simulated magnetometer's delay [ms] (a sample at t reads the field at t + δ)
SIM_DELAY_MS = -12.0


def simulated(seed: int, span: float = 90.0) -> dict[str, Any]:
    """A hand-motion trial with known truth, in :func:`load`'s form: the attitude integrated
    exactly from a smooth rate (rest for the first 6 s), the field B_0 + G (p − P_REF) along a
    wandering position, the magnetometer y = (R P)⁻¹ C_BL B + b + white noise 0.7 µT at
    t + δ, 29 % of its samples held (an exact repeat of the one before), the gyro in the body
    frame with a bias and white noise, the optical attitude with 0.5 mrad of white noise. The
    magnetometer model of this script is not used to make it."""
    rng = np.random.default_rng(seed)
    fs = 285.7142857142857
    sub = 8
    n = int(span * fs)
    tf = np.arange(n * sub + 1) / (fs * sub)
    freq = rng.uniform(0.1, 0.8, (3, 4))
    amp = rng.uniform(0.3, 0.8, (3, 4))
    ph = rng.uniform(0, 2 * np.pi, (3, 4))
    ramp = np.clip((tf - 6.0) / 2.0, 0.0, 1.0)
    w = np.stack(
        [(amp[i, :, None] * np.sin(2 * np.pi * freq[i, :, None] * tf + ph[i, :, None])).sum(0) for i in range(3)], 1
    )
    w *= ramp[:, None]
    steps = Rotation.from_rotvec(0.5 * (w[1:] + w[:-1]) / (fs * sub))
    q = np.empty((len(tf), 4))
    cur = Rotation.from_rotvec(rng.normal(0, 1, 3))
    q[0] = cur.as_quat()
    for i, st in enumerate(steps):
        cur = cur * st
        q[i + 1] = cur.as_quat()
    att_f = Slerp(tf, Rotation.from_quat(q))
    t = tf[::sub][:n]
    att = Rotation.from_quat(q[::sub][:n])
    pos = P_REF + 0.1 * np.column_stack([np.sin(2 * np.pi * 0.05 * t + k) for k in range(3)]) * ramp[::sub][:n, None]
    u = np.array([0.3, 0.6, -0.75])
    g_true = grad(np.array([1.0, 2.4, 0.4, -0.8, -0.3]))
    b_lab = F0 * u / np.linalg.norm(u) + (pos - P_REF) @ g_true.T
    td = np.clip(t + SIM_DELAY_MS * 1e-3, 0.0, tf[-1])
    body = att_f(td).inv().apply(b_lab)
    m_inv = np.linalg.inv(Rotation.from_rotvec(SIM_R).as_matrix() @ sym(SIM_P))
    mag = body @ m_inv.T + SIM_B + rng.normal(0, 0.7, (n, 3))
    held = np.r_[False, rng.random(n - 1) < 0.29]
    for j in np.flatnonzero(held):
        mag[j] = mag[j - 1]
    since = np.zeros(n, int)
    count = 0
    for k, h in enumerate(held):
        count = 0 if h else count + 1
        since[k] = count
    gyr = w[::sub][:n] + np.array([3.5e-3, 2.0e-3, -4.0e-3]) + rng.normal(0, 1.7e-3, (n, 3))
    opt = att * Rotation.from_rotvec(rng.normal(0, 5e-4, (n, 3)))
    return {
        "name": f"simulated-{seed}",
        "t": t,
        "gyr": gyr,
        "mag": mag,
        "use": ~held,
        "held_frac": held.mean(),
        "phase": np.clip(since, 1, PHASES) - 1,
        "t_opt": t,
        "opt": opt,
        "slerp": Slerp(t, opt),
        "pos": pos,
    }


def selfcheck(seeds: tuple[int, ...] = (1, 2, 3), span: float = 186.0) -> None:
    """Each estimator on the halves of simulated trials against their truth: the RMS and the
    largest |z| = |estimate − truth|/σ, with the sandwich's σ and with the white-noise σ."""
    names = (
        "ellipsoid (P, b)",
        "optical (P, b, R)",
        "gyro (R, b, P)",
        "optical R only",
        "gyro R only",
        "gyro→optical R",
    )
    zs: dict[str, dict[str, list[float]]] = {n: {"s": [], "w": []} for n in names}
    undetermined = 0
    for seed in seeds:
        d = simulated(seed, span)
        att = gyro_attitude(d)
        for s in ("h1", "h2"):
            seg = segments(d)[s]
            e = ellipsoid(d, seg, True)
            o = optical(d, seg, e, phased=True)
            g = gyro_ref(d, seg, att, float(SIM_P[:3].sum()), phased=True)
            gi = np.r_[0:6, 7:12]
            rows = [
                ("optical (P, b, R)", o, slice(0, 12), np.r_[SIM_P, SIM_B, SIM_R]),
                ("gyro (R, b, P)", g, gi, np.r_[SIM_R, SIM_B, SIM_P[[0, 1, 3, 4, 5]]]),
                ("optical R only", o, slice(9, 12), SIM_R),
                ("gyro R only", g, slice(0, 3), SIM_R),
            ]
            q = gyro_optical(d, seg, att)
            q_s = rot_sigma(q)
            zs["gyro→optical R"]["s"] += list(q["rot"] / q_s)
            if e["ok"]:
                rows.append(("ellipsoid (P, b)", e, slice(0, 9), np.r_[SIM_P, SIM_B]))
            else:
                undetermined += 1
            for name, f, sl, truth in rows:
                zs[name]["s"] += list((f["x"][sl] - truth) / f["ss"][sl])
                zs[name]["w"] += list((f["x"][sl] - truth) / f["sw"][sl])
    print(
        f"simulated {span:g}-s trials (seeds {seeds}), their halves against the truth; the ellipsoid "
        f"undetermined (at a bound) on {undetermined} of {2 * len(seeds)} halves"
    )
    for name, z in zs.items():
        if z["s"]:
            zs_ = np.array(z["s"])
            white = ""
            if z["w"]:
                zw = np.array(z["w"])
                white = f" (white σ {np.sqrt(np.mean(zw**2)):.2f}; largest {np.abs(zw).max():.1f})"
            print(
                f"  {name:<18} n {len(zs_):3d}: RMS z {np.sqrt(np.mean(zs_**2)):.2f}, largest |z| "
                f"{np.abs(zs_).max():.1f}{white}"
            )
