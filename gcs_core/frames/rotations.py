"""Rotations, Euler angles and quaternions (seed §4.1.2, ICD §2).

All functions broadcast over leading axes: an angle array of shape ``(N,)`` gives
matrices of shape ``(N, 3, 3)``; a quaternion array ``(N, 4)`` is ``(q1, q2, q3, q4)``
with ``q4`` the scalar part. Matrices map GCI to body (``v_B = C v_I``) unless a name
says otherwise.

References
----------
Wertz, J. R. (ed.), *Spacecraft Attitude Determination and Control*, Reidel 1978,
§12.1 and Appendix E (quaternions, Euler 1-2-3).
Shepperd, S. W., "Quaternion from rotation matrix", J. Guidance & Control 1(3), 1978
(the numerically robust branch choice used in :func:`quat_from_dcm`).
"""

from __future__ import annotations

import numpy as np

__all__ = [
    "T1",
    "T2",
    "T3",
    "skew",
    "euler123_to_dcm",
    "dcm_to_euler123",
    "euler123_partials",
    "quat_to_dcm",
    "quat_from_dcm",
    "quat_multiply",
    "quat_conjugate",
    "quat_normalize",
    "quat_to_euler123",
    "small_rotation",
    "rotvec_to_dcm",
    "dcm_to_rotvec",
    "orthonormalize",
]


def _cs(a):
    a = np.asarray(a, dtype=float)
    return np.cos(a), np.sin(a)


def T1(a):
    """Rotation about x by ``a`` (Eq 4-4): ``[[1,0,0],[0,c,s],[0,-s,c]]``. Shape ``a.shape + (3, 3)``."""
    c, s = _cs(a)
    o, z = np.ones_like(c), np.zeros_like(c)
    return np.stack([np.stack([o, z, z], -1), np.stack([z, c, s], -1), np.stack([z, -s, c], -1)], -2)


def T2(a):
    """Rotation about y by ``a`` (Eq 4-4): ``[[c,0,-s],[0,1,0],[s,0,c]]``."""
    c, s = _cs(a)
    o, z = np.ones_like(c), np.zeros_like(c)
    return np.stack([np.stack([c, z, -s], -1), np.stack([z, o, z], -1), np.stack([s, z, c], -1)], -2)


def T3(a):
    """Rotation about z by ``a`` (Eq 4-4): ``[[c,s,0],[-s,c,0],[0,0,1]]``."""
    c, s = _cs(a)
    o, z = np.ones_like(c), np.zeros_like(c)
    return np.stack([np.stack([c, s, z], -1), np.stack([-s, c, z], -1), np.stack([z, z, o], -1)], -2)


def skew(v):
    """Cross-product matrix ``[v x]`` so that ``skew(v) @ u == cross(v, u)``. ``(..., 3) -> (..., 3, 3)``."""
    v = np.asarray(v, dtype=float)
    x, y, z = v[..., 0], v[..., 1], v[..., 2]
    zero = np.zeros_like(x)
    return np.stack([np.stack([zero, -z, y], -1), np.stack([z, zero, -x], -1), np.stack([-y, x, zero], -1)], -2)


def euler123_to_dcm(roll, pitch, yaw):
    """Eq 4-4: ``[B] = T3(yaw) T2(pitch) T1(roll)``, reference-to-body."""
    return T3(yaw) @ T2(pitch) @ T1(roll)


def dcm_to_euler123(B):
    """Eq 4-5: roll, pitch, yaw from ``[B] = T3(ψ) T2(θ) T1(φ)``.

    ``φ = atan2(−B32, B33)``, ``θ = asin(B31)`` (computed as ``atan2(B31, hypot(B11, B21))``),
    ``ψ = atan2(−B21, B11)``. Roll and yaw
    come back in ``(−π, π]`` (the seed's ``[0, 2π)`` is the same angle), pitch in
    ``[−π/2, π/2]``. At gimbal lock (``|θ| = π/2``) roll is set to zero and yaw
    carries the whole rotation about the common axis: ``ψ = atan2(B12, B22)``.
    """
    B = np.asarray(B, dtype=float)
    cos_t = np.hypot(B[..., 0, 0], B[..., 1, 0])
    # atan2 rather than Eq 4-5's asin(B31): asin loses ~1e-8 rad within 1e-8 of ±90°
    pitch = np.arctan2(B[..., 2, 0], cos_t)
    singular = cos_t < 1e-12
    roll = np.where(singular, 0.0, np.arctan2(-B[..., 2, 1], B[..., 2, 2]))
    yaw = np.where(singular, np.arctan2(B[..., 0, 1], B[..., 1, 1]), np.arctan2(-B[..., 1, 0], B[..., 0, 0]))
    return roll, pitch, yaw


def euler123_partials(roll, pitch, yaw):
    """Eq 4-21/4-22: ``∂[B]/∂φ, ∂[B]/∂θ, ∂[B]/∂ψ`` for ``[B] = T3(ψ) T2(θ) T1(φ)``.

    Returns an array of shape ``(..., 3, 3, 3)``, the first of the last three axes
    indexing (roll, pitch, yaw).
    """
    R1, R2, R3 = T1(roll), T2(pitch), T3(yaw)
    c1, s1 = _cs(roll)
    c2, s2 = _cs(pitch)
    c3, s3 = _cs(yaw)
    z = np.zeros_like(c1)
    dR1 = np.stack([np.stack([z, z, z], -1), np.stack([z, -s1, c1], -1), np.stack([z, -c1, -s1], -1)], -2)
    dR2 = np.stack([np.stack([-s2, z, -c2], -1), np.stack([z, z, z], -1), np.stack([c2, z, -s2], -1)], -2)
    dR3 = np.stack([np.stack([-s3, c3, z], -1), np.stack([-c3, -s3, z], -1), np.stack([z, z, z], -1)], -2)
    return np.stack([R3 @ R2 @ dR1, R3 @ dR2 @ R1, dR3 @ R2 @ R1], -3)


def quat_normalize(q):
    """Unit quaternion with non-negative scalar part (the sign convention GCS stores)."""
    q = np.asarray(q, dtype=float)
    n = np.linalg.norm(q, axis=-1, keepdims=True)
    with np.errstate(invalid="ignore", divide="ignore"):  # a missing (NaN or zero) sample stays NaN
        q = q / n
    return np.where(q[..., 3:4] < 0.0, -q, q)


def quat_to_dcm(q):
    """Eq 4-8 (ICD §2): ``C(q) = (q4² − |e|²) I + 2 e eᵀ − 2 q4 [e×]``."""
    q = np.asarray(q, dtype=float)
    e, q4 = q[..., :3], q[..., 3]
    ee = np.einsum("...i,...j->...ij", e, e)
    eye = np.broadcast_to(np.eye(3), ee.shape)
    s = (q4**2 - np.sum(e * e, axis=-1))[..., None, None]
    return s * eye + 2.0 * ee - 2.0 * q4[..., None, None] * skew(e)


def quat_from_dcm(C):
    """Eq 4-9, made robust (Shepperd 1978): pick the largest of 4q4², 4q1², 4q2², 4q3².

    Eq 4-9 divides by ``4 q4`` and loses precision as ``q4 → 0`` (180° rotations);
    choosing the branch with the largest diagonal combination keeps the divisor at
    least 1/2. Returns unit quaternions with ``q4 ≥ 0``.
    """
    C = np.asarray(C, dtype=float)
    c11, c22, c33 = C[..., 0, 0], C[..., 1, 1], C[..., 2, 2]
    tr = c11 + c22 + c33
    cand = np.stack([1 + 2 * c11 - tr, 1 + 2 * c22 - tr, 1 + 2 * c33 - tr, 1 + tr], -1)  # 4 q_i^2
    k = np.argmax(cand, axis=-1)
    d12 = C[..., 0, 1] + C[..., 1, 0]
    d13 = C[..., 0, 2] + C[..., 2, 0]
    d23 = C[..., 1, 2] + C[..., 2, 1]
    m23 = C[..., 1, 2] - C[..., 2, 1]
    m31 = C[..., 2, 0] - C[..., 0, 2]
    m12 = C[..., 0, 1] - C[..., 1, 0]
    # Each branch: the vector 4*q_k*q (Eq 4-9 generalized; C(q) = ... - 2 q4 [e x]).
    b0 = np.stack([cand[..., 0], d12, d13, m23], -1)
    b1 = np.stack([d12, cand[..., 1], d23, m31], -1)
    b2 = np.stack([d13, d23, cand[..., 2], m12], -1)
    b3 = np.stack([m23, m31, m12, cand[..., 3]], -1)
    branches = np.stack([b0, b1, b2, b3], -2)
    v = np.take_along_axis(branches, k[..., None, None], axis=-2)[..., 0, :]
    return quat_normalize(v)


def quat_multiply(qp, q):
    """Eq 4-10: the quaternion ``q'' = q q'`` with ``C(q'') = C(q') C(q)``.

    The argument order follows the composition of matrices: ``quat_multiply(qp, q)``
    returns the quaternion of ``C(qp) @ C(q)`` (apply ``q`` first, then ``qp``).
    """
    qp = np.asarray(qp, dtype=float)
    q = np.asarray(q, dtype=float)
    a1, a2, a3, a4 = np.moveaxis(qp, -1, 0)
    b1, b2, b3, b4 = np.moveaxis(q, -1, 0)
    # Eq 4-10b: q'' = [[q4', q3', -q2', q1'], [-q3', q4', q1', q2'],
    #                  [q2', -q1', q4', q3'], [-q1', -q2', -q3', q4']] q
    return np.stack(
        [
            a4 * b1 + a3 * b2 - a2 * b3 + a1 * b4,
            -a3 * b1 + a4 * b2 + a1 * b3 + a2 * b4,
            a2 * b1 - a1 * b2 + a4 * b3 + a3 * b4,
            -a1 * b1 - a2 * b2 - a3 * b3 + a4 * b4,
        ],
        -1,
    )


def quat_conjugate(q):
    """``q* = (−e, q4)``, the inverse rotation (Eq 4-33a)."""
    q = np.asarray(q, dtype=float)
    return np.concatenate([-q[..., :3], q[..., 3:]], -1)


def quat_to_euler123(q):
    """Eq 4-11: roll, pitch, yaw straight from the quaternion of ``T3 T2 T1``."""
    return dcm_to_euler123(quat_to_dcm(q))


def rotvec_to_dcm(phi):
    """Rotation by the vector ``φ`` (axis × angle) as a frame rotation: ``exp(−[φ×])``.

    With GCS's error convention ``C_true = (I − [δθ×]) C_nominal`` to first order,
    ``rotvec_to_dcm(δθ) @ C_nominal`` is the exact version of that update.
    """
    phi = np.asarray(phi, dtype=float)
    ang = np.linalg.norm(phi, axis=-1)[..., None, None]
    K = skew(phi)
    small = ang < 1e-8
    safe = np.where(small, 1.0, ang)
    a = np.where(small, 1.0 - ang**2 / 6.0, np.sin(safe) / safe)
    b = np.where(small, 0.5 - ang**2 / 24.0, (1.0 - np.cos(safe)) / safe**2)
    eye = np.broadcast_to(np.eye(3), K.shape)
    return eye - a * K + b * (K @ K)


def dcm_to_rotvec(C):
    """Inverse of :func:`rotvec_to_dcm`: the vector ``φ`` with ``exp(−[φ×]) = C``."""
    q = quat_from_dcm(C)
    e, q4 = q[..., :3], q[..., 3]
    s = np.linalg.norm(e, axis=-1)
    ang = 2.0 * np.arctan2(s, q4)
    small = s < 1e-12
    scale = np.where(small, 2.0, ang / np.where(small, 1.0, s))
    return e * scale[..., None]


def small_rotation(dtheta):
    """First-order frame rotation ``I − [δθ×]`` (the multiplicative attitude error)."""
    dtheta = np.asarray(dtheta, dtype=float)
    return np.broadcast_to(np.eye(3), dtheta.shape[:-1] + (3, 3)) - skew(dtheta)


def orthonormalize(C):
    """Nearest rotation matrix (polar decomposition by SVD); guards accumulated round-off."""
    U, _, Vt = np.linalg.svd(np.asarray(C, dtype=float))
    R = U @ Vt
    det = np.linalg.det(R)
    U[..., :, 2] *= np.sign(det)[..., None]
    return U @ Vt
