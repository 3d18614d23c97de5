"""Covariance-only Kalman recursion for a gyro-carried attitude (seed Eq 3-4, §4.2.7.2).

With process noise the attitude is a dynamic state and the predictor runs the filter's
covariance equations without data — "the state will be kept at its nominal values and
only the covariance matrix needs to be updated and propagated" (seed §3.2.2)::

    P⁻_i = Φ P_{i−1} Φᵀ + Γ Q Γᵀ                                                (Eq 3-4)
    K = P⁻ Hᵀ (H P⁻ Hᵀ + R)⁻¹,   P = (I − K H) P⁻ (I − K H)ᵀ + K R Kᵀ

The filter state is the body-frame attitude error ``δθ`` at the current time followed
by every other solve-for element (gyro and sensor parameters, constant). Between two
event times the gyro carries the error (first order, :mod:`gcs_core.problem.attitude`)::

    δθ_b = C_b C_aᵀ δθ_a + C_b (E_b − E_a) δp,      E(t) = C(t)ᵀ ∂δθ(t)/∂p

``E`` is read from the gyro attitude provider, so the transition is exactly the one the
batch estimator uses; with zero process noise the recursion reproduces the information
form (Eq 3-2) mapped to the current time. The process noise is the filter's:
Farrenkopf's gyro model from the data book (:func:`~gcs_core.models.gyro_noise.gyro_noise`
read as the filter reads it, :func:`~gcs_core.estimators.kalman.mekf.attitude_gyro_noise`) in
:func:`~gcs_core.models.gyro_noise.farrenkopf_q` with the filter's maps ``W_y = Mᵀ G⁻¹``,
``W_b = −Mᵀ``::

    Q_θθ = σ_v² Δt W_y W_yᵀ + σ_u² Δt³/3 I,   Q_θb = −Mᵀ σ_u² Δt²/2,   Q_bb = σ_u² Δt I

(``Q_θb`` and ``Q_bb`` on the solve-for gyro biases, which random-walk when σ_u > 0, as
in the filter's state). The electronic read-out noise σ_e does not accumulate: as in the
filter it is a white attitude error shared by the rows of one time, ``R = I + σ_e² H_θ
H_θᵀ`` on the whitened rows. The Joseph form keeps ``P`` symmetric and positive
under round-off. Consider elements are carried by their sensitivity ``S``
(``S ← Φ S + Φ_c`` on propagation, ``S ← S − K (H S + H_c)`` on update), whose
covariance contribution is ``S P_c Sᵀ`` (consider filter, Tapley et al. 2004 §6.3).

The ``att.roll/pitch/yaw`` σ reported are those of the *current* attitude, mapped from
``δθ`` by the inverse of Eq 4-22 at the nominal angles of each output time.

References
----------
Farrenkopf, R. L., "Analytic steady-state accuracy solutions for two common spacecraft
attitude estimators", J. Guidance & Control 1(4), 1978. Tapley, B. D., Schutz, B. E.,
Born, G. H., *Statistical Orbit Determination*, Elsevier 2004, §4.7 and §6.3.
"""

from __future__ import annotations

from collections.abc import Mapping, Sequence
from dataclasses import dataclass, field, replace

import numpy as np

from gcs_core.estimators.kalman.mekf import attitude_gyro_noise
from gcs_core.frames.rotations import dcm_to_euler123
from gcs_core.models import common
from gcs_core.models.gyro import G_NAMES, g_matrix
from gcs_core.models.gyro_noise import GyroNoise, farrenkopf_q
from gcs_core.predictor.information import weighted_rows
from gcs_core.problem.attitude import ERR, RPY, BodyErrorAttitude, rpy_error_jacobians
from gcs_core.problem.build import Problem
from gcs_core.problem.linearization import linearize

#: a-priori σ used in place of an infinite one (the covariance form needs a finite P)
BIG_SIGMA = 1e6


@dataclass(frozen=True)
class _EventRows:
    """The whitened measurement rows of every frame, grouped by event time.

    Attributes
    ----------
    t_ref : the gyro attitude's reference time [s]; events : (E,) sorted event times [s]
        (``t_ref``, every frame time and output time from ``t_ref`` on).
    blocks : (m, k) whitened rows of each frame; order : frame indices sorted by event;
    starts : (E+1,) the frames of event ``k`` are ``blocks[order[starts[k]:starts[k+1]]]``.
    """

    t_ref: float
    events: np.ndarray
    blocks: list[np.ndarray]
    order: np.ndarray
    starts: np.ndarray

    def rows_at(self, k: int) -> np.ndarray | None:
        """The rows of every frame at event ``k`` stacked, or None if it has none."""
        i0, i1 = self.starts[k], self.starts[k + 1]
        if i1 > i0:
            return np.concatenate([self.blocks[i] for i in self.order[i0:i1]], axis=0)
        return None


@dataclass(frozen=True)
class _Transition:
    """The gyro's attitude transition between events (module docstring).

    Attributes
    ----------
    C : (E, 3, 3) nominal ``C_BI`` at the events; E : (E, 3, p) ``E(t) = Cᵀ ∂δθ/∂p``.
    solve_cols, consider_cols : (j, column) pairs, column ``j`` of ``E`` into the filter
        state (solve-for) or into the consider sensitivity ``S``.
    """

    C: np.ndarray
    E: np.ndarray
    solve_cols: list[tuple[int, int]]
    consider_cols: list[tuple[int, int]]


@dataclass(frozen=True)
class _FilterNoise:
    """The filter's process and read-out noise (Farrenkopf's model, module docstring).

    Attributes
    ----------
    noise : the gyro's σ_v, σ_u, σ_e; axes : gyro axes whose solve-for bias random-walks.
    q_idx : filter-state rows of ``Q`` (δθ, then those biases).
    Wy, Wb : (3, 3) ``∂ω/∂y = Mᵀ G⁻¹`` and ``∂ω/∂b = −Mᵀ`` (Eq 4-32 inverted).
    sig_e2 : σ_e² [rad²].
    """

    noise: GyroNoise
    axes: list[int]
    q_idx: list[int]
    Wy: np.ndarray
    Wb: np.ndarray
    sig_e2: float


def _event_rows(
    problem: Problem, lins: list, times: np.ndarray, masks: Mapping[str, np.ndarray], k_all: int
) -> _EventRows:
    """Every frame's whitened rows at its event (frames before ``t_ref`` dropped)."""
    rows = [weighted_rows(lin, sd.t, masks.get(sd.name)) for lin, sd in zip(lins, problem.sensors)]
    t_ref = float(problem.gyro_attitude.t_ref)
    t_rows = np.concatenate([t for t, _ in rows] + [np.zeros(0)])
    events = np.unique(np.concatenate([[t_ref], t_rows[t_rows >= t_ref], times[times >= t_ref]]))
    frame_ev, frame_X = [], []
    for t, X in rows:
        keep = t >= t_ref
        frame_ev.append(np.searchsorted(events, t[keep]))
        frame_X.append(X[keep].reshape(-1, X.shape[1], k_all))
    ev_idx = np.concatenate(frame_ev) if frame_ev else np.zeros(0, int)
    order = np.argsort(ev_idx, kind="stable")
    blocks = [x for Xs in frame_X for x in Xs]
    starts = np.searchsorted(ev_idx[order], np.arange(events.size + 1))
    return _EventRows(t_ref, events, blocks, order, starts)


def _transition(ae, others: list[str], consider: Sequence[str]) -> _Transition:
    """Transition pieces from the attitude evaluated at the events."""
    C = ae.C_BI
    assert C is not None  # a three-axis attitude
    pnames = list(ae.names[3:])
    F = np.einsum("eji,ejp->eip", C, ae.J[:, :, 3:])  # E(t) = Cᵀ ∂δθ/∂p
    sf = [(j, 3 + others.index(p)) for j, p in enumerate(pnames) if p in others]
    cf = [(j, list(consider).index(p)) for j, p in enumerate(pnames) if p in consider]
    return _Transition(C, F, sf, cf)


def _filter_noise(
    problem: Problem, values: Mapping[str, float], others: list[str], noise: GyroNoise | None
) -> _FilterNoise:
    """The process noise the filter carries (:func:`~gcs_core.estimators.kalman.mekf.make_layout`)."""
    gyro = problem.attitude.gyro
    bias_names = [f"{gyro}.bias_{a}" for a in "xyz"]
    noise = attitude_gyro_noise(problem) if noise is None else noise
    # the filter's dynamic biases (mekf.make_layout): the solve-for ones, when σ_u > 0
    axes = [a for a, b in enumerate(bias_names) if b in others] if noise.sigma_u > 0 else []
    q_idx = [0, 1, 2] + [3 + others.index(bias_names[a]) for a in axes]
    p_gyro = {k: values.get(f"{gyro}.{k}", 0.0) for k in G_NAMES + common.ALIGN_NAMES}
    M, _ = common.alignment_matrix(p_gyro)
    Wy, Wb = M.T @ np.linalg.inv(g_matrix(p_gyro)), -M.T  # ∂ω/∂y, ∂ω/∂b (Eq 4-32 inverted)
    return _FilterNoise(noise, axes, q_idx, Wy, Wb, noise.sigma_e**2)


def _output_jacobians(problem: Problem, values: Mapping[str, float], times: np.ndarray, t_ref: float) -> np.ndarray:
    """(T, 3, 3) ``∂δθ/∂δ(roll, pitch, yaw)`` at the output times (inverse of Eq 4-22)."""
    att = problem.attitude
    A_out = problem.gyro_attitude.ref.reference(np.maximum(times, t_ref))
    C_out = att.evaluate(values, np.maximum(times, t_ref)).C_BI
    rpy_out = np.column_stack(dcm_to_euler123(C_out @ np.swapaxes(A_out, -1, -2)))
    return rpy_error_jacobians(rpy_out)


def _prior_covariance(values: Mapping[str, float], sigma0: np.ndarray, n: int) -> np.ndarray:
    """(n, n) a-priori covariance at ``t_ref``, δθ mapped from σ(roll, pitch, yaw)."""
    s0 = np.where(np.isfinite(sigma0), sigma0, BIG_SIGMA)
    J0 = rpy_error_jacobians(np.array([[values[nm] for nm in RPY]]))[0]
    P = np.zeros((n, n))
    P[:3, :3] = J0 @ np.diag(s0[:3] ** 2) @ J0.T
    P[3:, 3:] = np.diag(s0[3:] ** 2)
    return P


@dataclass
class _History:
    """The σ history being recorded, and the covariances at the last output time."""

    sigma: np.ndarray
    sigma_noise: np.ndarray
    attitude_sigma: np.ndarray
    Jr: np.ndarray
    sc: np.ndarray
    last: dict = field(default_factory=dict)

    def record(self, j: int, P: np.ndarray, S: np.ndarray) -> None:
        """σ at output ``j`` from the filter covariance ``P`` and consider sensitivity ``S``."""
        n = P.shape[0]
        sc = self.sc
        Tm = np.eye(n)
        Tm[:3, :3] = np.linalg.solve(self.Jr[j], np.eye(3))  # δrpy = Jr⁻¹ δθ
        Pz = Tm @ P @ Tm.T
        Sc = (Tm @ S) * sc[None, :]
        Ptot = Pz + Sc @ Sc.T
        self.sigma_noise[j] = np.sqrt(np.clip(np.diag(Pz), 0, None))
        self.sigma[j] = np.sqrt(np.clip(np.diag(Ptot), 0, None))
        Sb = S * sc[None, :]
        self.attitude_sigma[j] = np.sqrt(np.clip(np.diag(P[:3, :3] + Sb[:3] @ Sb[:3].T), 0, None))
        self.last.update(P=Pz, P_consider=Ptot, budget=np.abs(Sc).T)


def _propagate(P: np.ndarray, S: np.ndarray, k: int, dt: float, tr: _Transition, fn: _FilterNoise) -> None:
    """Eq 3-4 from event ``k − 1`` to ``k``, in place: ``P⁻ = Φ P Φᵀ + Q`` (only the δθ rows
    of Φ differ from I), ``S ← Φ S + Φ_c``."""
    n = P.shape[0]
    C = tr.C
    L = np.zeros((3, n))
    L[:, :3] = C[k] @ C[k - 1].T  # Φ_θθ = C_b C_aᵀ
    G = C[k] @ (tr.E[k] - tr.E[k - 1])  # Φ_θp = C_b (E_b − E_a)
    for jp, jz in tr.solve_cols:
        L[:, jz] += G[:, jp]
    top = L @ P
    P[:3, :] = top
    P[:, :3] = top.T
    P[:3, :3] = top @ L.T
    Sn = L @ S
    for jp, jc in tr.consider_cols:
        Sn[:, jc] += G[:, jp]
    S[:3, :] = Sn
    P[np.ix_(fn.q_idx, fn.q_idx)] += farrenkopf_q(np.array([dt]), fn.noise, fn.Wy, fn.Wb, fn.axes)[0]


def _update(P: np.ndarray, S: np.ndarray, Y: np.ndarray, sig_e2: float) -> tuple[np.ndarray, np.ndarray]:
    """Kalman update with the whitened rows ``Y = [H, H_c]`` of one event (Joseph form);
    the new ``P`` and ``S``."""
    n = P.shape[0]
    Hx, Hc = Y[:, :n], Y[:, n:]
    PHt = P @ Hx.T
    R = np.eye(Y.shape[0])  # whitened rows
    if sig_e2 > 0:  # + σ_e² H_θ H_θᵀ (read-out)
        R += sig_e2 * (Hx[:, :3] @ Hx[:, :3].T)
    Sinn = Hx @ PHt + R  # S = H P Hᵀ + R
    K = np.linalg.solve(Sinn, PHt.T).T  # K = P Hᵀ S⁻¹ (S symmetric)
    IKH = np.eye(n) - K @ Hx
    P = IKH @ P @ IKH.T + K @ R @ K.T  # Joseph form
    P = 0.5 * (P + P.T)
    S = S - K @ (Hx @ S + Hc)
    return P, S


def kalman_history(
    problem: Problem,
    values: Mapping[str, float],
    names: Sequence[str],
    consider: Sequence[str],
    sigma0: np.ndarray,
    sigma_c: np.ndarray,
    times: np.ndarray,
    *,
    masks: Mapping[str, np.ndarray] | None = None,
    noise: GyroNoise | None = None,
) -> dict:
    """σ history of the covariance-only filter (module docstring; Eq 3-4).

    Parameters
    ----------
    problem : a Problem whose attitude is a :class:`~gcs_core.problem.gyro_attitude.GyroAttitude`.
    values : nominal element values.
    names : solve-for elements (``att.roll/pitch/yaw`` first); consider : consider elements.
    sigma0 : (n,) a-priori σ of ``names``; sigma_c : (c,) of ``consider``.
    times : (T,) output times.
    masks : sensor -> (N,) frames to use.
    noise : the gyro's noise (None: the data book's, as the filter reads it).

    Returns
    -------
    dict like :func:`gcs_core.predictor.information.static_history`.
    """
    att = problem.attitude
    names = list(names)
    others = [nm for nm in names if nm not in RPY]
    n, c = 3 + len(others), len(consider)
    err_problem = replace(problem, attitude=BodyErrorAttitude(att, values))
    lins = linearize(err_problem, values, list(ERR) + others + list(consider))
    ev = _event_rows(problem, lins, times, masks or {}, n + c)
    events, t_ref = ev.events, ev.t_ref
    tr = _transition(att.evaluate(values, events), others, consider)
    fn = _filter_noise(problem, values, others, noise)
    T = times.size
    hist = _History(
        np.zeros((T, n)),
        np.zeros((T, n)),
        np.zeros((T, 3)),
        _output_jacobians(problem, values, times, t_ref),
        np.asarray(sigma_c, dtype=float),
    )
    P = _prior_covariance(values, sigma0, n)
    S = np.zeros((n, c))
    out_at: dict[int, list[int]] = {int(e): [] for e in np.searchsorted(events, times[times >= t_ref])}
    for j in np.flatnonzero(times >= t_ref):
        out_at[int(np.searchsorted(events, times[j]))].append(int(j))
    for j in np.flatnonzero(times < t_ref):
        hist.record(int(j), P, S)
    for k in range(events.size):
        if k > 0:
            _propagate(P, S, k, events[k] - events[k - 1], tr, fn)
        Y = ev.rows_at(k)
        if Y is not None:
            P, S = _update(P, S, Y, fn.sig_e2)
        for jo in out_at.get(k, ()):
            hist.record(jo, P, S)
    return {
        "sigma": hist.sigma,
        "sigma_noise": hist.sigma_noise,
        "attitude_sigma": hist.attitude_sigma,
        "P": hist.last["P"],
        "P_consider": hist.last["P_consider"],
        "budget": hist.last["budget"],
        "unobservable": np.zeros(n, dtype=bool),
    }
