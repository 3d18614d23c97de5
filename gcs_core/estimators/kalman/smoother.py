"""Backward smoothing of the Kalman filter, and post-fit residuals of the whole span.

The filter's estimate at a frame uses the data up to that frame only; residuals of the
whole span need the attitude given *all* data. The static parameters ``s`` (sensor
calibration, gyro scale factors) end the filter with their final estimate ``s*``; the
dynamic states ``d = (δθ, b)`` are smoothed by Rauch–Tung–Striebel over the epochs,
*conditioned on* ``s = s*``. Conditioning the filter's joint Gaussian at every epoch::

    d_k | s  =  c_k + B_k s,    B_k = P_ds P_ss⁻¹,    P_k|s = P_dd − B_k P_sd

is exactly the filter that would have run with ``s`` known, so the RTS recursion over
``d`` alone (6×6 quantities per epoch) is exact for the linearized problem::

    d_{k+1} = Φ d_k + Φ_s s + u + w,   P⁻ = Φ P Φᵀ + Q,   G = P Φᵀ (P⁻)⁻¹
    d̂_k = d_k|s + G (d̂_{k+1} − d⁻_{k+1}),   P̂_k = P_k|s + G (P̂_{k+1} − P⁻) Gᵀ

The smoothed mean is linear in ``s*`` with sensitivity ``Γ_k`` (same recursion, started
at ``B_N``), so the covariance without conditioning is ``P̂_k + Γ_k P_ss Γ_kᵀ``.

The per-epoch records live in an :class:`EpochStore`: in memory below a size limit, else
in a temporary file written and read through ``numpy.memmap`` a slab at a time (a week
of 1 Hz data is ~1.2 GB of records); the smoother reads them back in chunks, so memory
stays bounded.

References
----------
Rauch, Tung & Striebel, "Maximum likelihood estimates of linear dynamic systems",
AIAA J. 3(8), 1965. Bell, "The iterated Kalman smoother as a Gauss–Newton method",
SIAM J. Optim. 4(3), 1994 (re-linearizing about the smoothed trajectory).
"""

from __future__ import annotations

import logging
import tempfile
from collections.abc import Mapping
from dataclasses import dataclass, replace
from typing import Literal

import numpy as np

from gcs_core.estimators.kalman.mekf import attitude_gyro_noise, gyro_rates, sensor_window, step_quaternions
from gcs_core.estimators.results import SensorResiduals, SmoothedTrajectory
from gcs_core.estimators.whole_span.readout import row_variance
from gcs_core.frames.rotations import dcm_to_rotvec, quat_from_dcm, quat_multiply, quat_normalize

log = logging.getLogger(__name__)


class EpochStore:
    """Per-epoch filter records for the smoother (module docstring).

    Fields (per epoch): ``t``; ``q`` (4) nominal attitude; ``bnom`` (nb) nominal biases;
    ``c`` (d), ``B`` (d, ns), ``Pc`` (d, d) the conditioned posterior; ``Phi`` (d, d),
    ``Phis`` (d, ngs), ``u`` (d), ``Q`` (d, d) the transition *into* the epoch.

    Parameters
    ----------
    n_epochs, d, ns, ngs, nb : sizes.
    limit_bytes : records larger than this go to a temporary memory-mapped file.
    """

    def __init__(self, n_epochs: int, d: int, ns: int, ngs: int, nb: int, *, limit_bytes: float = 256e6):
        shapes = {
            "t": (),
            "q": (4,),
            "bnom": (nb,),
            "c": (d,),
            "B": (d, ns),
            "Pc": (d, d),
            "Phi": (d, d),
            "Phis": (d, ngs),
            "u": (d,),
            "Q": (d, d),
        }
        self.fields, off = {}, 0
        for name, shp in shapes.items():
            size = int(np.prod(shp)) if shp else 1
            self.fields[name] = (off, size, shp)
            off += size
        self.n, self.width = int(n_epochs), off
        self.nbytes = self.n * self.width * 8
        self._file = None
        if self.nbytes > limit_bytes:
            self._file = tempfile.TemporaryFile(prefix="gcs-smoother-")
            self._file.truncate(self.nbytes)
            self.data = None
            log.info("smoother records: %.0f MB in a temporary file", self.nbytes / 1e6)
        else:
            self.data = np.zeros((max(self.n, 1), self.width))

    @property
    def spilled(self) -> bool:
        """True when the records are in a temporary file (mapped a slab at a time)."""
        return self._file is not None

    def _slab(self, k0: int, k1: int, mode: Literal["r", "r+"]) -> np.ndarray:
        if self._file is None:
            assert self.data is not None  # in memory when not spilled
            return self.data[k0:k1]
        # map only the rows in use: the process keeps no pages of the file once unmapped
        return np.memmap(
            self._file, dtype=np.float64, mode=mode, offset=k0 * self.width * 8, shape=(k1 - k0, self.width)
        )

    def write(self, k0: int, **arrays) -> None:
        """Write records of epochs ``k0..k0+G−1``; each array has leading dimension G."""
        G = next(iter(arrays.values())).shape[0]
        slab = self._slab(k0, k0 + G, "r+")
        for name, a in arrays.items():
            off, size, _ = self.fields[name]
            slab[:, off : off + size] = np.asarray(a, float).reshape(G, size)
        del slab  # unmapped: the pages stay in the OS cache, not in our RSS

    def read(self, k0: int, k1: int) -> dict[str, np.ndarray]:
        """Records of epochs ``k0..k1−1`` as arrays ``(k1−k0, *shape)`` (copies)."""
        slab = np.array(self._slab(k0, k1, "r"))
        return {
            name: slab[:, off : off + size].reshape((k1 - k0,) + shp) for name, (off, size, shp) in self.fields.items()
        }

    def close(self) -> None:
        if self._file is not None:
            self._file.close()
            self._file = None


@dataclass(frozen=True)
class SmoothedStates:
    """Raw output of :func:`rts_smooth`.

    Attributes
    ----------
    x : (N, d) smoothed dynamic error states (each epoch's own nominal).
    sigma : (N, d) their 1-sigma (static uncertainty included).
    P0 : (d, d) full covariance at epoch 0; Gamma0 : (d, ns) sensitivity to s at epoch 0.
    """

    x: np.ndarray
    sigma: np.ndarray
    P0: np.ndarray
    Gamma0: np.ndarray


def rts_smooth(
    store: EpochStore,
    s_star: np.ndarray,
    P_ss: np.ndarray,
    gs_pos: np.ndarray,
    *,
    n: int | None = None,
    chunk: int = 8192,
) -> SmoothedStates:
    """RTS over the dynamic states conditioned on ``s = s*`` (module docstring); the first
    ``n`` epochs of the store (all by default)."""
    N = store.n if n is None else int(n)
    d = store.fields["c"][2][0]
    ns = s_star.size
    s_gs = s_star[gs_pos]
    x_out, sd_out = np.empty((N, d)), np.empty((N, d))
    last = store.read(N - 1, N)
    xs = last["c"][0] + last["B"][0] @ s_star
    Ps, Gs = last["Pc"][0], last["B"][0]
    _total(x_out, sd_out, N - 1, xs[None], Ps[None], Gs[None], P_ss)
    P0, G0 = Ps + Gs @ P_ss @ Gs.T, Gs
    k1 = N - 1
    while k1 > 0:
        k0 = max(0, k1 - chunk)
        rec = store.read(k0, k1 + 1)
        B, Pf = rec["B"][:-1], rec["Pc"][:-1]
        xf = rec["c"][:-1] + B @ s_star  # d_k | s*
        Phi, Q = rec["Phi"][1:], rec["Q"][1:]
        # d⁻_{k+1} = Φ d_k + Φ_s s + u,   P⁻ = Φ P Φᵀ + Q
        xp = (Phi @ xf[:, :, None])[:, :, 0] + rec["Phis"][1:] @ s_gs + rec["u"][1:]
        Pp = Phi @ Pf @ np.swapaxes(Phi, 1, 2) + Q
        Pp = 0.5 * (Pp + np.swapaxes(Pp, 1, 2))
        # G = P Φᵀ (P⁻)⁻¹ = ((P⁻)⁻¹ Φ P)ᵀ   (solve, not invert)
        G = np.swapaxes(_solve(Pp, Phi @ Pf), 1, 2)
        Gp = Phi @ B  # Γ⁻_{k+1} = Φ B_k + Φ_s
        Gp[:, :, gs_pos] += rec["Phis"][1:]
        n_c = k1 - k0
        X, PS, GS = np.empty((n_c, d)), np.empty((n_c, d, d)), np.empty((n_c, d, ns))
        for j in range(n_c - 1, -1, -1):
            Gj = G[j]
            xs = xf[j] + Gj @ (xs - xp[j])
            Ps = Pf[j] + Gj @ (Ps - Pp[j]) @ Gj.T
            Gs = B[j] + Gj @ (Gs - Gp[j])
            X[j], PS[j], GS[j] = xs, Ps, Gs
        _total(x_out, sd_out, k0, X, PS, GS, P_ss)
        if k0 == 0:
            P0 = PS[0] + GS[0] @ P_ss @ GS[0].T
            G0 = GS[0]
        k1 = k0
    return SmoothedStates(x_out, sd_out, 0.5 * (P0 + P0.T), G0)


def _total(x_out, sd_out, k0, X, PS, GS, P_ss):
    """Store means and 1-sigma including the static uncertainty ``Γ P_ss Γᵀ``."""
    x_out[k0 : k0 + X.shape[0]] = X
    var = np.einsum("kii->ki", PS) + np.einsum("kij,jl,kil->ki", GS, P_ss, GS)
    sd_out[k0 : k0 + X.shape[0]] = np.sqrt(np.maximum(var, 0.0))


def _solve(A: np.ndarray, B: np.ndarray) -> np.ndarray:
    try:
        return np.linalg.solve(A, B)
    except np.linalg.LinAlgError:  # a singular prediction: least squares
        return np.linalg.pinv(A) @ B


def trajectory(store: EpochStore, sm: SmoothedStates, nb: int, bias_names: tuple[str, ...] = ()) -> SmoothedTrajectory:
    """Smoothed quaternions ``q = q(δθ) ⊗ q_nominal`` (``C = exp(−[δθ×]) C_nom``) and biases."""
    N = sm.x.shape[0]
    t, q = np.empty(N), np.empty((N, 4))
    bias = np.empty((N, nb)) if nb else None
    for k0 in range(0, N, 8192):
        k1 = min(N, k0 + 8192)
        rec = store.read(k0, k1)
        t[k0:k1] = rec["t"]
        dq = step_quaternions(sm.x[k0:k1, :3], np.ones(k1 - k0))
        q[k0:k1] = quat_normalize(quat_multiply(dq, rec["q"]))
        if bias is not None:
            bias[k0:k1] = rec["bnom"] + sm.x[k0:k1, 3 : 3 + nb]
    return SmoothedTrajectory(t, q, sm.sigma[:, :3], bias, sm.sigma[:, 3 : 3 + nb] if nb else None, tuple(bias_names))


def smoothed_residuals(
    problem,
    traj: SmoothedTrajectory,
    frame_epoch: Mapping[str, np.ndarray],
    values: Mapping[str, float],
    omega_at,
    edited: Mapping[str, np.ndarray],
    *,
    chunk: int = 65536,
) -> dict[str, SensorResiduals]:
    """Post-fit residuals of every sensor at the smoothed attitude and final parameters.

    Parameters
    ----------
    problem : the calibration problem.
    traj : smoothed trajectory; frame_epoch : sensor -> (N,) epoch of each frame.
    values : final element values; omega_at : ``t -> (N, 3)`` body rate at final gyro values.
    edited : sensor -> (N,) frames refused by the filter's gate (or edited beforehand).

    With a gyro read-out noise σ_e the rows are normalized by their marginal σ,
    ``sqrt(σ² + σ_e² |D|²)`` (D the row's attitude partials), as the whole-span fit's are
    (:mod:`gcs_core.estimators.whole_span.readout`): the read-out error is white per epoch, so the smoothed
    attitude cannot follow it and the residual carries it.
    """
    out = {}
    earth = getattr(problem.attitude, "earth_rate", None)  # a ground mission's (problem/earth_rate.py)
    sig_e2 = attitude_gyro_noise(problem).sigma_e ** 2 if problem.gyro_name is not None else 0.0
    for sd in problem.sensors:
        ep = frame_epoch[sd.name]
        reached = (ep >= 0) & (ep < traj.t.size)  # frames the filter processed
        y_pred = np.full(sd.y.shape, np.nan)
        readout = np.zeros(sd.y.shape) if sig_e2 > 0 and sd.model.attitude_kind == "three_axis" else None
        valid = np.zeros(sd.n, bool)
        for lo in range(0, sd.n, chunk):  # bounded memory on long spans
            hi = min(sd.n, lo + chunk)
            part = sensor_window(sd, lo, hi)
            k = np.where(reached[lo:hi], ep[lo:hi], 0)
            C, w = traj.C_BI(k), omega_at(part.t)
            if earth is not None and w is not None:
                w = w - C @ earth  # ω_B/lab = ω − C ω_E
            geom = replace(part.geom, C_BI=C, omega_B=w)
            pred = sd.model.predict(geom, problem.params_of(sd.name, values))
            y_pred[lo:hi] = pred.y
            valid[lo:hi] = np.asarray(pred.valid, bool)
            if readout is not None:
                readout[lo:hi] = row_variance(pred.d_att, sig_e2)
        r = sd.model.residual(sd.y, y_pred)
        valid &= np.all(np.isfinite(r), axis=1) & reached
        r = np.where(valid[:, None], r, np.nan)
        res = SensorResiduals.of(sd, y_pred, r, valid, edited.get(sd.name))
        if readout is not None:
            res = replace(res, normalized_=r / np.sqrt(np.asarray(sd.sigma) ** 2 + readout))
        out[sd.name] = res
    return out


def block_records(lay, blk, sol, seg, nom: Mapping[str, float], C_a: np.ndarray, prev_nom):
    """Records of one MEKF block for the :class:`EpochStore` (module docstring).

    Posterior at every epoch in current-time coordinates ``x_d = Ψ_d y``, conditioned on
    the static part (``B = P_ds P_ss⁻¹``, ``P_c = P_dd − B P_sd``, ``c = x̂_d − B ŝ``), and
    the transition into each epoch: ``Φ = Ψ_dd,k Ψ_dd,k−1⁻¹``, ``Φ_s = Ψ_ds,k − Φ Ψ_ds,k−1``,
    ``Q = Ψ_dd ΔΠ Ψ_ddᵀ``; into the block's first epoch, the reset ``u`` (old nominal
    relative to the new one, ``C_old = exp(−[u×]) C_a``; reset Jacobian taken as I).
    Returns the records (dict of (G, ...) arrays) and the block's end nominal.
    """
    d = lay.d
    G = blk.t.size
    Psi_d, ye, Pe = blk.Psi_d, sol.y_epoch, sol.P_epoch
    s_nom = np.array([nom[e] for e in lay.elements[d:]])
    xd = (Psi_d @ ye[:, :, None])[:, :, 0]
    Pxd = Psi_d @ Pe  # Ψ_d P
    Pdd, Pds, Pss = Pxd @ np.swapaxes(Psi_d, 1, 2), Pxd[:, :, d:], Pe[:, d:, d:]
    B = np.swapaxes(np.linalg.solve(Pss, np.swapaxes(Pds, 1, 2)), 1, 2)  # P_ds P_ss⁻¹
    Pc = Pdd - B @ np.swapaxes(Pds, 1, 2)  # P_dd − B P_sd
    c = xd - (B @ (s_nom + ye[:, d:])[:, :, None])[:, :, 0]
    Psi_dd, Psi_gs = Psi_d[:, :, :d], Psi_d[:, :, d + lay.gs_pos]
    Phi = np.broadcast_to(np.eye(d), (G, d, d)).copy()
    Phis = np.zeros((G, d, lay.gs_pos.size))
    u, Q = np.zeros((G, d)), np.zeros((G, d, d))
    if G > 1:
        Phi[1:] = Psi_dd[1:] @ np.linalg.inv(Psi_dd[:-1])  # Ψ_k Ψ_{k−1}⁻¹
        Phis[1:] = Psi_gs[1:] - Phi[1:] @ Psi_gs[:-1]
        u[1:] = -Phis[1:] @ s_nom[lay.gs_pos]  # static terms in absolute values
        Q[1:] = Psi_dd[1:] @ np.diff(blk.Pi, axis=0) @ np.swapaxes(Psi_dd[1:], 1, 2)
    bnom = np.array([nom[e] for e in lay.elements[3:d]])
    if prev_nom is not None:  # the reset at the boundary
        C_old, b_old = prev_nom
        u[0, :3] = dcm_to_rotvec(C_old @ C_a.T)
        u[0, 3:] = b_old - bnom
    recs = dict(
        t=blk.t,
        q=quat_from_dcm(seg.at(blk.t)[0]),
        bnom=np.broadcast_to(bnom, (G, lay.nb)),
        c=c,
        B=B,
        Pc=0.5 * (Pc + np.swapaxes(Pc, 1, 2)),
        Phi=Phi,
        Phis=Phis,
        u=u,
        Q=Q,
    )
    return recs, (seg.C[-1], bnom)


def gyro_residuals(problem, traj: SmoothedTrajectory, frame_epoch, values, edited):
    """:func:`smoothed_residuals` with body rates from the final gyro values (Eq 4-32)."""
    att = problem.attitude
    omega, *_ = gyro_rates(att, values, 0, att.y.shape[0])
    K = omega.shape[0]

    def omega_at(t):
        return omega[np.clip(np.searchsorted(att.knots, t, side="left"), 1, K) - 1]

    return smoothed_residuals(problem, traj, frame_epoch, values, omega_at, edited)
