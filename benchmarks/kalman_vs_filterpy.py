"""GCS's Kalman core against ``filterpy.kalman.KalmanFilter`` on one linear problem.

The problem has the shape of the attitude filter (seed Eq 3-3, 3-4, 4-38): n = 15 states,
six dynamic (attitude error δθ rotating with the body, coupled to a random-walk gyro bias)
and nine static (sensor parameters, Φ = I, Q = 0), one three-component measurement per
frame with diagonal R, 20000 frames. Both filters get the same Φ_k, Q_k, H_k, R, z_k.

GCS's core (:mod:`gcs_core.filtr.kalman`) works in block-start coordinates and processes
lifted groups of frames exactly; filterpy runs ``predict(F, Q)`` + ``update(z, R, H)`` per
frame. The script checks that the innovations, the final state and the final covariance
agree, then prints microseconds per frame and the speed ratio (target ≥ 3).

Run: ``python benchmarks/kalman_vs_filterpy.py [--frames N]``.
"""

from __future__ import annotations

import argparse
import sys
import time
from pathlib import Path

import numpy as np

sys.path.insert(0, str(Path(__file__).resolve().parents[1]))

from gcs_core.filtr.kalman import LinearBlock, referred_transitions, solve_block  # noqa: E402
from gcs_core.frames.rotations import rotvec_to_dcm  # noqa: E402

N_DYN, N_STATIC, M_MEAS = 6, 9, 3
BLOCK_FRAMES = 600
TARGET_RATIO = 3.0


def make_problem(n_frames: int, seed: int = 7):
    """Φ_k (structured), Q_k, H_k, R, z_k of an attitude-like linear problem."""
    rng = np.random.default_rng(seed)
    d, s, m = N_DYN, N_STATIC, M_MEAS
    n = d + s
    dt = 1.0
    sigma_v, sigma_u = 1e-4, 1e-6
    rate = rng.normal(size=3) * 1e-3
    R_step = rotvec_to_dcm(np.broadcast_to(rate * dt, (n_frames, 3)))   # Φ_θθ = C_k C_{k−1}ᵀ
    Phi_dd = np.zeros((n_frames, d, d))
    Phi_dd[:, :3, :3] = R_step
    Phi_dd[:, :3, 3:] = -dt * np.eye(3)                                  # ∂ω/∂b Δt
    Phi_dd[:, 3:, 3:] = np.eye(3)
    Phi_ds = np.zeros((n_frames, d, s))
    Phi_ds[:, :3, :3] = 1e-3 * rng.normal(size=(3, 3))                  # scale-factor coupling
    Q = np.zeros((n_frames, d, d))                                       # Farrenkopf
    Q[:, :3, :3] = (sigma_v ** 2 * dt + sigma_u ** 2 * dt ** 3 / 3) * np.eye(3)
    Q[:, :3, 3:] = Q[:, 3:, :3] = -0.5 * sigma_u ** 2 * dt ** 2 * np.eye(3)
    Q[:, 3:, 3:] = sigma_u ** 2 * dt * np.eye(3)
    H = np.zeros((n_frames, m, n))
    H[:, :, :3] = rng.normal(size=(n_frames, m, 3))
    H[:, :, d:] = rng.normal(size=(n_frames, m, s)) * 0.3
    R = np.array([1e-3, 2e-3, 1e-3]) ** 2
    # truth and data
    x = np.concatenate([rng.normal(size=3) * 1e-2, rng.normal(size=3) * 1e-4,
                        rng.normal(size=s) * 1e-2])
    z = np.empty((n_frames, m))
    chol = np.linalg.cholesky(Q[0])
    for k in range(n_frames):
        x[:d] = Phi_dd[k] @ x[:d] + Phi_ds[k] @ x[d:] + chol @ rng.normal(size=d)
        z[k] = H[k] @ x + np.sqrt(R) * rng.normal(size=m)
    P0 = np.diag(np.r_[np.full(3, 1e-2), np.full(3, 1e-4), np.full(s, 1e-2)] ** 2)
    return Phi_dd, Phi_ds, Q, H, R, z, P0


def gcs_pass(Phi_dd, Phi_ds, Q, H, R, z, P0):
    """GCS core over blocks of frames; returns final x, P and per-frame innovations."""
    N, m, n = H.shape
    d = N_DYN
    x, P = np.zeros(n), P0.copy()
    sig = np.sqrt(R)
    nus = np.empty((N, m))
    for k0 in range(0, N, BLOCK_FRAMES):
        k1 = min(k0 + BLOCK_FRAMES, N)
        K = k1 - k0
        Pdd, Pds, Pi = referred_transitions(Phi_dd[k0:k1], Phi_ds[k0:k1], Q[k0:k1])
        Psi_d = np.zeros((K + 1, d, n))
        Psi_d[0, :, :d] = np.eye(d)
        Psi_d[1:, :, :d], Psi_d[1:, :, d:] = Pdd, Pds
        Hk = H[k0:k1]
        A = Hk.copy()
        A[:, :, :d] = Hk[:, :, :d] @ Pdd                # A = H Ψ
        A[:, :, d:] += Hk[:, :, :d] @ Pds
        blk = LinearBlock(t=np.arange(K + 1.0), Pi=np.concatenate([np.zeros((1, d, d)), Pi]),
                          Psi_d=Psi_d, A=(A / sig[None, :, None]).reshape(K * m, n),
                          r=(z[k0:k1] / sig).reshape(-1), sigma=np.tile(sig, K),
                          row_epoch=np.repeat(np.arange(1, K + 1), m),
                          frame_start=np.arange(K) * m, frame_m=np.full(K, m),
                          frame_epoch=np.arange(1, K + 1))
        sol = solve_block(x, P, blk, edit_k=None)
        nus[k0:k1] = sol.nu
        Psi = np.eye(n)
        Psi[:d] = Psi_d[-1]
        x, P = Psi @ sol.y, Psi @ sol.P @ Psi.T          # back to current-time coordinates
    return x, P, nus


def filterpy_pass(Phi_dd, Phi_ds, Q, H, R, z, P0, keep=False):
    from filterpy.kalman import KalmanFilter

    N, m, n = H.shape
    d = N_DYN
    kf = KalmanFilter(dim_x=n, dim_z=m)
    kf.x = np.zeros(n)
    kf.P = P0.copy()
    kf.R = np.diag(R)
    F = np.stack([np.eye(n)] * N)
    F[:, :d, :d], F[:, :d, d:] = Phi_dd, Phi_ds
    Qf = np.zeros((N, n, n))
    Qf[:, :d, :d] = Q
    nus = np.empty((N, m)) if keep else None
    t0 = time.perf_counter()
    for k in range(N):
        kf.predict(F=F[k], Q=Qf[k])
        kf.update(z[k], H=H[k])
        if keep:
            nus[k] = kf.y
    return kf.x, kf.P, nus, time.perf_counter() - t0


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--frames", type=int, default=20000)
    args = ap.parse_args(argv)
    prob = make_problem(args.frames)
    N = args.frames

    t0 = time.perf_counter()
    x_g, P_g, nu_g = gcs_pass(*prob)
    t_gcs = time.perf_counter() - t0
    x_f, P_f, _, t_fp = filterpy_pass(*prob)
    _, _, nu_f, _ = filterpy_pass(*prob, keep=True)

    sig = np.sqrt(np.diag(P_f))
    dx = np.max(np.abs(x_g - x_f) / sig)
    dP = np.max(np.abs(P_g - P_f) / np.outer(sig, sig))
    dnu = np.max(np.abs(nu_g - nu_f)) / np.max(np.abs(nu_f))
    ok = dx < 1e-6 and dP < 1e-6 and dnu < 1e-6
    ratio = t_fp / t_gcs
    print(f"problem: n = {N_DYN + N_STATIC} states ({N_DYN} dynamic), m = {M_MEAS}, {N} frames")
    print(f"same answer: max |Δx|/σ = {dx:.1e}, max |ΔP|/σσ = {dP:.1e}, "
          f"max |Δν|/|ν| = {dnu:.1e} -> {'OK' if ok else 'MISMATCH'}")
    print(f"filterpy KalmanFilter: {t_fp / N * 1e6:7.2f} µs/frame")
    print(f"GCS kalman core:       {t_gcs / N * 1e6:7.2f} µs/frame")
    print(f"speed ratio: {ratio:.1f}x (target ≥ {TARGET_RATIO:.0f}x) -> "
          f"{'met' if ratio >= TARGET_RATIO else 'NOT met'}")
    return 0 if ok else 1


if __name__ == "__main__":
    raise SystemExit(main())
