"""The estimators of ``broad_magnetometer_sources.py``: the BROAD magnetometer against its
field's magnitude, the optical attitude and the gyro, each a least-squares fit with the
batch-means sandwich σ over contiguous :data:`BLOCK_S` windows (that script's docstring has the
model and the equations)."""

from __future__ import annotations

from pathlib import Path
from typing import Any

import h5py
import numpy as np
from scipy.optimize import least_squares, minimize_scalar
from scipy.signal import lfilter
from scipy.spatial.transform import Rotation, Slerp

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
