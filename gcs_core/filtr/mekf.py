"""Filter blocks from a calibration :class:`~gcs_core.filtr.problem.Problem` (FILTR, seed §3.2.2).

Two kinds of problem, one block format (:class:`~gcs_core.filtr.kalman.LinearBlock`):

* **With a gyro** (``problem.gyro_name`` set, ``problem.attitude`` a GyroAttitude): the
  multiplicative EKF. The filter state is laid out ``(δθ, b, s)`` (:class:`Layout`): the
  three ``att.roll/pitch/yaw`` elements are *reinterpreted* as the body attitude-error
  angles δθ of the current time (columns ``kf.dtheta_x/y/z``), ``b`` are the gyro biases
  that random-walk (``rrw > 0``), ``s`` every other solve-for element (static). Each block
  propagates a nominal attitude with the gyro-corrected rates (Eq 4-32 inverted,
  Eq 4-38) from the block-start attitude, evaluates every sensor's predictions and
  partials *vectorized* over the block at that nominal (through :func:`linearize`, the
  nominal attitude being its attitude provider), and hands the rows ``A = H Ψ(t)`` to
  the core, which then does exact frame-by-frame linear updates with the accumulated
  error state. The next block re-linearizes at the updated estimate (the reset).
* **Without a gyro** (reference-pointing or spinning): the state is the solve-for
  elements themselves, static (Q = 0): recursive least squares over blocks.

Both use the residual ``r = y − h(nominal)`` as the measurement of the error state.
"""

from __future__ import annotations

from dataclasses import dataclass, replace
from typing import Mapping

import numpy as np

from gcs_core.errors import EstimationError
from gcs_core.filtr.attitude import BIAS_RATE_NAMES, RPY, AttitudeEval
from gcs_core.filtr.kalman import GyroNoise, GyroSegment, LinearBlock
from gcs_core.filtr.problem import Problem, linearize
from gcs_core.models import common as model_common
from gcs_core.models.gyro import G_NAMES, g_matrix
from gcs_core.sidp.prepare import SensorData

#: filter columns of the attitude error δθ (body axes, rad).
DTH = ("kf.dtheta_x", "kf.dtheta_y", "kf.dtheta_z")


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


def gyro_noise(problem: Problem, scale: float = 1.0) -> GyroNoise:
    """σ_v, σ_u, σ_e of the gyro carrying the attitude (ICD §5 ``arw``, ``rrw``, ``electronic``).

    Without ``arw`` the gyro's ``noise`` (a rate 1-sigma per sample) is taken as
    ``σ_v = noise·sqrt(Δt)`` with Δt the median sample interval.
    """
    spec = problem.builder.spec.sensor(problem.gyro_name)
    arw = model_common.book_scalar(spec, "arw")
    if arw is None:
        dt = float(np.median(problem.attitude.dt))
        arw = float(spec.noise or 0.0) * np.sqrt(dt)
    rrw = model_common.book_scalar(spec, "rrw", 0.0) or 0.0
    ele = model_common.book_scalar(spec, "electronic", 0.0) or 0.0
    return GyroNoise(scale * float(arw), scale * float(rrw), scale * float(ele))


def make_layout(problem: Problem, noise: GyroNoise | None) -> Layout:
    """The filter state of ``problem`` (see :class:`Layout`)."""
    solve = list(problem.state.solve_for)
    if problem.gyro_name is None:
        return Layout(tuple(solve), tuple(solve), 0, 0, np.zeros(0, int), np.zeros(0, int),
                      np.zeros(0, int))
    missing = [n for n in RPY if n not in solve]
    if missing:
        raise EstimationError("the Kalman filter estimates the attitude with the gyros: make "
                              + ", ".join(missing) + " solve-for")
    pnames = list(problem.attitude.param_names)
    bias = [f"{problem.gyro_name}.bias_{a}" for a in "xyz"]
    dyn = [b for b in bias if b in solve] if noise is not None and noise.sigma_u > 0 else []
    static = [n for n in solve if n not in RPY and n not in dyn]
    elements = tuple(RPY) + tuple(dyn) + tuple(static)
    columns = DTH + tuple(dyn) + tuple(static)
    gyro = [n for n in elements[3:] if n in pnames]
    cols = np.array([elements.index(n) for n in gyro], int)
    d = 3 + len(dyn)
    gs = np.array([c - d for c in cols if c >= d], int)
    return Layout(columns, elements, d, len(dyn), cols,
                  np.array([pnames.index(n) for n in gyro], int), gs)


#: gyro parameters in the order of ``GyroAttitude.param_names`` that :func:`gyro_rates` knows.
_KNOWN_GYRO = G_NAMES + ("bias_x", "bias_y", "bias_z") + model_common.ALIGN_NAMES + BIAS_RATE_NAMES


def gyro_rates(att, values: Mapping[str, float], k0: int, k1: int):
    """Corrected rates of gyro rows ``k0..k1−1`` and their partials (Eq 4-32 inverted).

    ``ω = Mᵀ (G⁻¹ y − b − ḃ τ)`` (τ: time from the middle of the span; ḃ the optional bias
    rate); returns ω (K, 3), ``∂ω/∂p`` (K, 3, P) over ``att.param_names``, ``W_y = Mᵀ G⁻¹``
    and ``W_b = −Mᵀ``. These are the expressions of
    :class:`~gcs_core.filtr.attitude.GyroAttitude` restricted to a window of rows; if the
    provider has parameters this function does not know, its own (whole-span) rates are
    sliced instead.
    """
    names = tuple(n.split(".", 1)[1] for n in att.param_names)
    p = {n: values.get(f"{att.gyro}.{n}", 0.0) for n in _KNOWN_GYRO}
    G = g_matrix(p)
    Ginv = np.linalg.inv(G)
    M, dM = model_common.alignment_matrix(p)
    if names != _KNOWN_GYRO[:len(names)]:
        omega, W = att._rates(values)
        return omega[k0:k1], W[k0:k1], M.T @ Ginv, -M.T
    b = np.array([p["bias_x"], p["bias_y"], p["bias_z"]])
    bdot = np.array([p[n] for n in BIAS_RATE_NAMES])
    tau = att.knots[k0 + 1:k1 + 1] - 0.5 * (att.knots[0] + att.knots[-1])
    y = att.y[k0:k1]
    Gy = y @ Ginv.T                                           # G⁻¹ y
    u = Gy - b - tau[:, None] * bdot
    omega = u @ M                                             # Mᵀ (G⁻¹ y − b − ḃ τ)
    MtGinv = M.T @ Ginv
    W = np.empty((y.shape[0], 3, len(_KNOWN_GYRO)))
    for a in range(3):
        for c in range(3):
            W[:, :, 3 * a + c] = -MtGinv[:, a][None, :] * Gy[:, c:c + 1]   # ∂ω/∂G_ac
    W[:, :, 9:12] = -M.T[None, :, :]
    for k in range(3):
        W[:, :, 12 + k] = u @ dM[k]
    W[:, :, 15:18] = -M.T[None, :, :] * tau[:, None, None]
    return omega, W[:, :, :len(names)], MtGinv, -M.T


class NominalAttitude:
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
    fields = {f: cut(getattr(g, f)) for f in ("t", "C_BI", "spin_axis_I", "r_I", "v_I", "sun_I",
                                              "B_I", "star_I", "omega_B")}
    geom = replace(g, aux={k: cut(v) for k, v in g.aux.items()},
                   extra={k: cut(v) for k, v in g.extra.items()}, **fields)
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


def assemble(problem: Problem, layout: Layout, values: Mapping[str, float], seg: GyroSegment | None,
             t_a: float, t_b: float, first: bool, pre_edited: Mapping[str, np.ndarray],
             sig_e2: float = 0.0) -> tuple[LinearBlock, BlockFrames]:
    """Linearize every sensor's frames in ``(t_a, t_b]`` (``[t_a, t_b]`` if ``first``) at the
    nominal and stack them as rows of a :class:`LinearBlock` in block-start coordinates."""
    epochs, windows = block_epochs(problem, t_a, t_b, first)
    sub = [sensor_window(sd, lo, hi) for sd, (lo, hi) in zip(problem.sensors, windows)]
    att = NominalAttitude(seg) if seg is not None else problem.attitude
    prob = replace(problem, sensors=sub, attitude=att)
    lins = linearize(prob, values, layout.columns)
    if seg is not None:
        _, _, CC0, CE, Pi = seg.at(epochs)
        Psi_d = np.zeros((epochs.size, layout.d, layout.n))
        Psi_d[:, :3, :3] = CC0                                # x_θ = C C_0ᵀ y_θ + C E y_g
        Psi_d[:, :3, layout.gyro_cols] = CE
        Psi_d[:, 3:, 3:layout.d] = np.eye(layout.nb)
    else:
        Pi, Psi_d = np.zeros((epochs.size, 0, 0)), None
    n = layout.n
    parts: dict[str, list] = {"A": [], "r": [], "s": [], "h": [], "ep": [], "m": [], "sens": [],
                              "idx": []}
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
        H = lin.H[k]
        mj = H.shape[1]
        A = H if seg is None else H + H[:, :, :3] @ (Psi_d[ep[k], :3, :] - np.eye(3, n))  # A = H Ψ
        w = 1.0 / lin.sigma                                   # whiten: R = I
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
        blk = LinearBlock(t=epochs, Pi=Pi, Psi_d=Psi_d, A=np.zeros((0, n)), r=np.zeros(0),
                          sigma=np.zeros(0), row_epoch=z, frame_start=z, frame_m=z, frame_epoch=z)
        return blk, BlockFrames(epochs, tuple(info), z, z)
    cat = {k: np.concatenate(v) for k, v in parts.items() if v}
    fe, fs, m = cat["ep"], cat["sens"], cat["m"]
    order = np.lexsort((fs, fe))                              # frames by epoch, then sensor
    start_in = np.cumsum(m) - m                               # row start before reordering
    m = m[order]
    start = np.cumsum(m) - m
    rows = np.repeat(start_in[order] - start, m) + np.arange(int(m.sum()))
    blk = LinearBlock(t=epochs, Pi=Pi, Psi_d=Psi_d, A=cat["A"][rows], r=cat["r"][rows],
                      sigma=cat["s"][rows], row_epoch=np.repeat(fe[order], m), frame_start=start,
                      frame_m=m, frame_epoch=fe[order],
                      Hth=cat["h"][rows] if "h" in cat else None,
                      sig_e2=sig_e2 if "h" in cat else 0.0)
    return blk, BlockFrames(epochs, tuple(info), fs[order], cat["idx"][order])
