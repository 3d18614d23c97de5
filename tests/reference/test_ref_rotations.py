"""Rotations, Euler 1-2-3 angles and quaternions (gcs_core.frames.rotations; seed §4.1.2).

Round trips between DCM, quaternion and Euler angles, including the awkward places: pitch
within 1e-9 rad of +-90 deg (gimbal lock), 180-degree rotations (q4 ~ 0, where Eq 4-9
divides by zero) and tiny angles.
"""

import numpy as np
import pytest

from gcs_core import units
from gcs_core.frames import rotations as R

one_arcsecond = units.ARCSEC
machine = 1e-14  # round-off on unit-magnitude matrix elements


def _rng(seed=0):
    return np.random.default_rng(seed)


def _random_quats(n, seed=0):
    return R.quat_normalize(_rng(seed).normal(size=(n, 4)))


def _same_rotation(qa, qb):
    """q and -q are the same rotation."""
    return np.minimum(np.abs(qa - qb).max(-1), np.abs(qa + qb).max(-1))


def test_elementary_rotations_are_eq_4_4():
    """ICD §2 / Eq 4-4: T1, T2, T3 literally."""
    a = 0.3
    c, s = np.cos(a), np.sin(a)
    np.testing.assert_allclose(R.T1(a), [[1, 0, 0], [0, c, s], [0, -s, c]])
    np.testing.assert_allclose(R.T2(a), [[c, 0, -s], [0, 1, 0], [s, 0, c]])
    np.testing.assert_allclose(R.T3(a), [[c, s, 0], [-s, c, 0], [0, 0, 1]])
    assert R.T1(np.zeros(7)).shape == (7, 3, 3)


def test_quaternion_convention_is_eq_4_8():
    """q = (e sin(θ/2), cos(θ/2)) about z gives C = T3(θ): a frame (passive) rotation, q4 last."""
    th = 0.7
    q = np.array([0.0, 0.0, np.sin(th / 2), np.cos(th / 2)])
    np.testing.assert_allclose(R.quat_to_dcm(q), R.T3(th), atol=machine)
    q = np.array([np.sin(th / 2), 0.0, 0.0, np.cos(th / 2)])
    np.testing.assert_allclose(R.quat_to_dcm(q), R.T1(th), atol=machine)


def test_quaternion_dcm_round_trip_generic():
    q = _random_quats(5000, 1)
    C = R.quat_to_dcm(q)
    np.testing.assert_allclose(C @ np.swapaxes(C, -1, -2), np.broadcast_to(np.eye(3), C.shape), atol=machine)
    q2 = R.quat_from_dcm(C)
    assert np.max(_same_rotation(q2, q)) < machine
    assert np.all(q2[:, 3] >= 0.0)


def test_quaternion_from_dcm_at_180_degrees():
    """q4 = 0 exactly and q4 = 1e-9: Eq 4-9 would divide by 4 q4; Shepperd's branch keeps
    full precision."""
    rng = _rng(2)
    ax = rng.normal(size=(2000, 3))
    ax /= np.linalg.norm(ax, axis=1)[:, None]
    for half_residual in (0.0, 1e-9):
        q = np.concatenate([ax * np.cos(half_residual), np.full((2000, 1), np.sin(half_residual))], 1)
        q2 = R.quat_from_dcm(R.quat_to_dcm(q))
        assert np.max(_same_rotation(q2, q)) < machine
    # the three principal half-turns
    for k in range(3):
        C = np.diag([-1.0, -1.0, -1.0])
        C[k, k] = 1.0
        e = np.zeros(4)
        e[k] = 1.0
        assert _same_rotation(R.quat_from_dcm(C), e) < machine


def test_tiny_rotations():
    """A 2e-10 rad rotation survives the round trips with relative precision."""
    rng = _rng(3)
    ax = rng.normal(size=(1000, 3))
    ax /= np.linalg.norm(ax, axis=1)[:, None]
    ang = 2e-10
    q = np.concatenate([ax * np.sin(ang / 2), np.full((1000, 1), np.cos(ang / 2))], 1)
    C = R.quat_to_dcm(q)
    np.testing.assert_allclose(R.dcm_to_rotvec(C), ang * ax, atol=1e-6 * ang)
    np.testing.assert_allclose(R.quat_from_dcm(C), q, atol=1e-6 * ang)
    np.testing.assert_allclose(R.rotvec_to_dcm(ang * ax), C, atol=machine)
    # first-order small rotation agrees to second order
    np.testing.assert_allclose(R.small_rotation(ang * ax), C, atol=ang**2)


def test_rotation_vector_round_trip():
    phi = _rng(4).normal(size=(2000, 3))
    phi *= (np.pi * 0.999 * _rng(5).uniform(size=2000) / np.linalg.norm(phi, axis=1))[:, None]
    np.testing.assert_allclose(R.dcm_to_rotvec(R.rotvec_to_dcm(phi)), phi, atol=1e-12)


def test_euler123_round_trip_generic():
    rng = _rng(6)
    roll = rng.uniform(-np.pi, np.pi, 5000)
    pitch = rng.uniform(-np.pi / 2 + 1e-3, np.pi / 2 - 1e-3, 5000)
    yaw = rng.uniform(-np.pi, np.pi, 5000)
    B = R.euler123_to_dcm(roll, pitch, yaw)
    r2, p2, y2 = R.dcm_to_euler123(B)
    for a, b in ((r2, roll), (p2, pitch), (y2, yaw)):
        np.testing.assert_allclose(np.angle(np.exp(1j * (a - b))), 0.0, atol=1e-11)


@pytest.mark.parametrize("pitch", [np.pi / 2, -np.pi / 2, np.pi / 2 - 1e-9, -np.pi / 2 + 1e-9, np.pi / 2 - 1e-6])
def test_euler123_near_gimbal_lock_reproduces_the_matrix(pitch):
    """At and near pitch = ±90 deg the individual roll and yaw are ill-determined, but the
    angles returned must rebuild the same matrix. Observed: exact at ±90 deg, 1e-9 at
    1e-9 rad from it (see the pitch-precision test below); asserted 1e-8 (2 milliarcsec)."""
    rng = _rng(7)
    roll = rng.uniform(-np.pi, np.pi, 2000)
    yaw = rng.uniform(-np.pi, np.pi, 2000)
    B = R.euler123_to_dcm(roll, np.full(2000, pitch), yaw)
    r2, p2, y2 = R.dcm_to_euler123(B)
    assert np.all(np.isfinite(r2)) and np.all(np.isfinite(y2))
    np.testing.assert_allclose(R.euler123_to_dcm(r2, p2, y2), B, atol=1e-8)


def test_euler123_pitch_is_full_precision_near_90_degrees():
    pitch = np.pi / 2 - 1e-9
    B = R.euler123_to_dcm(0.3, pitch, -0.2)
    _, p2, _ = R.dcm_to_euler123(B)
    assert abs(p2 - pitch) < 1e-14


def test_quat_to_euler123_is_eq_4_11():
    """Eq 4-11: φ = atan2(−2(q2q3 − q1q4), −q1²−q2²+q3²+q4²), θ = asin(2(q1q3 + q2q4)),
    ψ = atan2(−2(q1q2 − q3q4), q1²−q2²−q3²+q4²)."""
    q = _random_quats(3000, 8)
    q1, q2, q3, q4 = q.T
    phi = np.arctan2(-2 * (q2 * q3 - q1 * q4), -(q1**2) - q2**2 + q3**2 + q4**2)
    theta = np.arcsin(np.clip(2 * (q1 * q3 + q2 * q4), -1, 1))
    psi = np.arctan2(-2 * (q1 * q2 - q3 * q4), q1**2 - q2**2 - q3**2 + q4**2)
    r, p, y = R.quat_to_euler123(q)
    np.testing.assert_allclose(r, phi, atol=1e-12)
    np.testing.assert_allclose(p, theta, atol=1e-7)  # asin reference near ±1 loses precision
    np.testing.assert_allclose(y, psi, atol=1e-12)
    # and the angles rebuild C(q) (Eq 4-4 = Eq 4-8)
    np.testing.assert_allclose(R.euler123_to_dcm(r, p, y), R.quat_to_dcm(q), atol=1e-12)


def test_composition_is_eq_4_10():
    """C(q'') = C(q') C(q) with quat_multiply(q', q); associativity, identity and inverse."""
    a, b, c = _random_quats(1000, 9), _random_quats(1000, 10), _random_quats(1000, 11)
    ab = R.quat_multiply(a, b)
    np.testing.assert_allclose(R.quat_to_dcm(ab), R.quat_to_dcm(a) @ R.quat_to_dcm(b), atol=machine)
    np.testing.assert_allclose(
        R.quat_multiply(R.quat_multiply(a, b), c), R.quat_multiply(a, R.quat_multiply(b, c)), atol=machine
    )
    ident = np.array([0.0, 0.0, 0.0, 1.0])
    np.testing.assert_allclose(R.quat_multiply(ident, a), a, atol=0)
    np.testing.assert_allclose(R.quat_multiply(R.quat_conjugate(a), a), np.broadcast_to(ident, a.shape), atol=machine)
    # the Eq 4-10b matrix form, written out from the seed
    a1, a2, a3, a4 = a.T
    M = np.stack(
        [
            np.stack([a4, a3, -a2, a1], -1),
            np.stack([-a3, a4, a1, a2], -1),
            np.stack([a2, -a1, a4, a3], -1),
            np.stack([-a1, -a2, -a3, a4], -1),
        ],
        -2,
    )
    np.testing.assert_allclose(np.einsum("nij,nj->ni", M, b), ab, atol=machine)


def test_euler123_partials_against_central_differences():
    rng = _rng(12)
    ang = rng.uniform(-1.2, 1.2, (3, 100))
    D = R.euler123_partials(*ang)
    h = 1e-6
    for k in range(3):
        dp = ang.copy()
        dm = ang.copy()
        dp[k] += h
        dm[k] -= h
        fd = (R.euler123_to_dcm(*dp) - R.euler123_to_dcm(*dm)) / (2 * h)
        np.testing.assert_allclose(D[:, k], fd, atol=1e-9)


def test_orthonormalize_restores_a_rotation():
    C = R.quat_to_dcm(_random_quats(200, 13))
    np.testing.assert_allclose(R.orthonormalize(C), C, atol=machine)
    noisy = R.orthonormalize(C + 1e-6 * _rng(14).normal(size=C.shape))
    np.testing.assert_allclose(noisy @ np.swapaxes(noisy, -1, -2), np.broadcast_to(np.eye(3), C.shape), atol=machine)
    np.testing.assert_allclose(np.linalg.det(noisy), 1.0, atol=machine)
