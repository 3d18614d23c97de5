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
(numpy/scipy on the HDF5, run under ``nice``).
"""

from __future__ import annotations

import sys
import time
from pathlib import Path
from typing import Any

import h5py
import numpy as np
from scipy.optimize import least_squares, minimize_scalar
from scipy.signal import lfilter
from scipy.spatial.transform import Rotation, Slerp

TRIALS = ("02_undisturbed_slow_rotation_B", "09_undisturbed_fast_rotation_with_breaks_B")
#: sandwich window [s]
BLOCK_S = 4.0
#: the gyro's and the optical reference's windows [s]
WINDOW_S = 0.15
#: the field's magnitude at P_REF that fixes P's common scale [µT]
F0 = 44.3
#: the lab point the field and its gradient refer to [m] (near both trials' mean position)
P_REF = np.array([0.056, -0.46, 1.45])
#: classes of a magnetometer sample's place after the last held sample (each its own time offset)
PHASES = 7
#: the interleaved split (a check of the σ themselves): alternate blocks of this length [s]
INTERLEAVE_S = 8.0
#: the knot spacing of the bias's wander [s]
WANDER_S = 20.0
#: the trace that fixes the gyro-referenced P's common scale
TRACE = 3.0
#: a rest: the optical rate below this [rad/s] for at least REST_MIN_S
REST_RATE = 0.05
REST_MIN_S = 3.0


def load(path: Path, keep_held: bool) -> dict[str, Any]:
    """One trial: times [s], gyro [rad/s], magnetometer [µT], optical body→ENU rotation, position [m]."""
    with h5py.File(path, "r") as f:
        fs = float(f.attrs["sampling_rate"])
        gyr = f["imu_gyr"][:]
        mag = f["imu_mag"][:]
        q = f["opt_quat"][:]
        pos = f["opt_pos"][:]
    t = np.arange(len(gyr)) / fs
    held = np.r_[False, np.all(mag[1:] == mag[:-1], axis=1)]
    # a sample's place after the last held one (1, 2, ...; PHASES and later share a class)
    since = np.zeros(len(held), int)
    count = 0
    for k, h in enumerate(held):
        count = 0 if h else count + 1
        since[k] = count
    tracked = np.isfinite(q).all(axis=1) & np.isfinite(pos).all(axis=1)
    opt = Rotation.from_quat(q[tracked][:, [1, 2, 3, 0]])
    return {
        "name": path.stem,
        "t": t,
        "gyr": gyr,
        "mag": mag,
        "use": ~held if not keep_held else np.ones(len(t), bool),
        "held_frac": held.mean(),
        "phase": np.clip(since, 1, PHASES) - 1,
        "t_opt": t[tracked],
        "opt": opt,
        "slerp": Slerp(t[tracked], opt),
        "pos": pos[tracked],
    }


def pos_at(d: dict[str, Any], t: np.ndarray) -> np.ndarray:
    return np.column_stack([np.interp(t, d["t_opt"], d["pos"][:, i]) for i in range(3)])


def rests(d: dict[str, Any]) -> list[tuple[float, float]]:
    """Rests from the optical attitude: its rate below REST_RATE for at least REST_MIN_S."""
    t = d["t_opt"]
    rv = (d["opt"][:-1].inv() * d["opt"][1:]).as_rotvec()
    rate = np.linalg.norm(rv, axis=1) / np.diff(t)
    # smooth over 0.2 s
    n = 57
    rate = np.convolve(rate, np.ones(n) / n, mode="same")
    still = np.r_[rate < REST_RATE, False]
    out, start = [], None
    for k, s in enumerate(still):
        if s and start is None:
            start = k
        if not s and start is not None:
            if t[k - 1] - t[start] >= REST_MIN_S:
                out.append((t[start] + 0.5, t[k - 1] - 0.5))
            start = None
    return out


def sym(v: np.ndarray) -> np.ndarray:
    return np.array([[v[0], v[3], v[4]], [v[3], v[1], v[5]], [v[4], v[5], v[2]]])


def grad(v: np.ndarray) -> np.ndarray:
    """Symmetric trace-free gradient from five elements (∂Bx/∂x, ∂By/∂y, ∂Bx/∂y, ∂Bx/∂z, ∂By/∂z)."""
    return np.array([[v[0], v[2], v[3]], [v[2], v[1], v[4]], [v[3], v[4], -v[0] - v[1]]])


def second_degree(v: np.ndarray) -> np.ndarray:
    """(N, 5) monomials of second degree of the direction of v: n_x², n_y², n_x n_y, n_x n_z, n_y n_z."""
    n = v / np.linalg.norm(v, axis=1)[:, None]
    return np.column_stack([n[:, 0] ** 2, n[:, 1] ** 2, n[:, 0] * n[:, 1], n[:, 0] * n[:, 2], n[:, 1] * n[:, 2]])


def sandwich(jac: np.ndarray, r: np.ndarray, t: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """(white-noise covariance, batch-means sandwich covariance); rows of jac/r at times t."""
    h_inv = np.linalg.pinv(jac.T @ jac)
    dof = max(len(r) - jac.shape[1], 1)
    cov_w = h_inv * (r @ r) / dof
    block = np.floor((t - t.min()) / BLOCK_S).astype(int)
    score = jac * r[:, None]
    g = np.zeros((block.max() + 1, jac.shape[1]))
    np.add.at(g, block, score)
    cov_s = h_inv @ (g.T @ g) @ h_inv
    return cov_w, cov_s


def fit(fun, x0, t_rows, bounds=None, free=None) -> dict[str, Any]:
    """Least squares with the batch-means sandwich σ; ``free``: fit only these indices of x0."""
    if free is not None:
        full = np.asarray(x0, float).copy()

        def sub(xf):
            xx = full.copy()
            xx[free] = xf
            return fun(xx)

        out = fit(sub, full[free], t_rows)
        x, ss, sw = full.copy(), np.zeros(len(full)), np.zeros(len(full))
        x[free], ss[free], sw[free] = out["x"], out["ss"], out["sw"]
        return {**out, "x": x, "ss": ss, "sw": sw}
    if bounds is None:
        res = least_squares(fun, x0, method="lm", x_scale="jac")
        at_bound = False
    else:
        res = least_squares(fun, x0, method="trf", x_scale="jac", bounds=bounds)
        at_bound = bool(np.any(np.isclose(res.x, bounds[0]) | np.isclose(res.x, bounds[1])))
    cov_w, cov_s = sandwich(res.jac, res.fun, t_rows)
    return {
        "x": res.x,
        "sw": np.sqrt(np.diag(cov_w)),
        "ss": np.sqrt(np.diag(cov_s)),
        "rms": float(np.sqrt(np.mean(res.fun**2))),
        "ok": res.status > 0 and not at_bound,
    }


def segments(d: dict[str, Any]) -> dict[str, np.ndarray]:
    t = d["t"]
    half = t[-1] / 2
    alt = np.floor(t / INTERLEAVE_S).astype(int) % 2 == 0
    return {"whole": np.ones(len(t), bool), "h1": t < half, "h2": t >= half, "A": alt, "B": ~alt}


# -- 1. attitude-independent ------------------------------------------------------------------


def ellipsoid(d: dict[str, Any], seg: np.ndarray, gradient: bool, drift: bool = False) -> dict[str, Any]:
    """|P (y − b(t))| = F0 + g·(p − P_REF): x = (P 6, b 3[, g 3][, ḃ 3])."""
    k = seg & d["use"]
    t = d["t"][k]
    y = d["mag"][k]
    p = pos_at(d, t) - P_REF
    tm = 0.5 * (t[0] + t[-1])

    def fun(x):
        b = x[6:9]
        i = 9
        mag = F0 * np.ones(len(t))
        if gradient:
            mag = mag + p @ x[i : i + 3]
            i += 3
        if drift:
            b = b + np.outer(t - tm, x[i : i + 3])
        return np.linalg.norm((y - b) @ sym(x[:6]), axis=1) - mag

    x0 = np.r_[1.0, 1.0, 1.0, 0, 0, 0, np.median(y, axis=0) * 0]
    x0[6:9] = 0.5 * (y.max(axis=0) + y.min(axis=0))
    x0 = np.r_[x0, np.zeros(3 * (gradient + drift))]
    # |P (y − b)| = F0 has its infimum 0 at P → 0, |b| → ∞ for any data (|ε y − F0 u| ≈ F0 −
    # ε u·y): the calibration is the local minimum near P = I, bounded away from that limit
    lo = np.r_[[0.5] * 3, [-0.3] * 3, [-20.0] * 3, [-20.0] * 3 * gradient, [-1.0] * 3 * drift]
    hi = -lo + np.r_[[2.0] * 3, np.zeros(len(lo) - 3)]
    out = fit(fun, np.clip(x0, lo + 1e-6, hi - 1e-6), t, (lo, hi))
    out["path_dB"] = float(np.ptp(p @ out["x"][9:12])) if gradient else 0.0
    return out


# -- 2. against the optical attitude ----------------------------------------------------------


def optical(
    d: dict[str, Any],
    seg: np.ndarray,
    e0: dict[str, Any],
    per_axis: bool = False,
    lowpass: bool = False,
    rotation_of: np.ndarray | None = None,
    phased: bool = False,
    quadratic: bool = False,
    wander_s: float | None = None,
) -> dict[str, Any]:
    """y = (R P)⁻¹ C_BL(t + δ)(B_0 + G (p − P_REF)) + b, residuals in the magnetometer's frame
    [µT]: x = (P 6, b 3, φ 3, u 2, G 5, δ [ms]).

    ``per_axis``: each magnetometer axis k at its own time, y_k = [(R P)⁻¹ C_BL(t + δ_k) B]_k + b_k:
    x = (P 6, b 3, φ 3, u 2, G 5, δ_x, δ_y, δ_z). ``lowpass``: the magnetometer reads the field
    through a first-order low-pass of time constant τ [ms] (appended to x) after the delay δ,
    τ dy/dt = y_in − y, run over every sample of the trial's 286-Hz grid. ``rotation_of``: a
    whole-trial x, of which only the rotation φ is refitted on this segment. ``phased``: each
    class of a sample's place after the last held sample (:data:`PHASES`) its own δ:
    x = (P 6, b 3, φ 3, u 2, G 5, δ_1 … δ_PHASES). ``quadratic``: a response of second degree in
    the field's direction in the magnetometer's frame, y += Q q(n), n = (R P)⁻¹ C_BL B / |B|,
    q = (n_x², n_y², n_x n_y, n_x n_z, n_y n_z) (n_z² is 1 − n_x² − n_y²), Q (3×5) [µT] appended to x.
    ``wander_s`` (with ``phased``): the bias wanders, b(t) = b + w(t), w linear between knots every
    ``wander_s`` seconds, w = 0 at the first; the knots' w (3 each) [µT] appended to x.
    """
    tg = d["t"][(d["t"] > d["t_opt"][0] + 0.05) & (d["t"] < d["t_opt"][-1] - 0.05)]
    grid = np.isin(d["t"], tg)
    pick = (seg & d["use"])[grid]
    t = tg[pick]
    y = d["mag"][grid][pick]
    cls = d["phase"][grid][pick]
    p = pos_at(d, tg if lowpass else t) - P_REF
    tt = tg if lowpass else t
    dt = float(np.median(np.diff(tg)))
    # the first guess: the ellipsoid's P and b where it determined them, else P = I, b = 0
    start = e0["x"][:9] if e0["ok"] else np.r_[1.0, 1.0, 1.0, np.zeros(6)]
    # B_0's direction: the first guess from the calibrated field in ENU
    v0 = d["slerp"](t).apply((y - start[6:9]) @ sym(start[:6])).mean(axis=0)
    u0 = v0 / np.linalg.norm(v0)
    e1 = np.cross(u0, [0, 0, 1.0])
    e1 /= np.linalg.norm(e1)
    e2 = np.cross(u0, e1)

    # the bias's wander: hat functions of knots every wander_s seconds
    n_knots = 1
    hat = np.zeros((len(t), 1))
    if wander_s is not None and len(t):
        knots = np.arange(t[0], t[-1] + wander_s, wander_s)
        n_knots = len(knots)
        hat = np.column_stack([np.interp(t, knots, np.eye(n_knots)[k]) for k in range(n_knots)])

    cache: dict[float, Rotation] = {}

    def opt_at(delta: float) -> Rotation:
        if delta not in cache:
            if len(cache) > PHASES + 2:
                cache.clear()
            cache[delta] = d["slerp"](tt + delta * 1e-3)
        return cache[delta]

    def fun(x):
        u = u0 + x[12] * e1 + x[13] * e2
        b_lab = F0 * u / np.linalg.norm(u) + p @ grad(x[14:19])
        m_inv = np.linalg.inv(Rotation.from_rotvec(x[9:12]).as_matrix() @ sym(x[:6]))
        if phased:
            pred = np.empty((len(t), 3))
            for c in range(PHASES):
                sel = cls == c
                pred[sel] = opt_at(x[19 + c])[sel].inv().apply(b_lab[sel]) @ m_inv.T
            if quadratic:
                pred = pred + second_degree(pred) @ x[19 + PHASES : 34 + PHASES].reshape(3, 5).T
            if wander_s is not None:
                pred = pred + hat @ np.r_[np.zeros(3), x[len(x) - 3 * (n_knots - 1) :]].reshape(n_knots, 3)
            return (y - x[6:9] - pred).ravel()
        delays = x[19:22] if per_axis else [x[19]] * 3
        pred = np.column_stack([opt_at(delays[k]).inv().apply(b_lab) @ m_inv[k] for k in range(3)])
        if lowpass:
            a = np.exp(-dt / max(x[-1] * 1e-3, 1e-6))
            pred = lfilter([1 - a], [1, -a], pred, axis=0, zi=a * pred[:1])[0][pick]
        return (y - x[6:9] - pred).ravel()

    x0 = np.r_[start, np.zeros(10), [-14.5] * (PHASES if phased else 3 if per_axis else 1), [5.0] * lowpass]
    if quadratic:
        if not phased:
            raise ValueError("quadratic needs phased")
        x0 = np.r_[x0, np.zeros(15)]
    if wander_s is not None:
        if not phased:
            raise ValueError("wander_s needs phased")
        x0 = np.r_[x0, np.zeros(3 * (n_knots - 1))]
    if lowpass:
        x0[19 : 19 + (3 if per_axis else 1)] = -9.5
    if rotation_of is not None:
        u = u0 + rotation_of[12] * e1 + rotation_of[13] * e2  # keep the whole trial's B_0
        x0 = rotation_of.copy()
        x0[12:14] = 0.0
        u0 = u / np.linalg.norm(u)
        e1 = np.cross(u0, [0, 0, 1.0])
        e1 /= np.linalg.norm(e1)
        e2 = np.cross(u0, e1)
        out = fit(fun, x0, np.repeat(t, 3), free=np.arange(9, 12))
        out["t"] = t
        return out
    out = fit(fun, x0, np.repeat(t, 3))
    out["t"] = t
    out["res"] = fun(out["x"]).reshape(-1, 3)
    # the prediction's rate of change [µT/ms]: d(pred)/dδ = −d(res)/dδ
    xp, xm = out["x"].copy(), out["x"].copy()
    xp[19] += 0.5
    xm[19] -= 0.5
    out["dpred"] = (fun(xm) - fun(xp)).reshape(-1, 3)
    return out


# -- 3. against the gyro ----------------------------------------------------------------------


def gyro_attitude(d: dict[str, Any], smat: np.ndarray | None = None) -> Slerp:
    """The gyro-carried body→lab rotation (bias: the mean rate over t = 1–6 s, at rest), as a
    Slerp; ``smat`` a symmetric matrix applied to the rate (the gyro's scale and non-orthogonality)."""
    t, w = d["t"], d["gyr"]
    at = (t > 1.0) & (t < 6.0)  # every trial starts at rest
    wb = w - w[at].mean(axis=0)
    if smat is not None:
        wb = wb @ smat.T
    dt = np.diff(t)
    steps = Rotation.from_rotvec(0.5 * (wb[1:] + wb[:-1]) * dt[:, None])
    q = np.empty((len(t), 4))
    cur = Rotation.identity()
    q[0] = cur.as_quat()
    for i, s in enumerate(steps):
        cur = cur * s
        q[i + 1] = cur.as_quat()
    return Slerp(t, Rotation.from_quat(q))


def pairs(d: dict[str, Any], seg: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Indices (i, j) of magnetometer samples WINDOW_S apart (the first used sample after)."""
    idx = np.flatnonzero(seg & d["use"])
    t = d["t"][idx]
    j = np.searchsorted(t, t + WINDOW_S)
    ok = j < len(idx)
    i, j = idx[ok], idx[j[ok]]
    keep = (d["t"][i] > 0.1) & (d["t"][j] < d["t"][-1] - 0.1) & (d["t"][j] - d["t"][i] < WINDOW_S + 0.02)
    return i[keep], j[keep]


def gyro_ref(
    d: dict[str, Any],
    seg: np.ndarray,
    att: Slerp,
    trace: float,
    rotation_of: np.ndarray | None = None,
    phased: bool = False,
    quadratic: bool = False,
) -> dict[str, Any]:
    """R P (y_j − b) = A(t_j+δ)ᵀ A(t_i+δ) R P (y_i − b): x = (φ 3, b 3, δ [ms], P 5).

    The equation is homogeneous in P: its common scale is fixed by its trace (``trace``, the
    same in every fit), its other five elements are fitted (P_zz = trace − P_xx − P_yy).
    ``phased``: each class of a sample's place after the last held one its own δ, appended to x.
    ``quadratic`` (with ``phased``): the response of second degree of :func:`optical`, removed from
    each sample before calibrating, y − b − Q q(n), n the direction of y − b; Q appended to x.
    """
    i, j = pairs(d, seg)
    ti, tj = d["t"][i], d["t"][j]
    yi, yj = d["mag"][i], d["mag"][j]
    ci, cj = d["phase"][i], d["phase"][j]
    cache: dict[float, Rotation] = {}

    def phi(delta: float) -> Rotation:
        if delta not in cache:
            cache.clear()
            cache[delta] = att(tj + delta * 1e-3).inv() * att(ti + delta * 1e-3)
        return cache[delta]

    def phi_phased(x) -> Rotation:
        dl = x[12 : 12 + PHASES] * 1e-3
        return att(tj + dl[cj]).inv() * att(ti + dl[ci])

    def lin(y, x):
        v = y - x[3:6]
        if quadratic:
            v = v - second_degree(v) @ x[12 + PHASES : 27 + PHASES].reshape(3, 5).T
        return v

    def fun(x):
        P = sym(np.r_[x[7], x[8], trace - x[7] - x[8], x[9:12]])
        r = Rotation.from_rotvec(x[:3])
        mi = r.apply(lin(yi, x) @ P)
        mj = r.apply(lin(yj, x) @ P)
        rot = phi_phased(x) if phased else phi(x[6])
        return (mj - rot.apply(mi)).ravel()

    x0 = np.r_[np.zeros(3), 0.5 * (yi.max(axis=0) + yi.min(axis=0)), -12.0, trace / 3, trace / 3, 0, 0, 0]
    if phased:
        x0 = np.r_[x0, [-11.0] * PHASES, np.zeros(15 * quadratic)]
        x0[6] = 0.0  # unused
    if rotation_of is not None:
        return fit(fun, rotation_of, np.repeat(ti, 3), free=np.arange(3))
    free = np.r_[0:6, 7 : len(x0)] if phased else None
    out = fit(fun, x0, np.repeat(ti, 3), free=free)
    out["pairs"] = len(i)
    return out


def gyro_optical(d: dict[str, Any], seg: np.ndarray, att: Slerp) -> dict[str, Any]:
    """θ_opt = K θ_gyro over the windows, K by linear least squares at the best optical δ."""
    i, j = pairs(d, seg)
    ti, tj = d["t"][i], d["t"][j]
    ok = (ti > d["t_opt"][0] + 0.05) & (tj < d["t_opt"][-1] - 0.05)
    ti, tj = ti[ok], tj[ok]
    th_g = (att(ti).inv() * att(tj)).as_rotvec()

    def solve(delta):
        o = d["slerp"]
        th_o = (o(ti + delta * 1e-3).inv() * o(tj + delta * 1e-3)).as_rotvec()
        k, *_ = np.linalg.lstsq(th_g, th_o, rcond=None)
        r = th_o - th_g @ k
        return k.T, r

    best = minimize_scalar(lambda dl: float(np.sum(solve(dl)[1] ** 2)), bounds=(-20, 20), method="bounded")
    k, r = solve(best.x)
    # K's covariance: the rows of K are three regressions on the same θ_gyro
    jac = np.kron(np.eye(3), th_g)  # x = K.ravel() (row-major), rows per component
    res = r.T.ravel()
    cov_w, cov_s = sandwich(jac, res, np.tile(ti, 3))
    u, s, vt = np.linalg.svd(k)
    rot = u @ vt
    return {
        "K": k,
        "rot": Rotation.from_matrix(rot).as_rotvec(),
        "cov_s": cov_s,
        "ss": np.sqrt(np.diag(cov_s)),
        "sw": np.sqrt(np.diag(cov_w)),
        "delta_ms": best.x,
        "rms": float(np.sqrt(np.mean(r**2))),
    }


def rot_sigma(g: dict[str, Any], n: int = 200, seed: int = 1) -> np.ndarray:
    """σ of K's rotation vector by drawing K from its sandwich covariance (seeded)."""
    rng = np.random.default_rng(seed)
    draws = rng.multivariate_normal(g["K"].ravel(), g["cov_s"], size=n)
    rv = []
    for kk in draws:
        u, _, vt = np.linalg.svd(kk.reshape(3, 3))
        rv.append(Rotation.from_matrix(u @ vt).as_rotvec())
    return np.std(rv, axis=0)


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


# -- a check against truth -------------------------------------------------------------------

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
    names = ("ellipsoid (P, b)", "optical (P, b, R)", "gyro (R, b, P)", "optical R only", "gyro R only")
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
            zs_, zw = np.array(z["s"]), np.array(z["w"])
            print(
                f"  {name:<18} n {len(zs_):3d}: RMS z {np.sqrt(np.mean(zs_**2)):.2f} (white σ "
                f"{np.sqrt(np.mean(zw**2)):.2f}), largest |z| {np.abs(zs_).max():.1f} (white σ {np.abs(zw).max():.1f})"
            )


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
