"""Quaternion products along the gyro knots (fast forms of the Eq 4-8/4-10 products), moved
out of :mod:`gcs_core.problem.gyro_attitude` unchanged: the DCM of a quaternion entry by
entry, the cumulative composition of the step rotations (a blocked scan) and the step
quaternions of Eq 4-38.
"""

from __future__ import annotations

import numpy as np

from gcs_core.frames.rotations import quat_multiply, quat_normalize


# ----------------------------------------------------------------------------------------
def fast_dcm(q) -> np.ndarray:
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


def scan_products(q, group: int = 8) -> np.ndarray:
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
    before = scan_products(np.ascontiguousarray(Q[:-1, -1]), group)  # product of groups < b
    Q[1:] = quat_multiply(Q[1:], before[:, None, :])
    return Q.reshape(-1, 4)[:n]


def quat_scan(q):
    """Cumulative composition ``Q_k = q_k ⊗ … ⊗ q_0``, normalized (see :func:`scan_products`)."""
    return quat_normalize(scan_products(np.asarray(q, dtype=float)))


def step_quaternions(omega, dt):
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
