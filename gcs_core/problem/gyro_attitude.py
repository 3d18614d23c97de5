"""The gyro-carried three-axis attitude and its partials (seed §4.2.7, Eq 4-32, 4-33, 4-38).

:class:`GyroAttitude` propagates the roll/pitch/yaw at ``t_ref`` with the gyro rates,
block by block with a carry, and forms the partials of the body attitude error with
respect to the attitude, the gyro's ``G`` (Eq 4-37), bias and bias rate as cumulative
sums; the derivation is in the docstring of :mod:`gcs_core.problem.attitude`, where the
other attitude providers and their :class:`~gcs_core.problem.attitude.AttitudeProvider`
protocol live.

On a ground mission that states the Earth's rate in its lab frame, the attitude carried by
the rates is inertial and is turned into the lab's exactly (:mod:`gcs_core.problem.earth_rate`).
"""

from __future__ import annotations

import operator
import sys
import weakref
from collections.abc import Mapping

import numpy as np

from gcs_core.compiled import COMPILED
from gcs_core.frames.rotations import euler123_to_dcm, quat_from_dcm, quat_multiply, quat_normalize
from gcs_core.models import common as model_common
from gcs_core.models.gyro import G_NAMES, g_matrix
from gcs_core.problem import kernels
from gcs_core.problem.attitude import (
    BIAS_RATE_NAMES,
    BLOCK_KNOTS,
    RPY,
    AttitudeEval,
    FrameAttitude,
    ReferenceAttitude,
    rpy_error_jacobian,
)
from gcs_core.problem.earth_rate import lab_attitude


# ----------------------------------------------------------------------------------------
# Quaternion helpers (fast forms of the Eq 4-8/4-10 products used along the gyro knots)
# ----------------------------------------------------------------------------------------
def _dcm(q) -> np.ndarray:
    """Eq 4-8 ``C(q) = (q4² − |e|²) I + 2 e eᵀ − 2 q4 [e×]``, entry by entry; (N, 4) -> (N, 3, 3).

    The same arithmetic as :func:`gcs_core.frames.rotations.quat_to_dcm`, without its
    (N, 3, 3) temporaries.
    """
    e1, e2, e3, q4 = q[:, 0], q[:, 1], q[:, 2], q[:, 3]
    s = q4 * q4 - (e1 * e1 + e2 * e2 + e3 * e3)
    a1, a2, a3 = 2.0 * q4 * e1, 2.0 * q4 * e2, 2.0 * q4 * e3
    C = np.empty((q.shape[0], 3, 3))
    C[:, 0, 0] = s + 2.0 * (e1 * e1)
    C[:, 1, 1] = s + 2.0 * (e2 * e2)
    C[:, 2, 2] = s + 2.0 * (e3 * e3)
    e12, e13, e23 = 2.0 * (e1 * e2), 2.0 * (e1 * e3), 2.0 * (e2 * e3)
    C[:, 0, 1] = e12 + a3
    C[:, 1, 0] = e12 - a3
    C[:, 0, 2] = e13 - a2
    C[:, 2, 0] = e13 + a2
    C[:, 1, 2] = e23 + a1
    C[:, 2, 1] = e23 - a1
    return C


def _scan_products(q, group: int = 8) -> np.ndarray:
    """``Q_k = q_k ⊗ … ⊗ q_0`` for (N, 4) ``q`` (not normalized).

    Two levels: a sequential product inside groups of ``group`` consecutive steps
    (``group − 1`` vectorized passes over N/group rows), the same recursively over the
    group totals, then each group is composed with the product of all earlier groups.
    About 2.3 passes over the data instead of the ``log2 N`` of a Hillis–Steele prefix;
    composition is associative, so only the round-off differs.
    """
    n = q.shape[0]
    if n <= 4 * group:
        Q = q.copy()
        d = 1
        while d < n:
            Q[d:] = quat_multiply(Q[d:], Q[:-d])
            d *= 2
        return Q
    nb = -(-n // group)
    Q = np.empty((nb * group, 4))
    Q[:n] = q
    Q[n:] = (0.0, 0.0, 0.0, 1.0)  # identity steps pad the last group
    Q = Q.reshape(nb, group, 4)
    for j in range(1, group):
        Q[:, j] = quat_multiply(Q[:, j], Q[:, j - 1])
    before = _scan_products(np.ascontiguousarray(Q[:-1, -1]), group)  # product of groups < b
    Q[1:] = quat_multiply(Q[1:], before[:, None, :])
    return Q.reshape(-1, 4)[:n]


def _quat_scan(q):
    """Cumulative composition ``Q_k = q_k ⊗ … ⊗ q_0``, normalized (see :func:`_scan_products`)."""
    return quat_normalize(_scan_products(np.asarray(q, dtype=float)))


def _step_quaternions(omega, dt):
    """Quaternions of ``exp(−[ω Δt ×])`` (Eq 4-38), shape (N, 4)."""
    phi = omega * dt[:, None]
    ang = np.sqrt(np.einsum("ij,ij->i", phi, phi))
    half = 0.5 * ang
    small = ang < 1e-12
    k = np.where(small, 0.5 - ang**2 / 48.0, np.sin(half) / np.where(small, 1.0, ang))
    out = np.empty((phi.shape[0], 4))
    np.multiply(phi, k[:, None], out=out[:, :3])
    out[:, 3] = np.cos(half)
    return out


# ----------------------------------------------------------------------------------------
class _GyroConsts:
    """Everything of the gyro-carried attitude that depends on the state but not on time."""

    __slots__ = ("Ginv", "M", "dM", "b", "bdot", "MtGinv", "C0", "J0", "Ma", "q0", "t_mid")

    def __init__(self, att: GyroAttitude, values: Mapping[str, float]):
        p = att._gyro_params(values)
        G = g_matrix(p)
        self.Ginv = np.linalg.inv(G)
        self.M, self.dM = model_common.alignment_matrix(p)
        self.b = np.array([p["bias_x"], p["bias_y"], p["bias_z"]])
        self.bdot = np.array([p[n] for n in BIAS_RATE_NAMES])
        self.MtGinv = self.M.T @ self.Ginv
        rpy = [values[n] for n in RPY]
        self.C0 = euler123_to_dcm(*rpy) @ att.ref.reference(att.t_ref)[0]
        self.J0 = rpy_error_jacobian(*rpy)
        self.Ma = self.C0.T @ self.J0  # C(t) Ma = ∂δθ(t)/∂(φ, θ, ψ)
        self.q0 = quat_from_dcm(self.C0)
        self.t_mid = 0.5 * (att.knots[0] + att.knots[-1])


class _Block:
    """Knots ``r0 .. r1`` of the gyro-carried attitude (rows ``r0 .. r1−1``).

    C : (n+1, 3, 3) attitude at the knots; omega : (n, 3) corrected rates;
    W : ``(G⁻¹ y, u, τ)`` of the rows, from which ``∂ω/∂p`` is formed where needed;
    E : (n+1, 3, P) the cumulative sums ``E_k``.
    """

    __slots__ = ("r0", "r1", "C", "omega", "W", "E")

    def __init__(self, r0, r1, C, omega, W, E):
        self.r0, self.r1, self.C, self.omega, self.W, self.E = r0, r1, C, omega, W, E


def _rate_partials(c: _GyroConsts, Gy, u, tau) -> np.ndarray:
    """``∂ω/∂p`` (n, 3, 18) over :attr:`GyroAttitude.param_names` from ``G⁻¹ y``, ``u``, ``τ``."""
    W = np.empty((Gy.shape[0], 3, 18))
    for a in range(3):
        for col in range(3):
            # ∂(G⁻¹)/∂G_ac = −G⁻¹ E_ac G⁻¹  ->  ∂ω = −Mᵀ G⁻¹ e_a (G⁻¹ y)_c
            W[:, :, 3 * a + col] = -c.MtGinv[:, a][None, :] * Gy[:, col : col + 1]
    W[:, :, 9:12] = -c.M.T[None, :, :]
    for k in range(3):
        W[:, :, 12 + k] = u @ c.dM[k]  # (∂M/∂a_k)ᵀ u
    W[:, :, 15:18] = -c.M.T[None, :, :] * tau[:, None, None]
    return W


def _progression(idx: np.ndarray):
    """A slice for ascending indices in arithmetic progression (views instead of gathers),
    else the indices as int32 (row numbers within a block; they are kept, see _Where)."""
    if idx.size == 1:
        return slice(int(idx[0]), int(idx[0]) + 1)
    if idx.size:
        step = int(idx[1] - idx[0])
        if step > 0 and idx[-1] - idx[0] == step * (idx.size - 1) and np.all(np.diff(idx) == step):
            return slice(int(idx[0]), int(idx[-1]) + 1, step)
    return idx.astype(np.int32)


class _Where:
    """Where N frame times fall among the knots of a :class:`GyroAttitude` (state-free).

    b : the block holding every frame (None when the frames straddle blocks);
    j : rows of the block's ``C``/``E`` to read (``X = E_k`` on knot k, ``E_{k−1}`` off a
    knot), a slice when regular; w : rows of the block's rates; g : (N,) frames off a knot
    (None when all are on knots), ig : their rows, s : (N_g,) their time past knot k − 1.
    Kept per chunk by :meth:`GyroAttitude._locate`, so irregular rows are int32 arrays.
    """

    __slots__ = ("b", "j", "w", "g", "ig", "s")
    b: int | None
    j: slice | np.ndarray | None
    w: slice | np.ndarray | None
    g: np.ndarray | None
    ig: np.ndarray | None
    s: np.ndarray | None

    @classmethod
    def of(cls, att: GyroAttitude, t: np.ndarray) -> _Where:
        self = cls()
        k = att._rows(t)
        b = (k - 1) // att._block_knots
        self.b = self.j = self.w = self.g = self.ig = self.s = None
        if not t.size or b[0] != b[-1] or not np.all(b == b[0]):
            return self
        self.b = int(b[0])
        i = k - 1 - self.b * att._block_knots  # row within the block
        on_knot = att.knots[k] == t  # frame on knot k: C_k, E_k
        if np.all(on_knot):
            self.j = _progression(i + 1)
            self.w = _progression(i)
            return self
        self.j = _progression(np.where(on_knot, i + 1, i))
        self.w = w = i.astype(np.int32)
        self.g = ~on_knot
        self.ig = w[self.g]
        self.s = t[self.g] - att.knots[k[self.g] - 1]
        return self


class GyroAttitude:
    """Attitude carried by the gyros from roll/pitch/yaw at ``t_ref`` (module docstring).

    Parameters
    ----------
    mode : reference frame of the roll/pitch/yaw at ``t_ref``.
    ephemeris : for the reference frame at ``t_ref``.
    gyro_name : the gyro sensor's name (its parameters are ``<name>.G_ij``, ``.bias_*``,
        ``.align_*``).
    t_gyro : (K,) gyro row times; row k averages the rate over ``(t_{k-1}, t_k]``.
    y_gyro : (K, 3) gyro output [rad/s].
    block_knots : rows per block of the propagation (bounded memory, below).
    earth_rate : (3,) the Earth's rate in the lab frame of a ground mission [rad/s], or None
        (:mod:`gcs_core.problem.earth_rate`).

    Memory. The propagation is computed in blocks of ``block_knots`` rows: each block
    starts from the attitude and ``E`` at its first knot (a checkpoint, 3×3 + 3×P
    numbers) and ends with the checkpoint of the next, so only one block of knot data
    (``C``, ``ω``, ``W``, ``E``) is held at a time, whatever the span. The chunked
    linearization asks for blocks in time order; any other request recomputes from the
    nearest checkpoint.
    """

    kind = "three_axis"

    def __init__(
        self,
        mode: str,
        ephemeris,
        gyro_name: str,
        t_gyro,
        y_gyro,
        *,
        block_knots: int = BLOCK_KNOTS,
        earth_rate=None,
    ):
        self.ref = ReferenceAttitude(mode, ephemeris)
        #: (3,) the Earth's rate in the reference (lab) frame [rad/s], or None (module docstring)
        self.earth_rate = None if earth_rate is None else np.asarray(earth_rate, float).reshape(3)
        self.gyro = gyro_name
        t_gyro = np.asarray(t_gyro, float)
        dt = np.diff(t_gyro)
        first = float(np.median(dt)) if dt.size else 1.0
        self.knots = np.concatenate([[t_gyro[0] - first], t_gyro])  # τ_0 .. τ_K
        self.y = np.asarray(y_gyro, float)
        self.t_ref = float(self.knots[0])
        self._block_knots = max(1, int(block_knots))
        self._key: tuple[float, ...] | None = None
        self._consts: _GyroConsts | None = None
        self._checkpoints: list = []
        self._blocks: dict[int, _Block] = {}
        self._spare: np.ndarray | None = None
        self._where: dict = {}
        self._getter = operator.itemgetter(*self.names)  # the state key: this provider's values

    @property
    def dt(self) -> np.ndarray:
        """(K,) ``Δ_k = τ_k − τ_{k−1}``."""
        return np.diff(self.knots)

    @property
    def block_knots(self) -> int:
        return self._block_knots

    @block_knots.setter
    def block_knots(self, value: int) -> None:
        self._block_knots = max(1, int(value))
        self._key = None
        self._where = {}

    @property
    def n_blocks(self) -> int:
        return -(-self.y.shape[0] // self._block_knots)

    def block_edges(self) -> np.ndarray:
        """Times ``τ_{bL}`` that end blocks (b = 1 .. n_blocks−1): a chunk of frames never
        straddles one."""
        return self.knots[self._block_knots : self.y.shape[0] : self._block_knots]

    @property
    def param_names(self) -> tuple[str, ...]:
        return tuple(
            f"{self.gyro}.{n}"
            for n in G_NAMES + ("bias_x", "bias_y", "bias_z") + model_common.ALIGN_NAMES + BIAS_RATE_NAMES
        )

    @property
    def names(self) -> tuple[str, ...]:
        return RPY + self.param_names

    def covers(self, t) -> np.ndarray:
        t = np.asarray(t, float)
        return (t >= self.knots[0]) & (t <= self.knots[-1])

    def _lab(self, C, w, t, gyro=None) -> FrameAttitude:
        """The frames in the lab's attitude, the partials at the carried one (earth_rate.py)."""
        C_lab, w = lab_attitude(C, w, t, self.t_ref, self.earth_rate)
        return FrameAttitude(C_lab, None, w, self.names, gyro=gyro, C_chain=C)

    def _gyro_params(self, values):
        return {n.split(".", 1)[1]: values[n] for n in self.param_names}

    def _state(self, values) -> _GyroConsts:
        key = tuple(map(float, self._getter(values)))
        if key != self._key:
            c = _GyroConsts(self, values)
            self._key, self._consts = key, c
            self._checkpoints = [(c.q0, c.C0, np.zeros((3, len(self.param_names))))]
            self._drop_blocks()
            return c
        assert self._consts is not None  # a key is only kept with its constants
        return self._consts

    def clear_cache(self) -> None:
        """Forget the propagation (the next evaluation recomputes it)."""
        self._key = None
        self._consts = None
        self._checkpoints = []
        self._drop_blocks()

    def _rates(self, values, k0: int = 0, k1: int | None = None):
        """Corrected body rates ω_k (K, 3) and ``∂ω_k/∂p`` (K, 3, 18) over param_names,
        for rows ``k0 .. k1−1`` (all by default).

        ``ω = Mᵀ (G⁻¹ y − b − ḃ (t − t_mid))``: Eq 4-32 inverted, with the bias drifting
        linearly about the middle of the span when the bias-instability effect is in use.
        """
        c = _GyroConsts(self, values)
        omega, Gy, u, tau = self._rate_terms(c, k0, self.y.shape[0] if k1 is None else k1)
        return omega, _rate_partials(c, Gy, u, tau)

    def _rate_terms(self, c: _GyroConsts, r0: int, r1: int):
        """``ω``, ``G⁻¹ y``, ``u = G⁻¹ y − b(t)`` (n, 3) and ``τ = t − t_mid`` (n,) of rows r0..r1−1."""
        tau = self.knots[r0 + 1 : r1 + 1] - c.t_mid
        if COMPILED:
            n = r1 - r0
            Gy, u, omega = np.empty((n, 3)), np.empty((n, 3)), np.empty((n, 3))
            kernels.rates(self.y[r0:r1], c.Ginv, c.b, c.bdot, c.M, tau, Gy, u, omega)
            return omega, Gy, u, tau
        Gy = self.y[r0:r1] @ c.Ginv.T  # G⁻¹ y
        u = Gy - c.b - tau[:, None] * c.bdot  # G⁻¹ y − b(t)   (n, 3)
        return u @ c.M, Gy, u, tau  # ω = Mᵀ u

    def _compute_block(self, b: int, with_E: bool) -> _Block:
        """Block ``b`` from its checkpoint (which must exist); records the next checkpoint.

        ``E_k = E_{r0} + Σ_{r0<j≤k} C_jᵀ W_j Δ_j`` with the increments formed from the
        structure of ``W`` (:func:`_rate_partials`) rather than from W itself::

            C_jᵀ ∂ω/∂G_ac = −(C_jᵀ Mᵀ G⁻¹)_{:,a} (G⁻¹ y)_c,   C_jᵀ ∂ω/∂b = −C_jᵀ Mᵀ,
            C_jᵀ ∂ω/∂a_k = C_jᵀ (∂M/∂a_k)ᵀ u,               C_jᵀ ∂ω/∂ḃ = −C_jᵀ Mᵀ τ_j

        Without ``with_E`` (predictions only) the sums are skipped. With numba
        (:mod:`gcs_core.problem.kernels`) the knots and the sums are one compiled pass
        each; the numpy form below composes the steps by a blocked scan.
        """
        c = self._consts
        assert c is not None  # _block() computed the state first
        L = self._block_knots
        r0, r1 = b * L, min(self.y.shape[0], (b + 1) * L)
        n = r1 - r0
        q_s, C_s, E_s = self._checkpoints[b]
        omega, Gy, u, tau = self._rate_terms(c, r0, r1)
        dt = self.knots[r0 + 1 : r1 + 1] - self.knots[r0:r1]
        C = np.empty((n + 1, 3, 3))
        C[0] = C_s
        if COMPILED:
            Q = np.empty((n, 4))
            kernels.propagate(q_s, omega, dt, Q, C[1:])
        else:
            steps = _step_quaternions(omega, dt)
            Q = quat_multiply(_quat_scan(steps), np.broadcast_to(q_s, steps.shape))
            C[1:] = _dcm(Q)
        E = None
        if with_E and COMPILED:
            E = self._spare_E(n + 1)
            kernels.gyro_sums(C, c.MtGinv, c.M, c.dM, Gy, u, tau, dt, E_s, E)
        elif with_E:
            Ct = np.ascontiguousarray(np.swapaxes(C[1:], 1, 2))  # C_jᵀ (n, 3, 3)
            E = self._spare_E(n + 1)
            E[0] = E_s
            incr = E[1:]  # increments, summed in place below
            V = (Ct.reshape(-1, 3) @ c.MtGinv).reshape(n, 9, 1)  # C_jᵀ Mᵀ G⁻¹
            g = (-Gy * dt[:, None]).reshape(n, 1, 3)
            incr[:, :, :9] = np.matmul(V, g).reshape(n, 3, 9)  # columns 3a + c
            Nb = (Ct.reshape(-1, 3) @ (-c.M.T)).reshape(n, 3, 3)  # −C_jᵀ Mᵀ
            np.multiply(Nb, dt[:, None, None], out=incr[:, :, 9:12])
            Z = np.stack([u @ c.dM[k] for k in range(3)], -1)  # (∂M/∂a_k)ᵀ u  (n, 3, 3)
            np.multiply(Ct @ Z, dt[:, None, None], out=incr[:, :, 12:15])
            np.multiply(incr[:, :, 9:12], tau[:, None, None], out=incr[:, :, 15:18])
            np.cumsum(incr, axis=0, out=incr)
            if np.any(E_s):
                incr += E_s
        ck = (Q[-1].copy(), C[-1].copy(), None if E is None else E[-1].copy())
        if len(self._checkpoints) == b + 1:
            self._checkpoints.append(ck)
        elif E is not None and self._checkpoints[b + 1][2] is None:
            self._checkpoints[b + 1] = ck
        return _Block(r0, r1, C, omega, (Gy, u, tau), E)

    def _drop_blocks(self) -> None:
        """Forget the held block; its E buffer becomes the spare if nothing else holds it."""
        for old in self._blocks.values():
            E = old.E
            old.E = None
            # references: the local name and the call argument (E: and its pointer to the base)
            if E is not None and E.base is not None and sys.getrefcount(E) == 2 and sys.getrefcount(E.base) == 2:
                self._spare = E.base
            del E
        self._blocks = {}

    def _spare_E(self, rows: int) -> np.ndarray:
        """An (rows, 3, 18) array, recycled from the block last dropped when nothing else
        holds it (fresh pages cost more than the sums written into them)."""
        buf = self._spare
        self._spare = None
        if buf is None or buf.size < rows * 54:
            buf = np.empty(max(rows, min(self._block_knots, self.y.shape[0]) + 1) * 54)
        return buf[: rows * 54].reshape(rows, 3, 18)

    def _block(self, values, b: int, with_E: bool = True) -> _Block:
        self._state(values)
        held = self._blocks.get(b)
        if held is not None and (held.E is not None or not with_E):
            return held
        # nearest checkpoint at or before b that carries what this block needs
        j = min(b, len(self._checkpoints) - 1)
        while with_E and self._checkpoints[j][2] is None:
            j -= 1
        self._drop_blocks()  # one block held at a time
        for jj in range(j, b + 1):
            blk = self._compute_block(jj, with_E)
            if jj < b and blk.E is not None:
                self._spare = blk.E.base
        self._blocks = {b: blk}
        return blk

    def _rows(self, t):
        K = self.y.shape[0]
        # interval k (1-based) holding t: τ_{k-1} < t ≤ τ_k; t = τ_0 maps to k = 1 with s = 0
        return np.clip(np.searchsorted(self.knots, t, side="left"), 1, K)

    def _locate(self, t) -> _Where:
        """Where the times ``t`` fall among the knots (:class:`_Where`).

        State-independent, so it is kept for times that view a longer array (a chunk of a
        sensor's frame times, asked again at every pass), keyed by that array's identity,
        the offset and the end values (frame times are never changed in place).
        """
        base = t.base if isinstance(t.base, np.ndarray) and t.base.ndim == 1 else None
        key = None
        if base is not None and t.size and t.strides == base.strides:
            off = (t.__array_interface__["data"][0] - base.__array_interface__["data"][0]) // t.itemsize
            key = (id(base), int(off), t.size, float(t[0]), float(t[-1]), self._block_knots)
            hit = self._where.get(key)
            if hit is not None and hit[0]() is base:
                return hit[1]
        where = _Where.of(self, t)
        if key is not None:
            if len(self._where) >= 1024:  # bounded: a long span's chunks
                self._where.clear()
            # a weak reference: the entry neither keeps the array alive nor outlives it
            self._where[key] = (weakref.ref(base), where)
        return where

    def _frames_in_block(self, blk: _Block, t, where: _Where) -> FrameAttitude:
        c = self._consts
        assert c is not None  # blk came from _block(), after _state()
        j, g = where.j, where.g
        if g is None:  # every frame on a knot
            return self._lab(blk.C[j], blk.omega[where.w], t, (c.Ma, (blk.E, j), None))
        C = blk.C[j].copy() if isinstance(j, slice) else blk.C[j]
        w = blk.omega[where.w]
        ig, s = where.ig, where.s
        # C(t) = exp(−[ω_k s ×]) C_{k−1};  C(t)ᵀ δθ(t) = C_0ᵀ δθ_0 + E_{k−1} + C(t)ᵀ W_k s δp
        C[g] = _dcm(_step_quaternions(blk.omega[ig], s)) @ blk.C[ig]
        Gy, u, tau = blk.W
        Wg = _rate_partials(c, Gy[ig], u[ig], tau[ig])
        return self._lab(C, w, t, (c.Ma, (blk.E, j), (g, Wg, s)))

    def frames(self, values: Mapping[str, float], t, *, partials: bool = True) -> FrameAttitude:
        """The attitude at times ``t`` in factored form (:class:`FrameAttitude`); without
        ``partials`` only ``C_BI`` and ``omega_B`` (the cumulative sums are skipped).

        The result may view the held block: use it before asking for another block.
        """
        t = np.atleast_1d(np.asarray(t, float))
        self._state(values)
        where = self._locate(t) if t.size else None
        if where is not None and where.b is not None:
            blk = self._block(values, where.b, partials)
            if not partials:
                C = blk.C[where.j]
                if where.g is not None:
                    if isinstance(where.j, slice):
                        C = C.copy()
                    C[where.g] = _dcm(_step_quaternions(blk.omega[where.ig], where.s)) @ blk.C[where.ig]
                return self._lab(C, blk.omega[where.w], t)
            return self._frames_in_block(blk, t, where)
        return FrameAttitude.of(self.evaluate(values, t))

    def evaluate(self, values: Mapping[str, float], t) -> AttitudeEval:
        t = np.atleast_1d(np.asarray(t, float))
        self._state(values)
        k = self._rows(t)
        b = (k - 1) // self._block_knots
        n, P = t.size, len(self.names)
        if n == 0 or np.all(b == b[0]):
            if n == 0:
                return AttitudeEval(
                    np.zeros((0, 3, 3)), None, self.names, np.zeros((0, 3, P)), omega_B=np.zeros((0, 3))
                )
            ev = self._frames_in_block(self._block(values, int(b[0])), t, _Where.of(self, t)).as_eval()
            return AttitudeEval(np.array(ev.C_BI), None, ev.names, ev.J, omega_B=np.array(ev.omega_B))
        C, J, w = np.empty((n, 3, 3)), np.empty((n, 3, P)), np.empty((n, 3))
        for bb in np.unique(b):
            sel = np.flatnonzero(b == bb)
            fr = self._frames_in_block(self._block(values, int(bb)), t[sel], _Where.of(self, t[sel]))
            C[sel], J[sel], w[sel] = fr.C_BI, fr.J, fr.omega_B
        return AttitudeEval(C, None, self.names, J, omega_B=w)
