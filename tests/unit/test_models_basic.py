"""Known-value checks of the observation models (seed §4.2, ICD §5).

Each expected value comes from a geometry simple enough to work by hand or from an
independent relation (spherical trigonometry for the horizon chord, the exact inverse of
the Sun-sensor transfer function), not from the model's own code path.
"""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest
from model_fixtures import CircularOrbit, random_dcm, random_unit, sensor, unit_from_angles

from gcs_core import units
from gcs_core.errors import InputError
from gcs_core.frames.rotations import T3, quat_from_dcm, quat_to_dcm
from gcs_core.io.types import SENSOR_TYPES, Table
from gcs_core.models import MODEL_TYPES, make_model
from gcs_core.models.base import Geometry
from gcs_core.models.common import alignment_matrix
from gcs_core.models.fine_sun import eight_coefficients, tan_from_counts
from gcs_core.models.gyro import corrected_rate, propagate_quaternion, rate_from_quaternions
from gcs_core.models.horizon import TWO_PI

one_arcsecond = units.ARCSEC
one_nT = 1.0
one_microsecond = 1e-6
machine_counts = 1e-9  # counts: round-off of a ~1e4-count value


# --------------------------------------------------------------------------------------
# registry
# --------------------------------------------------------------------------------------
def test_registry_covers_every_icd_type():
    assert set(MODEL_TYPES) == set(SENSOR_TYPES)


def test_unknown_type_names_the_type_key():
    with pytest.raises(InputError, match="sun_tracker") as err:
        make_model(sensor("X1", "sun_tracker"))
    assert err.value.key == "X1.type"


def test_missing_book_key_is_an_input_error():
    with pytest.raises(InputError, match="coeff_alpha"):
        make_model(sensor("FSS1", "fine_sun", coeff_beta=(0, 1e-4, 0, 50))).parameters()


def test_unknown_parameter_name_is_refused():
    model = make_model(sensor("TAM1", "magnetometer"))
    geom = Geometry(t=np.zeros(1), C_BI=np.eye(3)[None], B_I=np.ones((1, 3)))
    with pytest.raises(ValueError, match="bias_q"):
        model.predict(geom, {"bias_q": 1.0})


# --------------------------------------------------------------------------------------
# magnetometer
# --------------------------------------------------------------------------------------
def test_magnetometer_zero_alignment_is_attitude_times_field_plus_bias():
    rng = np.random.default_rng(11)
    model = make_model(sensor("TAM1", "magnetometer", bias=(10.0, -20.0, 30.0)))
    C, B = random_dcm(rng, 5), rng.normal(scale=3e4, size=(5, 3))
    pred = model.predict(Geometry(t=np.arange(5.0), C_BI=C, B_I=B), {})
    expected = np.einsum("nij,nj->ni", C, B) + [10.0, -20.0, 30.0]
    np.testing.assert_allclose(pred.y, expected, atol=1e-6 * one_nT)


def test_magnetometer_time_offset_without_field_model_leaves_the_field_still():
    """No field model in the geometry (no Ḃ_I): a time-tag offset rotates the measured field
    with the body only; the prediction and its time_offset partial stay finite and agree
    with a central difference (they were NaN and a ValueError)."""
    rng = np.random.default_rng(12)
    model = make_model(sensor("TAM1", "magnetometer"))
    n = 5
    geom = Geometry(
        t=np.arange(float(n)),
        C_BI=random_dcm(rng, n),
        B_I=rng.normal(scale=3e4, size=(n, 3)),
        omega_B=rng.normal(scale=1e-2, size=(n, 3)),
    )
    dt, h = 0.3, 1e-4  # [s]
    pred = model.predict(geom, {"time_offset": dt})
    slope = np.asarray(pred.d_par["time_offset"])
    assert np.all(np.isfinite(pred.y)) and np.all(np.isfinite(slope))
    plus = model.predict(geom, {"time_offset": dt + h}).y
    minus = model.predict(geom, {"time_offset": dt - h}).y
    np.testing.assert_allclose(slope, (plus - minus) / (2 * h), atol=1e-6 * one_nT)


def test_magnetometer_contamination_adds_k_times_channel():
    model = make_model(sensor("TAM1", "magnetometer"), aux_channels=("mtb_x",))
    geom = Geometry(
        t=np.arange(2.0), C_BI=np.stack([np.eye(3)] * 2), B_I=np.zeros((2, 3)), aux={"mtb_x": np.array([-60.0, 60.0])}
    )
    pred = model.predict(geom, {"contam_mtb_x_z": 0.5})
    np.testing.assert_allclose(pred.y, [[0, 0, -30.0], [0, 0, 30.0]], atol=1e-12)


# --------------------------------------------------------------------------------------
# star tracker
# --------------------------------------------------------------------------------------
def test_star_tracker_identity_alignment_reads_the_star_angles():
    """F_S = (cos h cos v, cos h sin v, sin h) gives back (h, v); scale S divides them."""
    h = np.radians([0.5, -1.0, 2.0])
    v = np.radians([-1.5, 0.3, 1.0])
    star = np.column_stack([np.cos(h) * np.cos(v), np.cos(h) * np.sin(v), np.sin(h)])
    model = make_model(sensor("FHST1", "star_tracker", fov_deg=4.0, noise=4e-5))
    geom = Geometry(t=np.arange(3.0), C_BI=np.stack([np.eye(3)] * 3), star_I=star)
    np.testing.assert_allclose(model.predict(geom, {}).y, np.column_stack([h, v]), atol=1e-6 * one_arcsecond)
    half = model.predict(geom, {"scale_h": 2.0, "scale_v": 0.5}).y
    np.testing.assert_allclose(half, np.column_stack([h / 2.0, v * 2.0]), atol=1e-6 * one_arcsecond)


def test_star_tracker_frame_outside_fov_is_invalid():
    star = np.array([[np.cos(0.2), np.sin(0.2), 0.0], [1.0, 0.0, 0.0]])  # 11.5° off, on axis
    model = make_model(sensor("FHST1", "star_tracker", fov_deg=4.0, noise=4e-5))
    pred = model.predict(Geometry(t=np.arange(2.0), C_BI=np.stack([np.eye(3)] * 2), star_I=star), {})
    assert pred.valid.tolist() == [False, True]
    assert np.all(np.isnan(pred.y[0])) and np.all(np.isnan(pred.d_par["scale_h"][0]))


def test_alignment_a3_rotates_about_sensor_z():
    """M = T3(a3): a star along body +x is seen at v = −a3 (v_S = T3(a3) x̂ = (cos, −sin, 0))."""
    model = make_model(sensor("FHST1", "star_tracker", fov_deg=4.0, noise=4e-5, alignment_deg=(0, 0, 1.0)))
    pred = model.predict(Geometry(t=np.zeros(1), C_BI=np.eye(3)[None], star_I=np.array([[1.0, 0, 0]])), {})
    np.testing.assert_allclose(pred.y[0], [0.0, -1.0 * units.DEG], atol=1e-6 * one_arcsecond)


# --------------------------------------------------------------------------------------
# Sun sensors
# --------------------------------------------------------------------------------------
FSS_COEFF = (0.01, 7.6e-5, 0.003, 50.0)


def test_fss_eight_coefficients_eq_4_25():
    A1, A2, A3, k = FSS_COEFF
    assert eight_coefficients(*FSS_COEFF) == pytest.approx(
        (A1, A2, A3, k * A2, k * A1, k * A3**2 / 2, 2 * k * A2, 2 * k * A1)
    )


def test_fss_transfer_function_inverse_consistency():
    """counts -> tan α (exact inverse of Eq 4-23) -> Sun vector -> model -> the same counts."""
    n_true = np.array([-5000.0, -1200.0, 0.0, 37.0, 4100.0])
    ta = tan_from_counts(n_true, *FSS_COEFF)
    tb = tan_from_counts(-n_true, 0.0, 7.7e-5, 0.002, 45.0)
    model = make_model(
        sensor(
            "FSS1", "fine_sun", noise=0.577, fov_deg=32.0, coeff_alpha=FSS_COEFF, coeff_beta=(0.0, 7.7e-5, 0.002, 45.0)
        )
    )
    sun = unit_from_angles(np.arctan(ta), np.arctan(tb))
    pred = model.predict(Geometry(t=np.arange(5.0), C_BI=np.stack([np.eye(3)] * 5), sun_I=sun), {})
    np.testing.assert_allclose(pred.y, np.column_stack([n_true, -n_true]), atol=machine_counts)
    # Eq 4-24 (the eight-coefficient series) agrees with the exact inverse to second order
    A = eight_coefficients(*FSS_COEFF)
    series = A[0] + A[1] * n_true + A[2] * np.sin(A[3] * n_true + A[4]) + A[5] * np.sin(A[6] * n_true + A[7])
    k, A3 = FSS_COEFF[3], FSS_COEFF[2]
    assert np.max(np.abs(series - ta)) < 2 * k**2 * A3**3  # next term is O(k² A3³)


def test_fss_behind_the_sensor_is_invalid():
    model = make_model(
        sensor("FSS1", "fine_sun", noise=0.577, fov_deg=32.0, coeff_alpha=FSS_COEFF, coeff_beta=FSS_COEFF)
    )
    sun = np.array([[-1.0, 0.0, 0.0], [1.0, 0.0, 0.0]])
    assert model.predict(Geometry(t=np.arange(2.0), C_BI=np.stack([np.eye(3)] * 2), sun_I=sun), {}).valid.tolist() == [
        False,
        True,
    ]


def test_css_known_angles_eq_4_16():
    K, b = 4.3633231e-3, (0.001, -0.002)
    model = make_model(sensor("CSS1", "coarse_sun", noise=0.577, fov_deg=60.0, scale=(K, K), bias=b))
    a = np.radians([0.0, 10.0, -25.0])
    c = np.radians([0.0, -5.0, 40.0])
    sun = unit_from_angles(a, c)
    pred = model.predict(Geometry(t=np.arange(3.0), C_BI=np.stack([np.eye(3)] * 3), sun_I=sun), {})
    np.testing.assert_allclose(pred.y, np.column_stack([(a + b[0]) / K, (c + b[1]) / K]), atol=machine_counts)


def test_plane_field_zero_tilt_reads_the_sun_angle():
    rng = np.random.default_rng(5)
    A, S = random_unit(rng, 6), random_unit(rng, 6)
    model = make_model(sensor("PFSS", "plane_field_sun", noise=1e-3, tilt_deg=0.0, bias=0.01))
    pred = model.predict(Geometry(t=np.arange(6.0), spin_axis_I=A, sun_I=S), {})
    angle = np.arctan2(np.linalg.norm(np.cross(A, S), axis=1), np.sum(A * S, axis=1))
    np.testing.assert_allclose(pred.y[:, 0], angle + 0.01, atol=1e-6 * one_arcsecond)


# --------------------------------------------------------------------------------------
# horizon scanner
# --------------------------------------------------------------------------------------
R_KM, H_KM = 7000.0, 40.0


def _static_ephemeris(r, sun):
    def eph(t):
        n = np.shape(t)[0]
        return np.tile(r, (n, 1)), np.zeros((n, 3)), np.tile(sun, (n, 1))

    return eph


def _horizon(gamma_deg=90.0, phi_h_deg=0.0, observable="in_out"):
    return make_model(
        sensor(
            "HS1",
            "horizon",
            noise=1e-3,
            gamma_deg=gamma_deg,
            phi_h_deg=phi_h_deg,
            horizon_height_km=H_KM,
            observable=observable,
        )
    )


@pytest.mark.parametrize("gamma_deg", [90.0, 80.0, 60.0])
def test_horizon_symmetric_geometry(gamma_deg):
    """Spin axis ⟂ nadir (η = 90°) and the Sun opposite the Earth, in the spin plane.

    The scan cone then cuts the Earth disc symmetrically about the nadir azimuth π:
    the half chord Ω obeys cos ρ = sin γ sin η cos Ω + cos γ cos η (spherical law of
    cosines on the triangle spin axis / nadir / line of sight, Wertz 1978 §11.2), so
    ``dt_in = (π − Ω − Φ_H)/ω`` and ``dt_out = (π + Ω − Φ_H)/ω``. The ICD's spherical
    Earth: the geometry carries no flattening.
    """
    omega, phi_h = 2.0, 30.0 * units.DEG
    rho = np.arcsin((units.R_EARTH_KM + H_KM) / R_KM)
    half_chord = np.arccos(np.cos(rho) / np.sin(np.radians(gamma_deg)))
    geom = Geometry(
        t=np.array([0.0]),
        spin_axis_I=np.array([0.0, 0.0, 1.0]),
        ephemeris=_static_ephemeris(np.array([R_KM, 0.0, 0.0]), np.array([1.0, 0.0, 0.0])),
        extra={"spin_rate": np.array([omega]), "earth_flattening": 0.0},
    )
    pred = _horizon(gamma_deg, 30.0).predict(geom, {})
    assert pred.valid[0]
    expected = np.array([np.pi - half_chord - phi_h, np.pi + half_chord - phi_h]) / omega
    np.testing.assert_allclose(pred.y[0], expected, atol=one_microsecond)
    wm = _horizon(gamma_deg, 30.0, observable="width_midscan").predict(geom, {})
    np.testing.assert_allclose(wm.y[0], [2 * half_chord / omega, (np.pi - phi_h) / omega], atol=one_microsecond)


def test_horizon_cone_missing_the_earth_is_invalid():
    geom = Geometry(
        t=np.array([0.0]),
        spin_axis_I=np.array([0.0, 0.0, 1.0]),
        ephemeris=_static_ephemeris(np.array([R_KM, 0.0, 0.0]), np.array([0.0, 1.0, 0.0])),
        extra={"spin_rate": np.array([1.0])},
    )
    pred = _horizon(gamma_deg=10.0).predict(geom, {})  # |η − γ| = 80° > ρ ≈ 66.5°
    assert not pred.valid[0] and np.all(np.isnan(pred.y[0]))


def test_horizon_implicit_solution_is_self_consistent():
    """With the ephemeris frozen at each crossing time, the same dt must come out.

    A slow spin (0.2 rad/s, 31 s period) lets the orbit move by up to 2° between the
    Sun sighting and the crossing, so reading the geometry at the crossing matters.
    """
    orbit = CircularOrbit(sun_rate=1e-4)
    model = _horizon(gamma_deg=85.0, phi_h_deg=40.0)
    t = np.array([100.0])
    geom = Geometry(t=t, spin_axis_I=orbit.normal, ephemeris=orbit, extra={"spin_rate": np.array([0.2])})
    pred = model.predict(geom, {"d_t": 3.0})
    assert pred.valid[0]
    dt = pred.y[0]
    for k in range(2):
        r, _, s = orbit(t + dt[k] + 3.0)
        frozen = Geometry(t=t, spin_axis_I=orbit.normal, extra=geom.extra, ephemeris=_static_ephemeris(r[0], s[0]))
        assert model.predict(frozen, {}).y[0, k] == pytest.approx(dt[k], abs=one_microsecond)
    moving_vs_frozen_at_sighting = model.predict(
        Geometry(
            t=t,
            spin_axis_I=orbit.normal,
            extra=geom.extra,
            ephemeris=_static_ephemeris(orbit(t + 3.0)[0][0], orbit(t + 3.0)[2][0]),
        ),
        {},
    ).y[0]
    assert np.max(np.abs(moving_vs_frozen_at_sighting - dt)) > 1e3 * one_microsecond  # the effect is real


def test_horizon_residual_wraps_modulo_the_spin_period():
    model = _horizon()
    omega = np.array([2.0, 2.0])
    period = TWO_PI / 2.0
    geom = Geometry(t=np.zeros(2), extra={"spin_rate": omega})
    y_meas = np.array([[period - 0.01, 0.5], [0.02, 1.0]])
    y_pred = np.array([[0.01, 0.4], [period - 0.03, 1.0]])
    np.testing.assert_allclose(model.residual(y_meas, y_pred, geom), [[-0.02, 0.1], [0.05, 0.0]], atol=1e-12)


def test_horizon_width_midscan_noise():
    model = _horizon(observable="width_midscan")
    assert model.components == ("width", "midscan")
    np.testing.assert_allclose(model.sigma(), [1e-3 * np.sqrt(2.0), 1e-3 / np.sqrt(2.0)])


def test_horizon_width_midscan_measurements_wrap():
    """dt_in = 3.0 s, dt_out = 0.5 s at ω = 2 rad/s (P = π s): the scan crossed the Sun
    sighting, so width = (0.5 − 3.0) mod π and mid-scan = (3.0 + width/2) mod π."""
    table = Table(
        path=Path("HS1.csv"),
        t=np.array([0.0]),
        lines=np.array([2]),
        columns={
            "t": np.array([0.0]),
            "spin_rate": np.array([2.0]),
            "dt_in": np.array([3.0]),
            "dt_out": np.array([0.5]),
        },
    )
    _, y = _horizon(observable="width_midscan").measurements(table)
    width = np.pi - 2.5
    np.testing.assert_allclose(y, [[width, 3.0 + width / 2 - np.pi]], atol=1e-12)
    _, y = _horizon().measurements(table)
    np.testing.assert_allclose(y, [[3.0, 0.5]])


def test_horizon_shared_sun_sensor_tilt_element():
    model = make_model(
        sensor("HS1", "horizon", noise=1e-3, gamma_deg=80, phi_h_deg=0, horizon_height_km=40, sun_sensor="PFSS")
    )
    spec = {p.name: p for p in model.parameters()}["eps_S"]
    assert spec.element == "PFSS.tilt"


# --------------------------------------------------------------------------------------
# gyro
# --------------------------------------------------------------------------------------
def test_gyro_model_inverse_recovers_the_rate():
    rng = np.random.default_rng(3)
    model = make_model(
        sensor("IRU", "gyro", alignment_deg=(1.0, -2.0, 0.5), noise=None, arw=3e-7, bias=(1e-6, -2e-6, 3e-6))
    )
    params = {**model.nominal(), **{f"G_{i}{j}": rng.uniform(-1e-2, 1e-2) for i in (1, 2, 3) for j in (1, 2, 3)}}
    omega = rng.normal(scale=0.01, size=(6, 3))
    y = model.predict(Geometry(t=np.arange(6.0), omega_B=omega), params).y
    M, _ = alignment_matrix(params)
    np.testing.assert_allclose(corrected_rate(y, params, M), omega, atol=1e-15)


def test_propagate_quaternion_about_z_is_T3():
    """Eq 4-38: a body spinning at w about z for Δt has C(t + Δt) = T3(w Δt) C(t)."""
    rng = np.random.default_rng(4)
    C0 = random_dcm(rng, 3)
    w, dt = 0.03, 7.0
    q1 = propagate_quaternion(quat_from_dcm(C0), np.array([0.0, 0.0, w]), dt)
    np.testing.assert_allclose(quat_to_dcm(q1), T3(w * dt) @ C0, atol=1e-14)


def test_rate_from_quaternions_inverts_propagation():
    rng = np.random.default_rng(6)
    q0 = quat_from_dcm(random_dcm(rng, 5))
    omega = rng.normal(scale=0.05, size=(5, 3))
    dt = np.array([0.5, 1.0, 2.0, 10.0, 30.0])
    q1 = propagate_quaternion(q0, omega, dt)
    np.testing.assert_allclose(rate_from_quaternions(q0, q1, dt), omega, atol=1e-14)


def test_gyro_sigma_from_angle_random_walk():
    model = make_model(sensor("IRU", "gyro", noise=None, arw=3.2e-7))
    np.testing.assert_allclose(model.sigma(), 3.2e-7)  # Δt = 1 s
    np.testing.assert_allclose(model.sigma(dt=4.0), 1.6e-7)
