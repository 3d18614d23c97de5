"""Discovery past the catalogue (issue 26), a seeded slice: one seed per kind, 4 h.

For each hidden drift of :mod:`drift_cases`: the first effect added is on the right sensor
and made on the right channel (or the orbit phase, which a temperature following the
orbit is an alias of); nothing is added on another sensor; every sensor ends at most 1.05
normalized RMS, fitted and held-out; the family's elements are within 3σ of the truth.
The form no family holds (a tracker error following the star's magnitude) is named by the
search and adds nothing. A nominal mission adds nothing. The gyro's bias stepping with its
heater is checked at 8 h too, and a mission whose heater switches without moving the bias
adds nothing. The rates over many seeds are ``benchmarks/discovery_past_catalogue.py``'s.
"""

from __future__ import annotations

import pytest
from drift_cases import KINDS, MAGNITUDE, DriftCase, analyse, outcome, simulate

from gcs_core.reporting import analysis_report

HOURS = 4.0
#: normalized RMS bound, fitted and held-out (issue 3's noise floor)
RMS_BOUND = 1.05
#: |estimate − truth| / σ allowed per element
Z_BOUND = 3.0


GYRO = next(c for c in KINDS if c.kind == "gyro_heater")
SLICE = [(c, HOURS) for c in KINDS] + [(GYRO, 8.0)]


@pytest.mark.slow
@pytest.mark.parametrize(("case", "hours"), SLICE, ids=[f"{c.id}-{h:g}h" for c, h in SLICE])
def test_drift_found_on_the_right_sensor_and_channel(case, hours, tmp_path):
    a = analyse(simulate(case, 1, tmp_path, hours))
    out = outcome(case, a)
    assert out["right_sensor_channel"], f"{case.kind}: added {out['added']}; {a.stop_reason}"
    assert not out["other_sensors"], f"{case.kind}: also added {out['other_sensors']}"
    assert out["rms"] <= RMS_BOUND, a.rms()
    assert out["holdout_rms"] <= RMS_BOUND, a.holdout_rms
    for name, z in out["z"].items():
        assert abs(z) <= Z_BOUND, f"{name}: {z:.2f} σ from the truth"
    rep = analysis_report(a, command="discover")
    assert rep["residual_structure"] is not None


@pytest.mark.slow
def test_a_form_no_family_holds_is_named_and_adds_nothing(tmp_path):
    a = analyse(simulate(MAGNITUDE, 1, tmp_path, HOURS))
    assert [s.effect for s in a.steps if s.action == "add"] == []
    rep = a.structure_report
    assert rep is not None
    found = [(d.sensor, d.channel) for d in rep.found]
    assert found and found[0] == ("FHST2", "tlm:mag"), found
    assert {s for s, _ in found} == {"FHST2"}


@pytest.mark.slow
def test_nominal_mission_adds_nothing_and_finds_nothing(tmp_path):
    a = analyse(simulate(None, 1, tmp_path, HOURS))
    assert [s.effect for s in a.steps if s.action == "add"] == []
    assert a.structure_report is not None and not a.structure_report.found


@pytest.mark.slow
def test_a_heater_that_does_not_move_the_bias_adds_nothing(tmp_path):
    """The gyro's score test on the switch is a test at the family-wise level, not a detector
    that always fires: with the heater switching and no bias step, nothing is added."""
    null = DriftCase("gyro_heater_null", "IRU.bias_vs_iru_heater", 0.0, "IRU", ("aux:iru_heater",))
    a = analyse(simulate(null, 1, tmp_path, HOURS))
    assert [s.effect for s in a.steps if s.action == "add"] == []
    assert a.structure_report is not None and not a.structure_report.found


@pytest.mark.slow
@pytest.mark.parametrize("seed", [6, 11])
def test_a_misfit_trackers_error_is_not_blamed_on_the_sun_sensor(seed, tmp_path):
    """8 h: the tracker's magnitude error tilts the attitude slowly and the Sun sensor,
    within its noise, then follows time too. Seed 6: the tracker's own drift families go
    first (blame rule 3); seed 11: the Sun sensor's drift, left with the tracker out of the
    fit, is no longer significant (rule 4). Nothing is added on another sensor."""
    a = analyse(simulate(MAGNITUDE, seed, tmp_path, 8.0))
    added = [s.effect for s in a.steps if s.action == "add"]
    assert all(e.startswith("FHST2.") for e in added), added
