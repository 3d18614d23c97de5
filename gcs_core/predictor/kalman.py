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
from dataclasses import replace

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
    """σ history of the covariance-only filter (module docstring).

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
    masks = masks or {}
    names = list(names)
    others = [nm for nm in names if nm not in RPY]
    n, c = 3 + len(others), len(consider)
    k_all = n + c
    err_problem = replace(problem, attitude=BodyErrorAttitude(att, values))
    lins = linearize(err_problem, values, list(ERR) + others + list(consider))
    rows = [weighted_rows(lin, sd.t, masks.get(sd.name)) for lin, sd in zip(lins, problem.sensors)]

    t_ref = float(problem.gyro_attitude.t_ref)
    t_rows = np.concatenate([t for t, _ in rows] + [np.zeros(0)])
    events = np.unique(np.concatenate([[t_ref], t_rows[t_rows >= t_ref], times[times >= t_ref]]))

    # every frame row at its event, as (row-block per frame) lists
    frame_ev, frame_X = [], []
    for t, X in rows:
        keep = t >= t_ref
        frame_ev.append(np.searchsorted(events, t[keep]))
        frame_X.append(X[keep].reshape(-1, X.shape[1], k_all))
    ev_idx = np.concatenate(frame_ev) if frame_ev else np.zeros(0, int)
    order = np.argsort(ev_idx, kind="stable")
    all_X = [x for Xs in frame_X for x in Xs]
    starts = np.searchsorted(ev_idx[order], np.arange(events.size + 1))

    # attitude transition pieces at the events
    ae = att.evaluate(values, events)
    C = ae.C_BI
    assert C is not None  # a three-axis attitude
    pnames = list(ae.names[3:])
    F = np.einsum("eji,ejp->eip", C, ae.J[:, :, 3:])  # E(t) = Cᵀ ∂δθ/∂p
    sf = [(j, 3 + others.index(p)) for j, p in enumerate(pnames) if p in others]
    cf = [(j, list(consider).index(p)) for j, p in enumerate(pnames) if p in consider]
    gyro = att.gyro
    bias_names = [f"{gyro}.bias_{a}" for a in "xyz"]
    noise = attitude_gyro_noise(problem) if noise is None else noise
    # the filter's dynamic biases (mekf.make_layout): the solve-for ones, when σ_u > 0
    axes = [a for a, b in enumerate(bias_names) if b in others] if noise.sigma_u > 0 else []
    q_idx = [0, 1, 2] + [3 + others.index(bias_names[a]) for a in axes]
    p_gyro = {k: values.get(f"{gyro}.{k}", 0.0) for k in G_NAMES + common.ALIGN_NAMES}
    M, _ = common.alignment_matrix(p_gyro)
    Wy, Wb = M.T @ np.linalg.inv(g_matrix(p_gyro)), -M.T  # ∂ω/∂y, ∂ω/∂b (Eq 4-32 inverted)
    sig_e2 = noise.sigma_e**2

    # output-time mapping δθ -> δ(roll, pitch, yaw)
    A_out = problem.gyro_attitude.ref.reference(np.maximum(times, t_ref))
    C_out = att.evaluate(values, np.maximum(times, t_ref)).C_BI
    rpy_out = np.column_stack(dcm_to_euler123(C_out @ np.swapaxes(A_out, -1, -2)))
    Jr = rpy_error_jacobians(rpy_out)

    # a-priori covariance at t_ref
    s0 = np.where(np.isfinite(sigma0), sigma0, BIG_SIGMA)
    J0 = rpy_error_jacobians(np.array([[values[nm] for nm in RPY]]))[0]
    P = np.zeros((n, n))
    P[:3, :3] = J0 @ np.diag(s0[:3] ** 2) @ J0.T
    P[3:, 3:] = np.diag(s0[3:] ** 2)
    S = np.zeros((n, c))
    sc = np.asarray(sigma_c, dtype=float)

    T = times.size
    out = {"sigma": np.zeros((T, n)), "sigma_noise": np.zeros((T, n)), "attitude_sigma": np.zeros((T, 3))}
    out_at: dict[int, list[int]] = {int(e): [] for e in np.searchsorted(events, times[times >= t_ref])}
    for j in np.flatnonzero(times >= t_ref):
        out_at[int(np.searchsorted(events, times[j]))].append(int(j))
    last: dict = {}

    def record(j):
        Tm = np.eye(n)
        Tm[:3, :3] = np.linalg.solve(Jr[j], np.eye(3))  # δrpy = Jr⁻¹ δθ
        Pz = Tm @ P @ Tm.T
        Sc = (Tm @ S) * sc[None, :]
        Ptot = Pz + Sc @ Sc.T
        out["sigma_noise"][j] = np.sqrt(np.clip(np.diag(Pz), 0, None))
        out["sigma"][j] = np.sqrt(np.clip(np.diag(Ptot), 0, None))
        Sb = S * sc[None, :]
        out["attitude_sigma"][j] = np.sqrt(np.clip(np.diag(P[:3, :3] + Sb[:3] @ Sb[:3].T), 0, None))
        last.update(P=Pz, P_consider=Ptot, budget=np.abs(Sc).T)

    for j in np.flatnonzero(times < t_ref):
        record(j)
    eye_n = np.eye(n)
    for k in range(events.size):
        if k > 0:
            # propagation, Eq 3-4: P⁻ = Φ P Φᵀ + Q (only the δθ rows of Φ differ from I)
            dt = events[k] - events[k - 1]
            L = np.zeros((3, n))
            L[:, :3] = C[k] @ C[k - 1].T  # Φ_θθ = C_b C_aᵀ
            G = C[k] @ (F[k] - F[k - 1])  # Φ_θp = C_b (E_b − E_a)
            for jp, jz in sf:
                L[:, jz] += G[:, jp]
            top = L @ P
            P[:3, :] = top
            P[:, :3] = top.T
            P[:3, :3] = top @ L.T
            Sn = L @ S
            for jp, jc in cf:
                Sn[:, jc] += G[:, jp]
            S[:3, :] = Sn
            P[np.ix_(q_idx, q_idx)] += farrenkopf_q(np.array([dt]), noise, Wy, Wb, axes)[0]
        i0, i1 = starts[k], starts[k + 1]
        if i1 > i0:
            Y = np.concatenate([all_X[i] for i in order[i0:i1]], axis=0)
            Hx, Hc = Y[:, :n], Y[:, n:]
            PHt = P @ Hx.T
            R = np.eye(Y.shape[0])  # whitened rows
            if sig_e2 > 0:  # + σ_e² H_θ H_θᵀ (read-out)
                R += sig_e2 * (Hx[:, :3] @ Hx[:, :3].T)
            Sinn = Hx @ PHt + R  # S = H P Hᵀ + R
            K = np.linalg.solve(Sinn, PHt.T).T  # K = P Hᵀ S⁻¹ (S symmetric)
            IKH = eye_n - K @ Hx
            P = IKH @ P @ IKH.T + K @ R @ K.T  # Joseph form
            P = 0.5 * (P + P.T)
            S = S - K @ (Hx @ S + Hc)
        for jo in out_at.get(k, ()):
            record(jo)
    return {
        **out,
        "P": last["P"],
        "P_consider": last["P_consider"],
        "budget": last["budget"],
        "unobservable": np.zeros(n, dtype=bool),
    }
