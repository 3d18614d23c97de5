"""The multiplicative EKF of FILTR: gyro kinematics and filter blocks (Eq 3-3, 3-4, 4-38).

Two kinds of problem, one block format (:class:`~gcs_core.estimators.kalman.linear.LinearBlock`):

* **With a gyro** (``problem.gyro_name`` set, ``problem.attitude`` a GyroAttitude): the
  multiplicative EKF. The filter state is laid out ``(δθ, b, s)`` (:class:`Layout`): the
  three ``att.roll/pitch/yaw`` elements are *reinterpreted* as the body attitude-error
  angles δθ **of the current time** (columns ``kf.dtheta_x/y/z``, convention
  ``C_true = (I − [δθ×]) C`` of :mod:`gcs_core.models.base`), ``b`` are the gyro biases
  that random-walk (``rrw > 0``), ``s`` every other solve-for element (static: gyro
  scale/misalignment, biases when ``rrw = 0``, sensor parameters). Each block propagates
  a nominal attitude with the gyro-corrected rates (Eq 4-32 inverted, Eq 4-38) from the
  block-start attitude (:class:`GyroSegment`), with the error transition of
  :mod:`gcs_core.problem.attitude`::

      Φ_θθ = C_k C_{k−1}ᵀ,   Φ_θp = C_k (E_k − E_{k−1}) = W_k Δ_k,   Φ_bb = I      (Eq 4-38)

  and Farrenkopf's process noise (:func:`~gcs_core.models.gyro_noise.farrenkopf_q`). Every sensor's predictions and
  partials are evaluated *vectorized* over the block at that nominal (through
  :func:`~gcs_core.problem.linearization.linearize`, the nominal being its attitude provider);
  the core then makes exact frame-by-frame linear updates with the accumulated error
  state (rows ``A = H Ψ(t)``), and the next block re-linearizes at the updated estimate
  (the reset).
* **Without a gyro** (reference-pointing or spinning): the state is the solve-for
  elements themselves, static (Q = 0): recursive least squares over blocks.

Both use the residual ``r = y − h(nominal)`` as the measurement of the error state.

References
----------
Lefferts, Markley & Shuster, "Kalman filtering for spacecraft attitude estimation",
J. Guidance 5(5), 1982 (multiplicative EKF). Farrenkopf, "Analytic steady-state accuracy
solutions for two common spacecraft attitude estimators", J. Guidance & Control 1(4),
1978 (σ_v, σ_u noise model).
"""

from __future__ import annotations

from collections.abc import Mapping
from dataclasses import dataclass, replace

import numpy as np

from gcs_core.errors import EstimationError
from gcs_core.estimators.kalman.linear import LinearBlock
from gcs_core.frames.rotations import quat_to_dcm
from gcs_core.models import common as model_common
from gcs_core.models.gyro import G_NAMES, g_matrix
from gcs_core.models.gyro_noise import GyroNoise, farrenkopf_q, gyro_noise
from gcs_core.problem.attitude import BIAS_RATE_NAMES, RPY, AttitudeEval, ProviderDefaults
from gcs_core.problem.build import Problem
from gcs_core.problem.earth_rate import lab_attitude
from gcs_core.problem.linearization import linearize
from gcs_core.problem.prepare import SensorData

#: filter columns of the attitude error δθ (body axes, rad).
DTH = ("kf.dtheta_x", "kf.dtheta_y", "kf.dtheta_z")


def step_quaternions(omega: np.ndarray, dt: np.ndarray) -> np.ndarray:
    """Quaternions of the frame rotation ``exp(−[ω Δt ×])`` of each step (Eq 4-38a), (K, 4)."""
    phi = omega * np.asarray(dt, float)[:, None]
    ang = np.linalg.norm(phi, axis=-1)
    small = ang < 1e-12
    k = np.where(small, 0.5 - ang**2 / 48.0, np.sin(0.5 * ang) / np.where(small, 1.0, ang))
    return np.column_stack([phi * k[:, None], np.cos(0.5 * ang)])


def cumulative_rotations(R: np.ndarray) -> np.ndarray:
    """``R_k ⋯ R_1`` for every k (K, 3, 3) by a parallel prefix (ceil(log2 K) matmul passes)."""
    C = np.array(R, float)
    d = 1
    while d < C.shape[0]:
        C[d:] = C[d:] @ C[:-d]
        d *= 2
    return C


class GyroSegment:
    """Nominal attitude carried by the gyros over one block, and its error transitions.

    The nominal starts at ``C_0`` at ``τ_0`` and turns with the corrected rates ``ω_k``
    of the intervals ``(τ_{k−1}, τ_k]`` (Eq 4-38). For the error state ``(δθ, p)``::

        Ψ_θ·(t) = [C(t) C_0ᵀ,  C(t) E(t)],   E(t) = Σ_{steps} Cᵀ W Δ       (attitude.py)
        Π(t) = Σ_{steps} Ψ_dd⁻¹ Q Ψ_dd⁻ᵀ,   Ψ_dd⁻¹ = [[C_0 Cᵀ, −C_0 E_b], [0, I]]

    Parameters
    ----------
    knots : (K+1,) times τ_0..τ_K [s].
    omega : (K, 3) corrected body rate of each interval [rad/s].
    Wg : (K, 3, ng) ``∂ω/∂p`` for the gyro parameters in the filter state, the nb
        random-walking biases first.
    C0 : (3, 3) nominal attitude at τ_0.
    noise, Wy, Wb, axes : for :func:`~gcs_core.models.gyro_noise.farrenkopf_q` (axes: the
        random-walking biases).
    earth : (3,) the Earth's rate in the lab frame of a ground mission [rad/s], or None.
        Then the rates carry the inertial attitude ``C_in`` from ``C_0`` and the nominal is
        the lab's, ``C = C_in exp(+[ω_E (t − τ_0)×])`` (exact;
        :mod:`gcs_core.problem.gyro_attitude`); the error transitions are ``C_in``'s, exactly
        (a body-frame error of ``C_in`` is the same error of ``C``).
    """

    def __init__(self, knots, omega, Wg, C0, noise: GyroNoise, Wy, Wb, axes=(), earth=None):
        self.knots = np.asarray(knots, float)
        self.dt = np.diff(self.knots)
        self.omega, self.Wg, self.C0 = np.asarray(omega, float), np.asarray(Wg, float), C0
        self.noise, self.Wy, self.Wb, self.axes = noise, Wy, Wb, tuple(axes)
        self.nb = len(self.axes)
        self.earth = None if earth is None else np.asarray(earth, float).reshape(3)
        steps = cumulative_rotations(quat_to_dcm(step_quaternions(self.omega, self.dt)))
        self.C_in = np.concatenate([C0[None], steps @ C0])  # (K+1, 3, 3)
        self.C = self._lab(self.C_in, self.knots)
        # E_k = Σ_{j≤k} C_jᵀ W_j Δ_j
        incr = np.swapaxes(self.C_in[1:], 1, 2) @ self.Wg * self.dt[:, None, None]
        self.E = np.concatenate([np.zeros((1, 3, self.Wg.shape[2])), np.cumsum(incr, axis=0)])
        Q = farrenkopf_q(self.dt, noise, Wy, Wb, self.axes)
        dPi = self._referred(self.C_in[1:], self.E[1:], Q)
        d = 3 + self.nb
        self.Pi = np.concatenate([np.zeros((1, d, d)), np.cumsum(dPi, axis=0)])

    def _lab(self, C_in, t):
        """The lab-frame nominal from the inertially carried one (no Earth rate: itself)."""
        return lab_attitude(C_in, None, t, self.knots[0], self.earth)[0]

    def _referred(self, C, E, Q):
        """``Ψ_dd⁻¹ Q Ψ_dd⁻ᵀ`` at the given states (process noise referred to τ_0)."""
        nb = self.nb
        T = np.zeros((C.shape[0], 3 + nb, 3 + nb))
        T[:, :3, :3] = self.C0 @ np.swapaxes(C, 1, 2)
        if nb:
            T[:, :3, 3:] = -self.C0 @ E[:, :, :nb]
            T[:, 3:, 3:] = np.eye(nb)
        out = T @ Q @ np.swapaxes(T, 1, 2)
        return 0.5 * (out + np.swapaxes(out, 1, 2))

    def at_knots(self):
        """``(C C_0ᵀ, C E, Π)`` at the knots τ_0..τ_K (as :meth:`at`, without re-propagating)."""
        return self.C_in @ self.C0.T, self.C_in @ self.E, self.Pi

    def at(self, t):
        """Nominal ``C`` (N, 3, 3), rate ω (N, 3), ``Ψ_θ·`` as ``(C C_0ᵀ, C E)`` and Π (N, d, d)."""
        t = np.atleast_1d(np.asarray(t, float))
        K = self.dt.size
        k = np.clip(np.searchsorted(self.knots, t, side="left"), 1, max(K, 1))
        s = t - self.knots[k - 1]
        if K == 0:
            N = t.size
            return (
                np.broadcast_to(self.C0, (N, 3, 3)),
                np.zeros((N, 3)),
                np.broadcast_to(np.eye(3), (N, 3, 3)),
                np.zeros((N, 3, self.Wg.shape[2])),
                np.zeros((N, 3 + self.nb, 3 + self.nb)),
            )
        w = self.omega[k - 1]
        C = quat_to_dcm(step_quaternions(w, s)) @ self.C_in[k - 1]
        E = self.E[k - 1] + np.swapaxes(C, 1, 2) @ self.Wg[k - 1] * s[:, None, None]
        Q = farrenkopf_q(s, self.noise, self.Wy, self.Wb, self.axes)
        Pi = self.Pi[k - 1] + self._referred(C, E, Q)
        if self.earth is not None:
            C_lab = self._lab(C, t)
            return C_lab, w - C_lab @ self.earth, C @ self.C0.T, C @ E, Pi
        return C, w, C @ self.C0.T, C @ E, Pi


def gyro_segment(att, k_a: int, k_b: int, omega, Wg, C0, noise: GyroNoise, Wy, Wb, axes=()) -> GyroSegment:
    """The :class:`GyroSegment` over gyro knots ``k_a..k_b`` of ``att`` (a GyroAttitude), with
    its Earth rate (None but on a ground mission that states it)."""
    return GyroSegment(att.knots[k_a : k_b + 1], omega, Wg, C0, noise, Wy, Wb, axes, earth=att.earth_rate)


@dataclass(frozen=True)
class Layout:
    """Order of the filter state (module docstring).

    Attributes
    ----------
    columns : column names given to :func:`linearize` (``kf.dtheta_*`` for δθ).
    elements : the state element behind each column (``att.roll/pitch/yaw`` for δθ).
    d : dynamic states (3 + nb with a gyro, 0 without); nb : random-walking biases.
    gyro_cols : (ng,) columns of the gyro parameters, the nb dynamic biases first.
    gyro_w : (ng,) their positions in ``GyroAttitude.param_names``.
    gs_pos : positions of the static gyro columns within the static part ``s``.
    """

    columns: tuple[str, ...]
    elements: tuple[str, ...]
    d: int
    nb: int
    gyro_cols: np.ndarray
    gyro_w: np.ndarray
    gs_pos: np.ndarray

    @property
    def n(self) -> int:
        return len(self.columns)

    @property
    def ns(self) -> int:
        return self.n - self.d

    @property
    def gyro(self) -> bool:
        return self.d > 0


def attitude_gyro_noise(problem: Problem, scale: float = 1.0) -> GyroNoise:
    """σ_v, σ_u, σ_e of the gyro carrying the attitude (:func:`gcs_core.models.gyro_noise.gyro_noise`
    at the median sample interval of its rows), times ``scale``."""
    assert problem.gyro_name is not None  # called for a gyro-carried attitude
    spec = problem.builder.spec.sensor(problem.gyro_name)
    dt = float(np.median(problem.gyro_attitude.dt))
    return gyro_noise(spec, dt).scaled(scale)


def make_layout(problem: Problem, noise: GyroNoise | None) -> Layout:
    """The filter state of ``problem`` (see :class:`Layout`)."""
    solve = list(problem.state.solve_for)
    if problem.gyro_name is None:
        return Layout(tuple(solve), tuple(solve), 0, 0, np.zeros(0, int), np.zeros(0, int), np.zeros(0, int))
    missing = [n for n in RPY if n not in solve]
    if missing:
        raise EstimationError(
            "the Kalman filter estimates the attitude with the gyros: make " + ", ".join(missing) + " solve-for"
        )
    pnames = list(problem.gyro_attitude.param_names)
    bias = [f"{problem.gyro_name}.bias_{a}" for a in "xyz"]
    dyn = [b for b in bias if b in solve] if noise is not None and noise.sigma_u > 0 else []
    static = [n for n in solve if n not in RPY and n not in dyn]
    elements = tuple(RPY) + tuple(dyn) + tuple(static)
    columns = DTH + tuple(dyn) + tuple(static)
    gyro = [n for n in elements[3:] if n in pnames]
    cols = np.array([elements.index(n) for n in gyro], int)
    d = 3 + len(dyn)
    gs = np.array([c - d for c in cols if c >= d], int)
    return Layout(columns, elements, d, len(dyn), cols, np.array([pnames.index(n) for n in gyro], int), gs)


#: gyro parameters in the order of ``GyroAttitude.param_names`` that :func:`gyro_rates` knows.
_KNOWN_GYRO = G_NAMES + ("bias_x", "bias_y", "bias_z") + model_common.ALIGN_NAMES + BIAS_RATE_NAMES


def gyro_rates(att, values: Mapping[str, float], k0: int, k1: int):
    """Corrected rates of gyro rows ``k0..k1−1`` and their partials (Eq 4-32 inverted).

    ``ω = Mᵀ (G⁻¹ y − b − ḃ τ)`` (τ: time from the middle of the span; ḃ the optional bias
    rate); returns ω (K, 3), ``∂ω/∂p`` (K, 3, P) over ``att.param_names``, ``W_y = Mᵀ G⁻¹``
    and ``W_b = −Mᵀ``. These are the expressions of
    :class:`~gcs_core.problem.gyro_attitude.GyroAttitude` restricted to a window of rows; if the
    provider has parameters this function does not know, its own (whole-span) rates are
    sliced instead.
    """
    names = tuple(n.split(".", 1)[1] for n in att.param_names)
    p = {n: values.get(f"{att.gyro}.{n}", 0.0) for n in _KNOWN_GYRO}
    G = g_matrix(p)
    Ginv = np.linalg.inv(G)
    M, dM = model_common.alignment_matrix(p)
    if names != _KNOWN_GYRO[: len(names)]:
        omega, W = att._rates(values)
        return omega[k0:k1], W[k0:k1], M.T @ Ginv, -M.T
    b = np.array([p["bias_x"], p["bias_y"], p["bias_z"]])
    bdot = np.array([p[n] for n in BIAS_RATE_NAMES])
    tau = att.knots[k0 + 1 : k1 + 1] - 0.5 * (att.knots[0] + att.knots[-1])
    y = att.y[k0:k1]
    Gy = y @ Ginv.T  # G⁻¹ y
    u = Gy - b - tau[:, None] * bdot
    omega = u @ M  # Mᵀ (G⁻¹ y − b − ḃ τ)
    MtGinv = M.T @ Ginv
    W = np.empty((y.shape[0], 3, len(_KNOWN_GYRO)))
    for a in range(3):
        for c in range(3):
            W[:, :, 3 * a + c] = -MtGinv[:, a][None, :] * Gy[:, c : c + 1]  # ∂ω/∂G_ac
    W[:, :, 9:12] = -M.T[None, :, :]
    for k in range(3):
        W[:, :, 12 + k] = u @ dM[k]
    W[:, :, 15:18] = -M.T[None, :, :] * tau[:, None, None]
    return omega, W[:, :, : len(names)], MtGinv, -M.T


class SegmentAttitude(ProviderDefaults):
    """Attitude provider for :func:`linearize` on a block: the gyro-propagated nominal.

    Its only "elements" are the error angles ``kf.dtheta_*`` with ``∂δθ/∂δθ = I``.
    """

    kind = "three_axis"
    names = DTH

    def __init__(self, seg: GyroSegment):
        self.seg = seg

    def evaluate(self, values, t) -> AttitudeEval:
        C, w, *_ = self.seg.at(t)
        J = np.broadcast_to(np.eye(3), (C.shape[0], 3, 3))
        return AttitudeEval(C, None, DTH, J, omega_B=w)


def sensor_window(sd: SensorData, lo: int, hi: int) -> SensorData:
    """Frames ``lo..hi−1`` of a sensor (every per-frame array of its geometry sliced)."""
    n, sl = sd.n, slice(lo, hi)

    def cut(a):
        return a[sl] if isinstance(a, np.ndarray) and a.ndim >= 1 and a.shape[0] == n else a

    g = sd.geom
    fields = {
        f: cut(getattr(g, f)) for f in ("t", "C_BI", "spin_axis_I", "r_I", "v_I", "sun_I", "B_I", "star_I", "omega_B")
    }
    geom = replace(
        g, aux={k: cut(v) for k, v in g.aux.items()}, extra={k: cut(v) for k, v in g.extra.items()}, **fields
    )
    return replace(sd, t=sd.t[sl], y=sd.y[sl], geom=geom, lines=sd.lines[sl])


@dataclass(frozen=True)
class BlockFrames:
    """Where the frames of one block come from.

    Attributes
    ----------
    epochs : (G,) epoch times; epoch 0 is the block start.
    sensors : per sensor: (name, frame indices (N,), epoch of each (N,), valid (N,)).
    frame_sensor, frame_index : (F,) sensor number and frame index of each row frame.
    """

    epochs: np.ndarray
    sensors: tuple
    frame_sensor: np.ndarray
    frame_index: np.ndarray


def block_epochs(problem: Problem, t_a: float, t_b: float, first: bool):
    """Epoch times of a block (its start, every frame time in the window, its end) and the
    frame window ``(lo, hi)`` of each sensor: ``(t_a, t_b]``, or ``[t_a, t_b]`` if ``first``."""
    windows, times = [], [np.array([t_a, t_b])]
    for sd in problem.sensors:
        lo = int(np.searchsorted(sd.t, t_a, side="left" if first else "right"))
        hi = int(np.searchsorted(sd.t, t_b, side="right"))
        windows.append((lo, hi))
        times.append(sd.t[lo:hi])
    return np.unique(np.concatenate(times)), windows


def assemble(
    problem: Problem,
    layout: Layout,
    values: Mapping[str, float],
    seg: GyroSegment | None,
    t_a: float,
    t_b: float,
    first: bool,
    pre_edited: Mapping[str, np.ndarray],
    sig_e2: float = 0.0,
) -> tuple[LinearBlock, BlockFrames]:
    """Linearize every sensor's frames in ``(t_a, t_b]`` (``[t_a, t_b]`` if ``first``) at the
    nominal and stack them as rows of a :class:`LinearBlock` in block-start coordinates."""
    epochs, windows = block_epochs(problem, t_a, t_b, first)
    sub = [sensor_window(sd, lo, hi) for sd, (lo, hi) in zip(problem.sensors, windows)]
    att = SegmentAttitude(seg) if seg is not None else problem.attitude
    prob = replace(problem, sensors=sub, attitude=att)
    lins = linearize(prob, values, layout.columns)
    if seg is not None:
        _, _, CC0, CE, Pi = seg.at(epochs)
        Psi_d = np.zeros((epochs.size, layout.d, layout.n))
        Psi_d[:, :3, :3] = CC0  # x_θ = C C_0ᵀ y_θ + C E y_g
        Psi_d[:, :3, layout.gyro_cols] = CE
        Psi_d[:, 3:, 3 : layout.d] = np.eye(layout.nb)
    else:
        Pi, Psi_d = np.zeros((epochs.size, 0, 0)), None
    n = layout.n
    parts: dict[str, list] = {"A": [], "r": [], "s": [], "h": [], "ep": [], "m": [], "sens": [], "idx": []}
    info = []
    for j, (sd, lin, (lo, hi)) in enumerate(zip(sub, lins, windows)):
        ep = np.searchsorted(epochs, sd.t)
        used = lin.valid.copy()
        edited = pre_edited.get(sd.name)
        if edited is not None:
            used &= ~np.asarray(edited[lo:hi], bool)
        info.append((sd.name, np.arange(lo, hi), ep, lin.valid))
        k = np.nonzero(used)[0]
        if k.size == 0:
            continue
        assert lin.H is not None  # linearize() stores the rows
        H = lin.H[k]
        mj = H.shape[1]
        A = H if Psi_d is None else H + H[:, :, :3] @ (Psi_d[ep[k], :3, :] - np.eye(3, n))  # A = H Ψ
        w = 1.0 / lin.sigma  # whiten: R = I
        parts["A"].append((A * w[None, :, None]).reshape(-1, n))
        parts["r"].append((lin.r[k] * w).reshape(-1))
        parts["s"].append(np.tile(lin.sigma, k.size))
        if sig_e2 > 0:
            parts["h"].append((H[:, :, :3] * w[None, :, None]).reshape(-1, 3))
        parts["ep"].append(ep[k])
        parts["m"].append(np.full(k.size, mj))
        parts["sens"].append(np.full(k.size, j))
        parts["idx"].append(lo + k)
    if not parts["ep"]:
        z = np.zeros(0, int)
        blk = LinearBlock(
            t=epochs,
            Pi=Pi,
            Psi_d=Psi_d,
            A=np.zeros((0, n)),
            r=np.zeros(0),
            sigma=np.zeros(0),
            row_epoch=z,
            frame_start=z,
            frame_m=z,
            frame_epoch=z,
        )
        return blk, BlockFrames(epochs, tuple(info), z, z)
    cat = {k: np.concatenate(v) for k, v in parts.items() if v}
    fe, fs, m = cat["ep"], cat["sens"], cat["m"]
    order = np.lexsort((fs, fe))  # frames by epoch, then sensor
    start_in = np.cumsum(m) - m  # row start before reordering
    m = m[order]
    start = np.cumsum(m) - m
    rows = np.repeat(start_in[order] - start, m) + np.arange(int(m.sum()))
    blk = LinearBlock(
        t=epochs,
        Pi=Pi,
        Psi_d=Psi_d,
        A=cat["A"][rows],
        r=cat["r"][rows],
        sigma=cat["s"][rows],
        row_epoch=np.repeat(fe[order], m),
        frame_start=start,
        frame_m=m,
        frame_epoch=fe[order],
        Hth=cat["h"][rows] if "h" in cat else None,
        sig_e2=sig_e2 if "h" in cat else 0.0,
    )
    return blk, BlockFrames(epochs, tuple(info), fs[order], cat["idx"][order])
