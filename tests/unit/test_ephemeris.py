"""Ephemeris interpolation, analytic orbits and light corrections (gcs_core.ephem)."""

import time
from pathlib import Path

import numpy as np
import pytest

from gcs_core import units
from gcs_core.ephem import corrections, timescale
from gcs_core.ephem.ephemeris import Ephemeris
from gcs_core.ephem.orbit import KeplerOrbit, TleOrbit, build_ephemeris, solve_kepler
from gcs_core.ephem.sun import sun_position_km
from gcs_core.errors import InputError
from gcs_core.io.types import Table

one_meter = 1e-3  # km
one_mm_per_s = 1e-6  # km/s
one_arcsecond = units.ARCSEC
EPOCH = "2024-03-20T06:00:00Z"


def _leo(j2=True):
    return KeplerOrbit(6878.137, 0.0012, 97.4, 30.0, 40.0, 50.0, EPOCH, j2=j2)


# ---------------------------------------------------------------- Ephemeris


def test_hermite_on_a_kepler_orbit_is_better_than_a_meter_at_60_s():
    """Cubic Hermite error bound h^4/384 n^4 |r| ~ 0.3 m for LEO at 60 s (module docstring)."""
    orbit = _leo()
    eph = build_ephemeris(orbit, EPOCH, 0.0, 6000.0, step=60.0)
    t = np.linspace(0.0, 6000.0, 20_001)
    r, v = eph.state(t)
    r_true, v_true = orbit.state(t)
    assert np.max(np.linalg.norm(r - r_true, axis=1)) < one_meter
    # the derivative of the Hermite polynomial is one order worse: ~2e-5 km/s
    assert np.max(np.linalg.norm(v - v_true, axis=1)) < 50 * one_mm_per_s
    # exact at the rows
    np.testing.assert_allclose(eph.state(eph.t)[0], eph.r_I_km, rtol=0, atol=1e-9)
    np.testing.assert_allclose(eph.state(eph.t)[1], eph.v_I_km_s, rtol=0, atol=1e-12)


def test_hermite_reproduces_cubic_motion_exactly():
    """On each interval the interpolant is the cubic matching r and v at both ends, so a
    cubic trajectory is reproduced to round-off (also on uneven spacing)."""

    def traj(t):
        c = np.array([[7000.0, -3.0, 0.02, -1e-5], [10.0, 7.5, -0.01, 2e-6], [-50.0, 1.0, 0.0, 3e-6]])
        r = c[:, 0] + np.outer(t, c[:, 1]) + np.outer(t**2, c[:, 2]) + np.outer(t**3, c[:, 3])
        v = c[:, 1] + np.outer(2 * t, c[:, 2]) + np.outer(3 * t**2, c[:, 3])
        return r, v

    tk = np.array([0.0, 17.0, 60.0, 61.5, 120.0])
    rk, vk = traj(tk)
    eph = Ephemeris(tk, rk, vk, np.tile([1.5e8, 0.0, 0.0], (tk.size, 1)))
    t = np.linspace(0.0, 120.0, 777)
    r, v = eph.state(t)
    r_true, v_true = traj(t)
    np.testing.assert_allclose(r, r_true, rtol=0, atol=1e-9)
    np.testing.assert_allclose(v, v_true, rtol=0, atol=1e-11)


def test_orbit_normal_is_not_disturbed_by_velocity_interpolation():
    """The Hermite derivative stays in the orbit plane: the earth_pointing y axis
    -(r x v)/|r x v| is good to far better than an arcsecond."""
    orbit = _leo(j2=False)
    eph = build_ephemeris(orbit, EPOCH, 0.0, 3000.0, step=60.0)
    t = np.linspace(0.0, 3000.0, 3001)
    r, v = eph.state(t)
    rt, vt = orbit.state(t)
    h = np.cross(r, v)
    ht = np.cross(rt, vt)
    assert np.max(corrections.angle_between(h, ht)) < 0.01 * one_arcsecond


def test_scalar_and_vector_queries():
    eph = build_ephemeris(_leo(), EPOCH, 0.0, 600.0, step=60.0)
    r, v = eph.state(30.0)
    assert r.shape == (3,) and v.shape == (3,)
    assert eph.sun_geocentric(np.array([30.0, 40.0])).shape == (2, 3)


def test_coverage_errors_name_the_file_and_the_gap():
    eph = build_ephemeris(_leo(), EPOCH, 0.0, 600.0, step=60.0, source="mission/ephemeris.csv")
    assert eph.t_start == 0.0 and eph.t_end == 600.0
    eph.check_covers(np.array([0.0, 600.0]))  # edges are covered
    with pytest.raises(InputError) as err:
        eph.check_covers(np.array([-5.0, 100.0, 700.0]), what="telemetry of TAM1")
    msg = str(err.value)
    assert "mission/ephemeris.csv" in msg and "telemetry of TAM1" in msg
    assert "-5.000 s to 0.000 s" in msg and "600.000 s to 700.000 s" in msg and "\n" not in msg
    with pytest.raises(InputError):
        eph.state(np.array([601.0]))
    with pytest.raises(InputError):
        eph.sun_unit(-1.0)
    np.testing.assert_array_equal(eph.covers([-1.0, 0.0, 600.0, 600.1]), [0, 1, 1, 0])


def test_bad_tables_are_refused():
    t = np.array([0.0, 60.0, 60.0])
    z = np.zeros((3, 3))
    with pytest.raises(InputError, match="strictly increasing"):
        Ephemeris(t, z, z, z, source="e.csv")
    with pytest.raises(InputError, match="at least two"):
        Ephemeris([0.0], z[:1], z[:1], z[:1])
    with pytest.raises(InputError, match="shape"):
        Ephemeris([0.0, 1.0], z, z[:2], z[:2])


def test_from_table_reads_icd_columns_and_names_a_missing_one():
    orbit = _leo()
    t = np.arange(0.0, 301.0, 60.0)
    r, v = orbit.state(t)
    s = sun_position_km(timescale.julian_date(EPOCH, t))
    cols = {"t": t}
    for i, ax in enumerate("xyz"):
        cols["r" + ax], cols["v" + ax], cols["s" + ax] = r[:, i], v[:, i], s[:, i]
    table = Table(path=Path("m/ephemeris.csv"), t=t, columns=cols, lines=np.arange(2, 2 + t.size))
    eph = Ephemeris.from_table(table)
    np.testing.assert_array_equal(eph.r_I_km, r)
    assert eph.source == str(Path("m/ephemeris.csv"))
    cols.pop("sy")
    with pytest.raises(InputError) as err:
        Ephemeris.from_table(Table(path=Path("m/ephemeris.csv"), t=t, columns=cols, lines=np.arange(2, 2 + t.size)))
    assert "sy" in str(err.value) and "m/ephemeris.csv" in str(err.value)


def test_sun_interpolation_and_earth_velocity():
    """Linear Sun interpolation departs from the curved path by |s| (2pi/yr)^2 h^2 / 8
    ~ 3 m at h = 60 s (asserted: 10 m, 0.01 milliarcsec of direction); -ds/dt is the
    Earth's orbital velocity (29.3-30.3 km/s, perpendicular to the Sun within e = 0.0167)."""
    eph = build_ephemeris(_leo(), EPOCH, 0.0, 3600.0, step=60.0)
    t = np.linspace(0.0, 3600.0, 1001)
    s = eph.sun_geocentric(t)
    s_true = sun_position_km(timescale.julian_date(EPOCH, t))
    assert np.max(np.linalg.norm(s - s_true, axis=1)) < 10 * one_meter
    ve = eph.earth_velocity_km_s(t)
    speed = np.linalg.norm(ve, axis=1)
    assert np.all((speed > 29.2) & (speed < 30.4))
    cosang = np.sum(ve * s, axis=1) / (speed * np.linalg.norm(s, axis=1))
    assert np.max(np.abs(cosang)) < 0.02  # e = 0.0167
    u = eph.sun_unit(t)
    r = eph.position(t)
    np.testing.assert_allclose(u, (s - r) / np.linalg.norm(s - r, axis=1)[:, None], atol=1e-15)


def test_600k_queries_are_fast():
    eph = build_ephemeris(_leo(), EPOCH, 0.0, 86400.0, step=30.0)
    t = np.sort(np.random.default_rng(1).uniform(0.0, 86400.0, 600_000))
    t0 = time.perf_counter()
    r, v = eph.state(t)
    s = eph.sun_unit(t)
    elapsed = time.perf_counter() - t0
    assert r.shape == (600_000, 3) and s.shape == (600_000, 3)
    assert elapsed < 3.0, f"600k interpolations took {elapsed:.2f} s"


# ---------------------------------------------------------------- orbits


def test_kepler_solver():
    rng = np.random.default_rng(2)
    M = rng.uniform(-20.0, 20.0, 1000)
    for e in (0.0, 0.1, 0.7, 0.95):
        E = solve_kepler(M, e)
        np.testing.assert_allclose(E - e * np.sin(E), M, rtol=0, atol=1e-12)


def test_kepler_velocity_is_the_derivative_of_position():
    """Including the J2 drift terms, so that tabulated orbits interpolate consistently."""
    orbit = _leo(j2=True)
    t = np.linspace(0.0, 6000.0, 101)
    h = 0.01
    rp, _ = orbit.state(t + h)
    rm, _ = orbit.state(t - h)
    _, v = orbit.state(t)
    np.testing.assert_allclose((rp - rm) / (2 * h), v, rtol=0, atol=1e-8)


def test_two_body_energy_and_period():
    orbit = _leo(j2=False)
    t = np.linspace(0.0, orbit.period_s, 50)
    r, v = orbit.state(t)
    energy = 0.5 * np.sum(v * v, axis=1) - units.MU_EARTH / np.linalg.norm(r, axis=1)
    np.testing.assert_allclose(energy, -units.MU_EARTH / (2 * orbit.a_km), rtol=1e-12)
    np.testing.assert_allclose(r[-1], r[0], rtol=0, atol=1e-6)


def test_j2_nodal_rate_of_a_sun_synchronous_orbit():
    """A circular orbit at 700 km altitude is Sun-synchronous at i = 98.19 deg (Vallado,
    Fundamentals, sun-synchronous inclination vs altitude; also Wertz SMAD): its node
    advances 360 deg per tropical year, 1.991e-7 rad/s. One percent."""
    orbit = KeplerOrbit(units.R_EARTH_KM + 700.0, 0.0, 98.19, 0.0, 0.0, 0.0, EPOCH)
    target = 2 * np.pi / (365.2422 * 86400.0)
    assert abs(orbit.raan_dot - target) < 0.01 * target


def test_kepler_refuses_bad_elements():
    with pytest.raises(InputError, match="orbit.e"):
        KeplerOrbit(7000.0, 1.2, 0.0, 0.0, 0.0, 0.0, EPOCH)
    with pytest.raises(InputError, match="orbit.a_km"):
        KeplerOrbit(-7000.0, 0.0, 0.0, 0.0, 0.0, 0.0, EPOCH)


ISS_TLE = (
    "1 25544U 98067A   19343.69339541  .00001764  00000-0  38792-4 0  9991",
    "2 25544  51.6439 211.2001 0007417  17.6667  85.6398 15.50103472202482",
)


def test_tle_orbit_matches_sgp4_directly():
    """The ISS element set of the python-sgp4 documentation; TleOrbit must reproduce
    Satrec.sgp4 at the same Julian dates, with the mission epoch shifting t."""
    from sgp4.api import Satrec

    sat = Satrec.twoline2rv(*ISS_TLE)
    orbit = TleOrbit(*ISS_TLE, "2019-12-09T12:00:00Z")
    t = np.array([0.0, 600.0, 5400.0])
    r, v = orbit.state(t)
    for k, tk in enumerate(t):
        jd, fr = timescale.julian_date_parts("2019-12-09T12:00:00Z", tk)
        e, rr, vv = sat.sgp4(float(jd), float(fr))
        assert e == 0
        np.testing.assert_allclose(r[k], rr, rtol=0, atol=1e-9)
        np.testing.assert_allclose(v[k], vv, rtol=0, atol=1e-12)
    assert abs(np.linalg.norm(r[0]) - 6780.0) < 60.0
    with pytest.raises(InputError):
        TleOrbit("1 garbage", "2 garbage", EPOCH)


def test_build_ephemeris_shifts_between_orbit_and_mission_epochs():
    orbit = _leo()
    eph = build_ephemeris(orbit, "2024-03-20T06:10:00Z", 0.0, 125.0, step=30.0)
    np.testing.assert_array_equal(eph.t, [0.0, 30.0, 60.0, 90.0, 120.0, 125.0])
    np.testing.assert_allclose(eph.r_I_km[0], orbit.state(600.0)[0][0], rtol=0, atol=1e-9)


# ---------------------------------------------------------------- corrections


def test_annual_aberration_constant():
    """The IAU 1976 constant of aberration kappa = 20.49552 arcsec is v/c for the Earth's
    mean orbital speed (v = kappa c = 29.789 km/s); a source perpendicular to that velocity
    is displaced by asin(beta) (exact) or atan(beta) (first order), both kappa to 1e-9."""
    kappa = 20.49552 * one_arcsecond
    u = np.array([[1.0, 0.0, 0.0]])
    v = np.array([[0.0, kappa * units.C_KM_S, 0.0]])
    assert abs(v[0, 1] - 29.789) < 1e-3
    for first in (False, True):
        up = corrections.aberrate(u, v, first_order=first)
        ang = corrections.angle_between(u, up)[0]
        assert abs(ang - kappa) < 1e-4 * one_arcsecond
        assert up[0, 1] > 0.0  # displaced toward the motion


def test_exact_and_first_order_aberration_differ_by_beta_squared():
    rng = np.random.default_rng(5)
    u = rng.normal(size=(1000, 3))
    v = rng.normal(size=(1000, 3)) * 30.0
    a = corrections.aberrate(u, v)
    b = corrections.aberrate(u, v, first_order=True)
    np.testing.assert_allclose(np.linalg.norm(a, axis=1), 1.0, atol=1e-15)
    assert np.max(corrections.angle_between(a, b)) < 0.01 * one_arcsecond
    # a source straight ahead or behind is not displaced
    np.testing.assert_allclose(corrections.aberrate([0.0, 0.0, 1.0], [0.0, 0.0, 30.0]), [0.0, 0.0, 1.0], atol=1e-15)


def test_apparent_sun_from_spacecraft():
    """Parallax from a 7000 km position perpendicular to the Sun: 7000/1.496e8 rad
    (9.65 arcsec); orbital aberration from 7.5 km/s perpendicular: 5.16 arcsec."""
    s = np.array([[units.AU_KM, 0.0, 0.0]])
    r = np.array([[0.0, 7000.0, 0.0]])
    u = corrections.sun_from_spacecraft(s, r)
    assert abs(corrections.angle_between(u, s)[0] - 7000.0 / units.AU_KM) < 1e-4 * one_arcsecond
    v = np.array([[0.0, 0.0, 7.5]])
    ua = corrections.apparent_sun_from_spacecraft(s, r, v)
    assert abs(corrections.angle_between(ua, u)[0] - 7.5 / units.C_KM_S) < 0.001 * one_arcsecond
    star = corrections.apparent_star_direction([[1.0, 0.0, 0.0]], [[0.0, 29.78, 0.0]], [[0.0, 0.0, 7.5]])
    assert star.shape == (1, 3)
