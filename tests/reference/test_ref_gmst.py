"""Reference tests for mission time: GMST (IAU 1982), Julian dates, decimal years, epochs."""

from datetime import UTC, datetime

import numpy as np
import pytest

from gcs_core import units
from gcs_core.ephem import timescale as ts
from gcs_core.errors import InputError

one_arcsecond = units.ARCSEC
one_microsecond_of_day = 1e-6 / 86400.0  # [day]


def test_vallado_example_3_5_gmst():
    """Vallado, *Fundamentals of Astrodynamics and Applications*, 4th ed. (2013), Example 3-5
    (p. 188): 1992 August 20, 12:14:00 UT1 -> theta_GMST = 152.578787810 deg.

    (Earlier editions print 152.578787886 deg for the same example; the two differ by
    0.0003 arcsec.) UT1 = UTC here, as ICD §2 prescribes.
    """
    published_deg = 152.578787810
    gmst = ts.gmst_rad("1992-08-20T12:14:00Z", [0.0])
    assert gmst.shape == (1,)
    assert abs(np.degrees(gmst[0]) - published_deg) * units.DEG < 0.001 * one_arcsecond


def test_gmst_at_j2000_is_the_constant_term():
    """IAU 1982 (Aoki et al. 1982): GMST at J2000.0 (2000-01-01 12:00 UT1) is
    18h 41m 50.54841s = 280.46061837 deg, the constant term of the expression."""
    gmst = ts.gmst_rad(ts.J2000, 0.0)
    expected = 67310.54841 / 86400.0 * 2.0 * np.pi
    assert abs(gmst - expected) < 0.001 * one_arcsecond


def test_gmst_rate_is_the_sidereal_rate():
    """dGMST/dt = 2pi/86400 (1 + 8640184.812866/(86400*36525)) ~ 7.2921158e-5 rad/s (WGS-84
    omega = 7.292115e-5 rad/s to its printed digits)."""
    t = np.array([0.0, 3600.0])
    g = np.unwrap(ts.gmst_rad("2024-03-20T06:00:00Z", t))
    rate = (g[1] - g[0]) / 3600.0
    assert abs(rate - units.OMEGA_EARTH) < 1e-12 + 1e-6 * units.OMEGA_EARTH


def test_gmst_is_vectorized_and_consistent_across_epochs():
    """The same instant reached from two epochs gives the same GMST (precision of the
    seconds-since-J2000 bookkeeping), here 600k samples over a week."""
    t = np.linspace(0.0, 7 * 86400.0, 600_000)
    a = ts.gmst_rad("2024-03-20T06:00:00Z", t)
    b = ts.gmst_rad("2024-03-19T06:00:00Z", t + 86400.0)
    d = np.angle(np.exp(1j * (a - b)))
    assert a.shape == t.shape
    assert np.max(np.abs(d)) < 1e-4 * one_arcsecond
    assert np.all((a >= 0.0) & (a < 2.0 * np.pi))


def test_vallado_example_3_4_julian_date():
    """Vallado 4th ed., Example 3-4: 1996 October 26, 14:20:00 UT -> JD 2450383.09722222."""
    jd = ts.julian_date("1996-10-26T14:20:00Z", 0.0)
    assert abs(jd - 2450383.09722222) < 1e-8
    whole, frac = ts.julian_date_parts("1996-10-26T14:20:00Z", np.array([0.0, 36000.0]))
    assert whole[0] == 2450382.5 and abs(frac[0] - 14 / 24 - 20 / 1440) < one_microsecond_of_day
    assert whole[1] == 2450383.5  # crossed midnight
    assert np.all((frac >= 0.0) & (frac < 1.0))


def test_julian_date_of_known_instants():
    """J2000.0 is JD 2451545.0; 2006-04-02 00:00 UTC is JD 2453827.5 (Vallado Example 5-1)."""
    assert ts.julian_date(ts.J2000, 0.0) == 2451545.0
    assert ts.julian_date("2006-04-02T00:00:00Z", 0.0) == 2453827.5
    assert ts.days_since_j2000("2000-01-02T12:00:00Z", 0.0) == 1.0


def test_decimal_year_convention():
    """IGRF convention: year + elapsed/length of that year (2024 has 366 days)."""
    ep = "2024-01-01T00:00:00Z"
    day = 86400.0
    y = ts.decimal_year(ep, np.array([0.0, 183 * day, 366 * day, 366 * day + 365 * day / 2]))
    np.testing.assert_allclose(y, [2024.0, 2024.5, 2025.0, 2025.5], atol=1e-12)
    # spans crossing new year backwards as well
    assert abs(ts.decimal_year("2025-01-01T00:00:00Z", -183 * day) - 2024.5) < 1e-12


@pytest.mark.parametrize(
    "text, expected",
    [
        ("2024-03-20T06:00:00Z", datetime(2024, 3, 20, 6, tzinfo=UTC)),
        ("2024-03-20T06:00:00.250Z", datetime(2024, 3, 20, 6, 0, 0, 250000, tzinfo=UTC)),
        ("2024-03-20 06:00:00", datetime(2024, 3, 20, 6, tzinfo=UTC)),
        ("2024-03-20T08:00:00+02:00", datetime(2024, 3, 20, 6, tzinfo=UTC)),
        ("2024-03-20", datetime(2024, 3, 20, tzinfo=UTC)),
    ],
)
def test_parse_epoch_accepts_iso_utc(text, expected):
    got = ts.parse_epoch(text, key="mission.epoch")
    assert got == expected and got.tzinfo is not None


def test_parse_epoch_accepts_datetime():
    """TOML's native datetimes arrive as datetime objects; naive ones are UTC."""
    assert ts.parse_epoch(datetime(2024, 3, 20, 6)) == datetime(2024, 3, 20, 6, tzinfo=UTC)


@pytest.mark.parametrize("bad", ["yesterday", "2024-13-01T00:00:00Z", "2024-02-30", "", 42])
def test_parse_epoch_refuses_bad_text_naming_the_key(bad):
    with pytest.raises(InputError) as err:
        ts.parse_epoch(bad, key="mission.epoch")
    assert "mission.epoch" in str(err.value)
    assert "\n" not in str(err.value)
