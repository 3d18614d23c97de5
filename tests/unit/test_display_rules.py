"""The one display rule for units and labels (gcs_core.display), issue 22 item 6."""

from __future__ import annotations

import pytest

from gcs_core import display
from gcs_core.units import ARCSEC, DEG


def test_a_large_angle_reads_in_degrees():
    """31.8° with an 8.2″ σ was ``114436.9 ± 8.2 arcsec``."""
    text = display.estimate(31.7880 * DEG, 8.2 * ARCSEC, "rad")
    assert text.endswith(" deg") and text.startswith("31.78")
    assert display.estimate(54.0 * ARCSEC, 1.2 * ARCSEC, "rad") == "54.0 ± 1.2 arcsec"


@pytest.mark.parametrize("channel, unit", [("mtb_x", "nT/(A m²)"), ("tam_temp", "nT/°C"), ("pos_x", "nT/aux")])
def test_contamination_in_its_channels_unit(channel, unit):
    assert display.per_channel("nT", channel) == unit


def test_the_magnetometer_declares_its_contamination_in_the_channels_unit():
    from repo_paths import SAMPLE_MISSIONS

    from gcs_core.config import config_for
    from gcs_core.session import Analysis

    mission = SAMPLE_MISSIONS / "hidden-tam-contamination"
    if not (mission / "mission.toml").is_file():
        pytest.skip("sample_data/missions/hidden-tam-contamination is not generated")
    state = Analysis(config_for(mission)).problem.state
    assert state["TAM1.contam_mtb_x_x"].unit == "nT/(A m²)"
    assert state["TAM1.contam_tam_temp_x"].unit == "nT/°C"


@pytest.mark.parametrize("lo, hi", [(0.886, 1.189), (0.9, 1.175), (0.0, 7200.0), (-104.0, 104.0)])
def test_ticks_are_round_and_at_least_two(lo, hi):
    ticks = display.nice_ticks(lo, hi, 4)
    assert len(ticks) >= 2
    labels = display.tick_labels(ticks)
    assert all(len(lab.replace("-", "").replace(".", "")) <= 4 for lab in labels), labels
