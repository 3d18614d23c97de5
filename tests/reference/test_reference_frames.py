"""Reference frames of the attitude modes and spin-axis geometry (gcs_core.frames.reference)."""

import numpy as np
import pytest

from gcs_core import units
from gcs_core.ephem.orbit import KeplerOrbit
from gcs_core.errors import InputError
from gcs_core.frames import reference as ref
from gcs_core.frames.rotations import T1, T2, T3

one_arcsecond = units.ARCSEC
EPOCH = "2024-03-20T06:00:00Z"


def _random_states(n, seed):
    rng = np.random.default_rng(seed)
    r = rng.normal(size=(n, 3)) * 7000.0
    v = rng.normal(size=(n, 3)) * 7.5
    s = rng.normal(size=(n, 3)) * 1.5e8
    return r, v, s


def _assert_rotation(A):
    eye = np.broadcast_to(np.eye(3), A.shape)
    np.testing.assert_allclose(A @ np.swapaxes(A, -1, -2), eye, atol=1e-14)
    np.testing.assert_allclose(np.linalg.det(A), 1.0, atol=1e-14)


@pytest.mark.parametrize("mode", ["inertial", "earth_pointing", "sun_pointing"])
def test_reference_matrices_are_rotations(mode):
    r, v, s = _random_states(200, 1)
    A = ref.reference_dcm(mode, r, v, s)
    assert A.shape == (200, 3, 3)
    _assert_rotation(A)


def test_earth_pointing_axes_follow_the_icd():
    """ICD §2: z_R = -r/|r|, y_R = -(r x v)/|r x v|, x_R = y_R x z_R; rows of A are the axes,
    so A r points along -z and A (r x v) along -y; x_R is along-track (v . x_R > 0)."""
    r, v, _ = _random_states(100, 2)
    A = ref.reference_dcm("earth_pointing", r, v)
    rR = np.einsum("nij,nj->ni", A, r)
    hR = np.einsum("nij,nj->ni", A, np.cross(r, v))
    np.testing.assert_allclose(rR[:, :2], 0.0, atol=1e-9)
    assert np.all(rR[:, 2] < 0.0)
    np.testing.assert_allclose(hR[:, [0, 2]], 0.0, atol=1e-7)
    assert np.all(hR[:, 1] < 0.0)
    assert np.all(np.einsum("ni,ni->n", A[:, 0, :], v) > 0.0)


def test_sun_pointing_axes_follow_the_icd():
    """ICD §2: x_R = s/|s|, y_R = (z_GCI x x_R)/|.| (so y_R is in the equator plane),
    z_R = x_R x y_R (so z_R has a positive GCI z component)."""
    _, _, s = _random_states(100, 3)
    A = ref.reference_dcm("sun_pointing", sun_I=s)
    np.testing.assert_allclose(A[:, 0, :], s / np.linalg.norm(s, axis=1)[:, None], atol=1e-15)
    np.testing.assert_allclose(A[:, 1, 2], 0.0, atol=1e-15)
    assert np.all(A[:, 2, 2] > 0.0)
    # at the March equinox (Sun along +x_GCI) the reference frame is the GCI frame
    np.testing.assert_allclose(ref.reference_dcm("sun_pointing", sun_I=[1.5e8, 0.0, 0.0])[0], np.eye(3), atol=1e-15)


def test_inertial_and_bad_modes():
    np.testing.assert_array_equal(ref.reference_dcm("inertial")[0], np.eye(3))
    assert ref.reference_dcm("inertial", np.zeros((5, 3))).shape == (5, 3, 3)
    with pytest.raises(InputError, match="spin"):
        ref.reference_dcm("spinning")
    with pytest.raises(InputError, match="mission.attitude_mode"):
        ref.reference_dcm("nadir")


def test_spin_axis_and_ra_dec_round_trip():
    """Eq 4-2 and its inverse, including near the poles and at RA wrap."""
    rng = np.random.default_rng(4)
    ra = rng.uniform(0.0, 2 * np.pi, 1000)
    dec = rng.uniform(-np.pi / 2, np.pi / 2, 1000)
    dec[:3] = [np.pi / 2 - 1e-9, -np.pi / 2 + 1e-9, 0.0]
    A = ref.spin_axis(ra, dec)
    np.testing.assert_allclose(np.linalg.norm(A, axis=1), 1.0, atol=1e-15)
    ra2, dec2 = ref.ra_dec_from_vector(A)
    np.testing.assert_allclose(dec2, dec, atol=1e-12)
    dra = np.angle(np.exp(1j * (ra2 - ra))) * np.cos(dec)  # RA error as an arc
    np.testing.assert_allclose(dra, 0.0, atol=1e-12)
    assert np.all((ra2 >= 0) & (ra2 < 2 * np.pi))
    # the seed's example guess for a spinner: RA 303.5 deg, Dec -25.5 deg
    a = ref.spin_axis(np.radians(303.5), np.radians(-25.5))
    assert a.shape == (3,) and a[2] < 0 and a[0] > 0 and a[1] < 0


def test_spin_axis_partials_against_central_differences():
    """Central differences with h = 1e-6 rad have truncation error h^2/6 ~ 2e-13."""
    rng = np.random.default_rng(5)
    ra = rng.uniform(0.0, 2 * np.pi, 200)
    dec = rng.uniform(-1.5, 1.5, 200)
    d_ra, d_dec = ref.spin_axis_partials(ra, dec)
    h = 1e-6
    fd_ra = (ref.spin_axis(ra + h, dec) - ref.spin_axis(ra - h, dec)) / (2 * h)
    fd_dec = (ref.spin_axis(ra, dec + h) - ref.spin_axis(ra, dec - h)) / (2 * h)
    np.testing.assert_allclose(d_ra, fd_ra, atol=1e-9)
    np.testing.assert_allclose(d_dec, fd_dec, atol=1e-9)


def test_earth_pointing_rate_is_the_frame_rate():
    """Eq 4-34: for the earth_pointing frame dA/dt = -[omega_R x] A with omega_R = A omega_I.
    Checked on a two-body orbit by central differences of A (h = 0.5 s); it also equals
    (r x v)/|r|^2 and has R components (0, -|omega|, 0)."""
    orbit = KeplerOrbit(7000.0, 0.01, 51.6, 20.0, 30.0, 40.0, EPOCH, j2=False)
    t = np.linspace(0.0, 5000.0, 40)
    h = 0.5
    A = ref.reference_dcm("earth_pointing", *orbit.state(t))
    Ap = ref.reference_dcm("earth_pointing", *orbit.state(t + h))
    Am = ref.reference_dcm("earth_pointing", *orbit.state(t - h))
    Adot = (Ap - Am) / (2 * h)
    W = -Adot @ np.swapaxes(A, -1, -2)  # [omega_R x]
    omega_R_fd = np.stack([W[:, 2, 1], W[:, 0, 2], W[:, 1, 0]], -1)
    r, v = orbit.state(t)
    omega_I = ref.earth_pointing_rate(r, v)
    omega_R = np.einsum("nij,nj->ni", A, omega_I)
    np.testing.assert_allclose(omega_R, omega_R_fd, atol=1e-10)
    np.testing.assert_allclose(omega_I, np.cross(r, v) / np.sum(r * r, axis=1)[:, None], atol=1e-15)
    np.testing.assert_allclose(ref.earth_pointing_rate(r, v, frame="R"), omega_R, atol=1e-15)


def test_attitude_from_rpy_is_eq_4_6():
    """C_BI = T3(yaw) T2(pitch) T1(roll) A, vectorized; zero angles give A itself."""
    r, v, s = _random_states(50, 6)
    rng = np.random.default_rng(6)
    roll, pitch, yaw = rng.uniform(-0.3, 0.3, (3, 50))
    A = ref.reference_dcm("sun_pointing", sun_I=s)
    C = ref.attitude_from_rpy("sun_pointing", roll, pitch, yaw, A)
    expected = T3(yaw) @ T2(pitch) @ T1(roll) @ A
    np.testing.assert_allclose(C, expected, atol=1e-15)
    _assert_rotation(C)
    np.testing.assert_allclose(ref.attitude_from_rpy("sun_pointing", 0.0, 0.0, 0.0, A), A, atol=1e-15)
    np.testing.assert_allclose(ref.attitude_from_rpy("inertial", 0.1, 0.0, 0.0), T1(0.1), atol=1e-15)
    with pytest.raises(ValueError):
        ref.attitude_from_rpy("earth_pointing", 0.0, 0.0, 0.0)
