"""The ``[orbit] tle`` extension: SGP4 states, the TEME frame and the published example.

Reference: Vallado, D. A., Crawford, P., Hujsak, R., Kelso, T. S., "Revisiting Spacetrack
Report #3", AIAA 2006-6753 (2006), Appendix C: satellite 00005 on 2000-06-28
15:08:51.655 UTC, ΔUT1 = 0.162360 s, ΔAT = 21 s as published (TT centuries 0.004904360547;
TAI − UTC was 32 s then, and GCS's table says so: 11 s of TT move precession by 2e-5 arcsec):

    r_TEME  = ( 3961.0035498, 6010.7511740, 4619.3009301) km
    r_TOD   = ( 3961.4214985, 6010.4752688, 4619.3015310) km
    r_PEF   = (  298.8036328, -7192.3146229, 4619.3015310) km
    r_J2000 = ( 3961.7442603, 6010.2156109, 4619.3625758) km   (IAU-76/FK5)

The published TEME and TOD vectors differ by 0.60 m along z, which no rotation about z
(the TEME↔TOD relation) can produce: the example is self-consistent to about a metre,
and the tolerances below say so.
"""

from __future__ import annotations

from datetime import UTC, datetime
from pathlib import Path

import numpy as np
import pytest
from repo_paths import TEST_DATA

from gcs_core.ephem import teme
from gcs_core.ephem.ephemeris import Ephemeris
from gcs_core.ephem.orbit import TleOrbit
from gcs_core.ephem.sun import sun_position_km
from gcs_core.ephem.timescale import julian_date
from gcs_core.ephem.tle import read_tle, tle_states
from gcs_core.errors import InputError
from gcs_core.frames.rotations import T2, T3
from gcs_core.io.mission import read_mission_spec
from gcs_core.io.tle_table import tle_ephemeris_table
from gcs_core.units import ARCSEC

TLE = TEST_DATA / "astropi" / "iss-2022-01-31.tle"
EPOCH = datetime(2022, 1, 31, 12, 21, 15, tzinfo=UTC)
one_metre = 1e-3  # km
one_mm = 1e-6  # km

VALLADO_EPOCH = datetime(2000, 6, 28, 15, 8, 51, 655000, tzinfo=UTC)
R_TEME = np.array([3961.0035498, 6010.7511740, 4619.3009301])
R_TOD = np.array([3961.4214985, 6010.4752688, 4619.3015310])
R_PEF = np.array([298.8036328, -7192.3146229, 4619.3015310])
R_J2000 = np.array([3961.7442603, 6010.2156109, 4619.3625758])
DUT1_S = 0.162360
#: the example's own TEME/TOD inconsistency along z [km]
EXAMPLE_Z_MISMATCH = abs(R_TEME[2] - R_TOD[2])
#: the 66 IAU 1980 nutation terms GCS leaves out: ≈ 3 mas RSS; 10 mas (0.4 m at 8560 km)
#: bounds them with margin
TRUNCATION = 10e-3 * ARCSEC * 8560.0


def test_vallado2006_tt_centuries():
    T = teme._tt_centuries(VALLADO_EPOCH, np.array([21.0 - 32.0]))[0]  # the example's ΔAT
    assert T == pytest.approx(0.004904360547, abs=1e-12)


def test_vallado2006_j2000_to_tod_precession_nutation():
    """J2000 → TOD (IAU 1976 precession, IAU 1980 nutation without EOP corrections)."""
    T = teme._tt_centuries(VALLADO_EPOCH, np.array([0.0]))
    zeta, theta, z = teme.precession_angles(T)
    N, _ = teme._mod_to_tod(T, 0.0, 0.0)
    r_tod = (N @ T3(-z) @ T2(theta) @ T3(-zeta) @ R_J2000)[0]
    assert np.linalg.norm(r_tod - R_TOD) < TRUNCATION  # 0.11 m here


def test_vallado2006_teme_to_j2000():
    Q = teme.teme_to_j2000_matrix(VALLADO_EPOCH, [0.0])
    r = teme.rotate_state(Q, R_TEME)[0]
    # 1.13 m: the example's 0.60 m z mismatch plus the matching x, y turn, and truncation
    assert np.linalg.norm(r - R_J2000) < 2 * EXAMPLE_Z_MISMATCH + TRUNCATION


def test_vallado2006_teme_to_pef_is_the_icd_earth_rotation():
    """ICD §2's Earth rotation R3(GMST) applied to TEME gives the published PEF vector;
    with the ICD's UT1 = UTC it is off by the Earth's turn in ΔUT1 = 0.16 s."""
    r = teme.teme_to_pef(VALLADO_EPOCH, [DUT1_S], R_TEME)[0]
    assert np.linalg.norm(r - R_PEF) < 2 * EXAMPLE_Z_MISMATCH  # 1.17 m
    r_icd = teme.teme_to_pef(VALLADO_EPOCH, [0.0], R_TEME)[0]
    turn = 7.292115e-5 * DUT1_S * np.hypot(*R_PEF[:2])  # 85.2 m
    assert np.linalg.norm(r_icd - R_PEF) == pytest.approx(turn, abs=2 * EXAMPLE_Z_MISMATCH)


def test_frame_chain_is_consistent():
    """TEME → J2000 after MOD → TEME is MOD → J2000 (one precession, one nutation)."""
    t = np.array([0.0, 3600.0, 86400.0])
    lhs = teme.teme_to_j2000_matrix(EPOCH, t) @ teme.mod_to_teme_matrix(EPOCH, t)
    np.testing.assert_allclose(lhs, teme.mod_to_j2000_matrix(EPOCH, t), atol=1e-14)


def test_table_rows_are_the_sgp4_package_states():
    """The tabulated rows are the sgp4 package's own TEME states at the same instants."""
    from sgp4.api import Satrec

    l1, l2 = read_tle(TLE)
    sat = Satrec.twoline2rv(l1, l2)
    table = tle_ephemeris_table(TLE, EPOCH, 0.0, 70200.0)
    t = table.t
    ref_r, ref_v = [], []
    for ti in t[::97]:
        whole = np.floor(julian_date(EPOCH, ti) - 0.5) + 0.5
        frac = (EPOCH.timestamp() + ti - (whole - 2440587.5) * 86400.0) / 86400.0
        err, r, v = sat.sgp4(whole, frac)
        assert err == 0
        ref_r.append(r)
        ref_v.append(v)
    r_tab = table.stack(("rx", "ry", "rz"))[::97]
    v_tab = table.stack(("vx", "vy", "vz"))[::97]
    assert np.max(np.linalg.norm(r_tab - np.array(ref_r), axis=1)) < one_mm
    assert np.max(np.linalg.norm(v_tab - np.array(ref_v), axis=1)) < one_mm


def test_interpolated_state_between_rows_matches_sgp4():
    """Between the 10 s rows the Hermite interpolation stays within 5 cm and 5 cm/s of SGP4.
    The orbit's curvature alone would allow 0.3 mm (h⁴ n⁴ |r| / 384); SGP4's velocity is
    not exactly the derivative of its position (3.6 cm/s apart for this TLE), and the
    interpolation, which uses both, inherits ≈ h δv / 4."""
    table = tle_ephemeris_table(TLE, EPOCH, 0.0, 7200.0)
    eph = Ephemeris.from_table(table)
    rng = np.random.default_rng(5)
    t = np.sort(rng.uniform(0.0, 7200.0, 500))
    r_ref, v_ref = TleOrbit(*read_tle(TLE), EPOCH).state(t)
    r, v = eph.state(t)
    assert np.max(np.linalg.norm(r - r_ref, axis=1)) < 50 * one_mm  # 1.9 cm
    assert np.max(np.linalg.norm(v - v_ref, axis=1)) < 50 * one_mm  # km/s: 3.0 cm/s


def test_sun_in_teme_is_the_analytic_sun_turned_by_nutation():
    t = np.array([0.0, 40000.0])
    _, _, sun = tle_states(TleOrbit(*read_tle(TLE), EPOCH), EPOCH, t, "teme")
    mod = sun_position_km(julian_date(EPOCH, t))
    cos = np.sum(sun * mod, axis=1) / np.linalg.norm(sun, axis=1) / np.linalg.norm(mod, axis=1)
    ang = np.arccos(np.clip(cos, -1, 1)) / ARCSEC
    assert np.all(ang < 20.0) and np.all(ang > 0.1)  # nutation + equation of equinoxes


def test_j2000_frame_differs_by_precession():
    t = np.array([0.0])
    orbit = TleOrbit(*read_tle(TLE), EPOCH)
    r_teme, _, _ = tle_states(orbit, EPOCH, t, "teme")
    r_j2k, _, _ = tle_states(orbit, EPOCH, t, "j2000")
    ang = np.arccos(np.dot(r_teme[0], r_j2k[0]) / np.linalg.norm(r_teme) / np.linalg.norm(r_j2k))
    # 22.08 years of general precession (50.29″/yr) projected on this position
    assert 0.0 < np.degrees(ang) < 22.1 * 50.29 / 3600


def _mission(tmp_path, orbit_table: str) -> Path:
    (tmp_path / "telemetry").mkdir()
    (tmp_path / "telemetry" / "M.csv").write_text("t,bx,by,bz\n0,1,2,3\n10,1,2,3\n")
    (tmp_path / "o.tle").write_text(TLE.read_text())
    (tmp_path / "mission.toml").write_text(f"""[mission]
name = "x"
epoch = "2022-01-31T12:21:15Z"
attitude_mode = "earth_pointing"
{orbit_table}
[[sensor]]
name = "M"
type = "magnetometer"
telemetry = "telemetry/M.csv"
alignment_deg = [0, 0, 0]
noise = 100.0
bias = [0, 0, 0]
""")
    return tmp_path


def test_mission_orbit_table(tmp_path):
    spec = read_mission_spec(_mission(tmp_path, '[orbit]\ntle = "o.tle"\nframe = "j2000"\n'))
    assert spec.orbit_tle == tmp_path / "o.tle" and spec.orbit_frame == "j2000"
    assert spec.ephemeris_file is None and spec.orbit_step_s == 10.0


@pytest.mark.parametrize(
    "table, key",
    [
        ('[orbit]\ntle = "o.tle"\nframe = "gcrf"\n', "orbit.frame"),
        ('[orbit]\ntle = "o.tle"\nstep_s = 120\n', "orbit.step_s"),
        ('[orbit]\ntle = "missing.tle"\n', "orbit.tle"),
        ('[orbit]\nframe = "teme"\n', "orbit.tle"),
        ('[orbit]\ntle = "o.tle"\n[ephemeris]\nfile = "e.csv"\n', "orbit"),
    ],
)
def test_mission_orbit_errors_name_the_key(tmp_path, table, key):
    with pytest.raises(InputError) as err:
        read_mission_spec(_mission(tmp_path, table))
    assert err.value.key == key and err.value.line is not None


def test_tle_file_errors(tmp_path):
    p = tmp_path / "x.tle"
    p.write_text("ISS\n1 25544U\n")
    with pytest.raises(InputError, match="expected one element set"):
        read_tle(p)
    lines = TLE.read_text().splitlines()
    p.write_text("\n".join([lines[0], lines[1][:60], lines[2]]))
    with pytest.raises(InputError) as err:
        read_tle(p)
    assert err.value.line == 2


def test_stale_elements_warn(caplog):
    import logging

    with caplog.at_level(logging.WARNING, logger="gcs_core.ephem.tle"):
        tle_ephemeris_table(TLE, EPOCH, 10 * 86400.0, 10 * 86400.0 + 600.0)
    assert "days from the elements' epoch" in caplog.text
    caplog.clear()
    with caplog.at_level(logging.WARNING, logger="gcs_core.ephem.tle"):
        tle_ephemeris_table(TLE, EPOCH, 0.0, 70200.0)
    assert not caplog.text
