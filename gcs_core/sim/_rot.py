"""Rotation helpers private to the truth simulator (ICD §2, seed Eq 4-4, 4-8, 4-33).

The simulator deliberately does not import :mod:`gcs_core.frames.rotations`: a bug
shared by the estimator and the simulator would cancel out and hide. The
quaternion <-> matrix conversions here go through :class:`scipy.spatial.transform.Rotation`
(an independent implementation), bridged to the ICD convention, and the Euler
matrices are written out again from Eq 4-4.

Conventions (ICD §2)
--------------------
* ``T1(a) = [[1,0,0],[0,c,s],[0,-s,c]]``, ``T2(a) = [[c,0,-s],[0,1,0],[s,0,c]]``,
  ``T3(a) = [[c,s,0],[-s,c,0],[0,0,1]]`` (frame rotations, Eq 4-4).
* A direction-cosine matrix ``C`` maps GCI to body, ``v_B = C v_I``.
* Quaternion ``q = (q1, q2, q3, q4)``, scalar last, with (Eq 4-8)
  ``C(q) = (q4² − |e|²) I + 2 e eᵀ − 2 q4 [e×]``.
  SciPy's ``Rotation.from_quat(q).as_matrix()`` is the *active* rotation
  ``(q4² − |e|²) I + 2 e eᵀ + 2 q4 [e×]``, which is ``C(q)ᵀ``. Hence
  ``C(q) = Rotation.from_quat(q).as_matrix().T`` and the ICD quaternion of ``C`` is the
  SciPy quaternion of ``Cᵀ``.
* Rotation vector of a frame rotation: ``C = exp(−[φ×])`` (a body turning by ``φ``);
  ``φ`` is SciPy's ``as_rotvec`` of ``Cᵀ``.

Shapes: angles ``(N,)`` give matrices ``(N, 3, 3)``; quaternions ``(N, 4)``.
"""

from __future__ import annotations

import numpy as np
from scipy.spatial.transform import Rotation

__all__ = [
    "rot1",
    "rot2",
    "rot3",
    "rpy_to_dcm",
    "dcm_to_rpy",
    "quat_to_dcm",
    "dcm_to_quat",
    "dcm_to_rotvec",
    "rotvec_to_dcm",
    "unit",
]


def _stack3(rows):
    return np.stack([np.stack(r, axis=-1) for r in rows], axis=-2)


def rot1(a):
    """Eq 4-4 ``T1(a)``, rotation of the frame about x. ``a.shape + (3, 3)``."""
    a = np.asarray(a, dtype=float)
    c, s, o, z = np.cos(a), np.sin(a), np.ones_like(a), np.zeros_like(a)
    return _stack3([(o, z, z), (z, c, s), (z, -s, c)])


def rot2(a):
    """Eq 4-4 ``T2(a)``, rotation of the frame about y."""
    a = np.asarray(a, dtype=float)
    c, s, o, z = np.cos(a), np.sin(a), np.ones_like(a), np.zeros_like(a)
    return _stack3([(c, z, -s), (z, o, z), (s, z, c)])


def rot3(a):
    """Eq 4-4 ``T3(a)``, rotation of the frame about z."""
    a = np.asarray(a, dtype=float)
    c, s, o, z = np.cos(a), np.sin(a), np.ones_like(a), np.zeros_like(a)
    return _stack3([(c, s, z), (-s, c, z), (z, z, o)])


def rpy_to_dcm(roll, pitch, yaw):
    """Eq 4-4: ``[B] = T3(yaw) T2(pitch) T1(roll)`` (also the alignment ``M`` of ICD §2)."""
    return rot3(yaw) @ rot2(pitch) @ rot1(roll)


def dcm_to_rpy(B):
    """Inverse of :func:`rpy_to_dcm` (Eq 4-5): roll, pitch, yaw in radians.

    ``B31 = sin θ``, ``B32 = −sin φ cos θ``, ``B33 = cos φ cos θ``, ``B21 = −sin ψ cos θ``,
    ``B11 = cos ψ cos θ``. Not for gimbal lock (``|θ| = 90°``).
    """
    B = np.asarray(B, dtype=float)
    pitch = np.arcsin(np.clip(B[..., 2, 0], -1.0, 1.0))
    roll = np.arctan2(-B[..., 2, 1], B[..., 2, 2])
    yaw = np.arctan2(-B[..., 1, 0], B[..., 0, 0])
    return roll, pitch, yaw


def quat_to_dcm(q):
    """Eq 4-8 written out: ``C(q) = (q4² − |e|²) I + 2 e eᵀ − 2 q4 [e×]``. ``(N,4) -> (N,3,3)``."""
    q = np.asarray(q, dtype=float)
    q = q / np.linalg.norm(q, axis=-1, keepdims=True)
    q1, q2, q3, q4 = q[..., 0], q[..., 1], q[..., 2], q[..., 3]
    return _stack3(
        [
            (q1 * q1 - q2 * q2 - q3 * q3 + q4 * q4, 2 * (q1 * q2 + q3 * q4), 2 * (q1 * q3 - q2 * q4)),
            (2 * (q1 * q2 - q3 * q4), -q1 * q1 + q2 * q2 - q3 * q3 + q4 * q4, 2 * (q2 * q3 + q1 * q4)),
            (2 * (q1 * q3 + q2 * q4), 2 * (q2 * q3 - q1 * q4), -q1 * q1 - q2 * q2 + q3 * q3 + q4 * q4),
        ]
    )


def dcm_to_quat(C):
    """ICD quaternion (q4 ≥ 0) of the GCI-to-body matrix ``C``: SciPy's quaternion of ``Cᵀ``."""
    C = np.asarray(C, dtype=float)
    flat = C.reshape(-1, 3, 3)
    q = Rotation.from_matrix(np.swapaxes(flat, -1, -2)).as_quat()
    q = np.where(q[:, 3:4] < 0.0, -q, q)
    return q.reshape(C.shape[:-2] + (4,))


def dcm_to_rotvec(C):
    """Rotation vector ``φ`` with ``C = exp(−[φ×])`` (Eq 4-33: angle ``2 acos q4``, axis ``e``)."""
    C = np.asarray(C, dtype=float)
    flat = C.reshape(-1, 3, 3)
    phi = Rotation.from_matrix(np.swapaxes(flat, -1, -2)).as_rotvec()
    return phi.reshape(C.shape[:-2] + (3,))


def rotvec_to_dcm(phi):
    """Frame rotation ``exp(−[φ×])`` for rotation vectors ``φ`` ``(..., 3)``."""
    phi = np.asarray(phi, dtype=float)
    flat = phi.reshape(-1, 3)
    R = Rotation.from_rotvec(flat).as_matrix()
    return np.swapaxes(R, -1, -2).reshape(phi.shape[:-1] + (3, 3))


def unit(v):
    """Unit vectors along the last axis."""
    v = np.asarray(v, dtype=float)
    return v / np.linalg.norm(v, axis=-1, keepdims=True)
