"""Honest precision and units at the edge (gcs_core.display, as the TUI shows numbers).

Rule: σ keeps two significant digits and the value is rounded to σ's last digit;
angles are shown in arcsec while σ is below one degree and in degrees above, rates in deg/h (a
body rate from 1°/s in deg/s). The expected strings are worked out by hand from that rule.
"""

from __future__ import annotations

import math

import pytest

from gcs_core import display as fmt
from gcs_core.units import ARCSEC, DEG


@pytest.mark.parametrize(
    "value, sigma, unit, expected",
    [
        (12.3456, 0.0234, "nT", "12.346 ± 0.023 nT"),
        (2e-5, 1.1e-5, "rad", "4.1 ± 2.3 arcsec"),  # 4.125″ ± 2.269″
        (math.pi / 2 + 1e-5, 1.32e-5, "rad", "90.00057 ± 0.00076 deg"),  # from 10° in degrees (issue 22)
        (0.99996, 4.3e-5, "1", "0.999960 ± 0.000043"),
        (1.23e-5, 1.1e-6, "1", "(1.23 ± 0.11)e-5"),
        (-0.0647, 0.0299, "s", "-0.065 ± 0.030 s"),
        (12345.6, 1234.0, "nT", "12300 ± 1200 nT"),
        (-2e-5 * DEG, 1.0 * DEG, "rad", "0.0 ± 1.0 deg"),  # no "-0.0"
    ],
)
def test_estimate_keeps_two_digits_of_sigma(value, sigma, unit, expected):
    assert fmt.estimate(value, sigma, unit) == expected


def test_rates_in_degrees_per_hour():
    one_deg_per_hour = DEG / 3600.0
    assert fmt.quantity(2 * one_deg_per_hour, "rad/s", digits=2) == "2.0 deg/h"


def test_display_round_trip():
    shown = fmt.display_unit("rad", 5 * ARCSEC)
    assert shown == "arcsec"
    assert fmt.from_display(fmt.to_display(5 * ARCSEC, "rad", shown), "rad", shown) == pytest.approx(
        5 * ARCSEC, rel=1e-15
    )


def test_missing_sigma_and_statistics():
    assert fmt.estimate(3.0, math.inf, "nT") == "3.00000 ± ∞ nT"
    assert fmt.pvalue(1e-30) == "< 1e-16"
    assert fmt.fixed(float("nan"), 3) == "—"
    assert fmt.fixed(-0.04, 1) == "0.0"


def test_a_body_rate_reads_in_degrees_per_second():
    """A rate from 1°/s (a hand turning a unit, a spinner) is in deg/s, value or σ; a gyro's
    bias stays in deg/h (BROAD's body rate read −458144 deg/h before this rule)."""
    assert fmt.estimate(-127.26 * DEG, 0.0021 * DEG, "rad/s") == "-127.2600 ± 0.0021 deg/s"
    assert fmt.estimate(0.5 * DEG, 2.0 * DEG, "rad/s").endswith(" deg/s")
    assert fmt.estimate(2.0 * DEG / 3600.0, 0.01 * DEG / 3600.0, "rad/s") == "2.000 ± 0.010 deg/h"
