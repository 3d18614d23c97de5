"""The gyro-carried three-axis attitude and its partials (seed §4.2.7, Eq 4-32, 4-33, 4-38).

:class:`GyroAttitude` propagates the roll/pitch/yaw at ``t_ref`` with the gyro rates,
block by block with a carry, and forms the partials of the body attitude error with
respect to the attitude, the gyro's ``G`` (Eq 4-37), bias and bias rate as cumulative
sums; the derivation is in the docstring of :mod:`gcs_core.problem.attitude`, where the
other attitude providers and their :class:`~gcs_core.problem.attitude.AttitudeProvider`
protocol live.

A bias following aux channels (the family ``bias_vs_<channel>`` of the gyro, issue 26: the
bias stepping when a heater switches) is carried inside the propagation::

    b(t) = b + ḃ τ + Σ_i k_i x_i(t),   ∂ω/∂k_i = −Mᵀ x_i(t)

with ``x_i`` the channel held over each row's interval, minus its mean over the rows; its
cumulative sums are those of the bias with ``x_i`` in place of ``τ`` (:meth:`GyroAttitude._compute_block`).

On a ground mission that states the Earth's rate in its lab frame, the attitude carried by
the rates is inertial and is turned into the lab's exactly (:mod:`gcs_core.problem.earth_rate`).
"""

from __future__ import annotations

import operator
import sys
from collections.abc import Mapping

import numpy as np

from gcs_core.compiled import COMPILED
from gcs_core.frames.rotations import euler123_to_dcm, quat_from_dcm, quat_multiply
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
from gcs_core.problem.quat_steps import fast_dcm, quat_scan, step_quaternions
from gcs_core.problem.view_cache import ViewCache


# ----------------------------------------------------------------------------------------
class _GyroConsts:
    """Everything of the gyro-carried attitude that depends on the state but not on time."""

    __slots__ = ("Ginv", "M", "dM", "b", "bdot", "k", "MtGinv", "C0", "J0", "Ma", "q0", "t_mid")

    def __init__(self, att: GyroAttitude, values: Mapping[str, float]):
        p = att._gyro_params(values)
        G = g_matrix(p)
        self.Ginv = np.linalg.inv(G)
        self.M, self.dM = model_common.alignment_matrix(p)
        self.b = np.array([p["bias_x"], p["bias_y"], p["bias_z"]])
        self.bdot = np.array([p[n] for n in BIAS_RATE_NAMES])
        #: (m, 3) the bias per unit of each step channel [rad/s per unit]
        self.k = np.array([[p[f"bias_{ax}_vs_{tag}"] for ax in "xyz"] for tag in att.step_tags]).reshape(-1, 3)
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
    W : ``(G⁻¹ y, u, τ, x)`` of the rows (x: (n, m) the step channels), from which ``∂ω/∂p`` is formed where needed;
    E : (n+1, 3, P) the cumulative sums ``E_k``.
    """

    __slots__ = ("r0", "r1", "C", "omega", "W", "E")

    def __init__(self, r0, r1, C, omega, W, E):
        self.r0, self.r1, self.C, self.omega, self.W, self.E = r0, r1, C, omega, W, E


def _rate_partials(c: _GyroConsts, Gy, u, tau, xs) -> np.ndarray:
    """``∂ω/∂p`` (n, 3, 18 + 3m) over :attr:`GyroAttitude.param_names` from ``G⁻¹ y``, ``u``,
    ``τ`` and the m step channels ``xs`` (n, m)."""
    W = np.empty((Gy.shape[0], 3, 18 + 3 * xs.shape[1]))
    for a in range(3):
        for col in range(3):
            # ∂(G⁻¹)/∂G_ac = −G⁻¹ E_ac G⁻¹  ->  ∂ω = −Mᵀ G⁻¹ e_a (G⁻¹ y)_c
            W[:, :, 3 * a + col] = -c.MtGinv[:, a][None, :] * Gy[:, col : col + 1]
    W[:, :, 9:12] = -c.M.T[None, :, :]
    for k in range(3):
        W[:, :, 12 + k] = u @ c.dM[k]  # (∂M/∂a_k)ᵀ u
    W[:, :, 15:18] = -c.M.T[None, :, :] * tau[:, None, None]
    for i in range(xs.shape[1]):
        W[:, :, 18 + 3 * i : 21 + 3 * i] = -c.M.T[None, :, :] * xs[:, i, None, None]
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
    steps : channel -> (K,) its value over each row's interval: the bias follows it
        (module docstring; elements ``<gyro>.bias_<ax>_vs_<channel>``); taken about its mean.

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
        steps=None,
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
        steps = dict(steps or {})
        #: the aux channels the bias follows, and (K, m) their values about the mean
        self.step_tags: tuple[str, ...] = tuple(steps)
        self.X = np.zeros((self.y.shape[0], len(steps)))
        for i, tag in enumerate(self.step_tags):
            x = np.asarray(steps[tag], float).reshape(-1)
            self.X[:, i] = x - np.mean(x)
        self.t_ref = float(self.knots[0])
        self._block_knots = max(1, int(block_knots))
        self._key: tuple[float, ...] | None = None
        self._consts: _GyroConsts | None = None
        self._checkpoints: list = []
        self._blocks: dict[int, _Block] = {}
        self._spare: np.ndarray | None = None
        self._where = ViewCache(1024)
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
        self._where = ViewCache(1024)

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
            for n in G_NAMES
            + ("bias_x", "bias_y", "bias_z")
            + model_common.ALIGN_NAMES
            + BIAS_RATE_NAMES
            + tuple(f"bias_{ax}_vs_{tag}" for tag in self.step_tags for ax in "xyz")
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
        """Corrected body rates ω_k (K, 3) and ``∂ω_k/∂p`` (K, 3, P) over param_names,
        for rows ``k0 .. k1−1`` (all by default).

        ``ω = Mᵀ (G⁻¹ y − b − ḃ (t − t_mid))``: Eq 4-32 inverted, with the bias drifting
        linearly about the middle of the span when the bias-instability effect is in use.
        """
        c = _GyroConsts(self, values)
        k1 = self.y.shape[0] if k1 is None else k1
        omega, Gy, u, tau = self._rate_terms(c, k0, k1)
        return omega, _rate_partials(c, Gy, u, tau, self.X[k0:k1])

    def _rate_terms(self, c: _GyroConsts, r0: int, r1: int):
        """``ω``, ``G⁻¹ y``, ``u = G⁻¹ y − b(t)`` (n, 3) and ``τ = t − t_mid`` (n,) of rows r0..r1−1."""
        tau = self.knots[r0 + 1 : r1 + 1] - c.t_mid
        if COMPILED:
            n = r1 - r0
            Gy, u, omega = np.empty((n, 3)), np.empty((n, 3)), np.empty((n, 3))
            kernels.rates(self.y[r0:r1], c.Ginv, c.b, c.bdot, c.M, tau, Gy, u, omega)
        else:
            Gy = self.y[r0:r1] @ c.Ginv.T  # G⁻¹ y
            u = Gy - c.b - tau[:, None] * c.bdot  # G⁻¹ y − b(t)   (n, 3)
            omega = u @ c.M  # ω = Mᵀ u
        if self.step_tags and np.any(c.k):
            u -= self.X[r0:r1] @ c.k  # the bias following the step channels
            omega = u @ c.M
        return omega, Gy, u, tau

    def _compute_block(self, b: int, with_E: bool) -> _Block:
        """Block ``b`` from its checkpoint (which must exist); records the next checkpoint.

        ``E_k = E_{r0} + Σ_{r0<j≤k} C_jᵀ W_j Δ_j`` with the increments formed from the
        structure of ``W`` (:func:`_rate_partials`) rather than from W itself::

            C_jᵀ ∂ω/∂G_ac = −(C_jᵀ Mᵀ G⁻¹)_{:,a} (G⁻¹ y)_c,   C_jᵀ ∂ω/∂b = −C_jᵀ Mᵀ,
            C_jᵀ ∂ω/∂a_k = C_jᵀ (∂M/∂a_k)ᵀ u,               C_jᵀ ∂ω/∂ḃ = −C_jᵀ Mᵀ τ_j,
            C_jᵀ ∂ω/∂k_i = −C_jᵀ Mᵀ x_ij

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
            steps = step_quaternions(omega, dt)
            Q = quat_multiply(quat_scan(steps), np.broadcast_to(q_s, steps.shape))
            C[1:] = fast_dcm(Q)
        E = None
        xs = self.X[r0:r1]
        if with_E and COMPILED:
            E = self._spare_E(n + 1)
            if self.step_tags:
                E18 = np.empty((n + 1, 3, 18))
                kernels.gyro_sums(C, c.MtGinv, c.M, c.dM, Gy, u, tau, dt, np.ascontiguousarray(E_s[:, :18]), E18)
                E[:, :, :18] = E18
                self._step_sums(C, c, dt, xs, E_s, E)
            else:
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
            for i in range(xs.shape[1]):
                np.multiply(incr[:, :, 9:12], xs[:, i, None, None], out=incr[:, :, 18 + 3 * i : 21 + 3 * i])
            np.cumsum(incr, axis=0, out=incr)
            if np.any(E_s):
                incr += E_s
        ck = (Q[-1].copy(), C[-1].copy(), None if E is None else E[-1].copy())
        if len(self._checkpoints) == b + 1:
            self._checkpoints.append(ck)
        elif E is not None and self._checkpoints[b + 1][2] is None:
            self._checkpoints[b + 1] = ck
        return _Block(r0, r1, C, omega, (Gy, u, tau, xs), E)

    @staticmethod
    def _step_sums(C, c: _GyroConsts, dt, xs, E_s, E) -> None:
        """The step channels' columns of ``E`` (from 18 on), in place: ``E_s`` plus the
        cumulative sums of ``−C_jᵀ Mᵀ x_ij Δ_j`` (the bias's increments times ``x``)."""
        n = dt.size
        Nb = (np.swapaxes(C[1:], 1, 2).reshape(-1, 3) @ (-c.M.T)).reshape(n, 3, 3) * dt[:, None, None]
        for i in range(xs.shape[1]):
            cols = slice(18 + 3 * i, 21 + 3 * i)
            E[0, :, cols] = E_s[:, cols]
            np.cumsum(Nb * xs[:, i, None, None], axis=0, out=E[1:, :, cols])
            E[1:, :, cols] += E_s[:, cols]

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
        """An (rows, 3, P) array, recycled from the block last dropped when nothing else
        holds it (fresh pages cost more than the sums written into them)."""
        P = len(self.param_names)
        buf = self._spare
        self._spare = None
        if buf is None or buf.size < rows * 3 * P:
            buf = np.empty(max(rows, min(self._block_knots, self.y.shape[0]) + 1) * 3 * P)
        return buf[: rows * 3 * P].reshape(rows, 3, P)

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
        sensor's frame times, asked again at every pass: :class:`~.view_cache.ViewCache`).
        """
        return self._where.get(t, self._block_knots, lambda: _Where.of(self, t))

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
        C[g] = fast_dcm(step_quaternions(blk.omega[ig], s)) @ blk.C[ig]
        Gy, u, tau, xs = blk.W
        Wg = _rate_partials(c, Gy[ig], u[ig], tau[ig], xs[ig])
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
                    C[where.g] = fast_dcm(step_quaternions(blk.omega[where.ig], where.s)) @ blk.C[where.ig]
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
