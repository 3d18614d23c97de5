"""Asking for an effect the mission cannot have says what it would need.

The magnetometer's field gradient (``MAG.field_gradient``) exists only on a laboratory
mission: a constant field and the sensor's position as aux channels. On a flight mission
the config's request is refused with the config key and both missing conditions named,
rather than "no effect in the state definition".
"""

from __future__ import annotations

import pytest
from repo_paths import SAMPLE_MISSIONS

from gcs_core.errors import ConfigError
from gcs_core.io.importer import load_mission
from gcs_core.problem.build import StateOptions, build_problem

MISSION = SAMPLE_MISSIONS / "nominal-sunpoint"


def test_field_gradient_on_a_flight_mission_names_what_it_needs():
    mission = load_mission(MISSION)
    with pytest.raises(ConfigError) as err:
        build_problem(mission, options=StateOptions(effects=("TAM1.field_gradient",)))
    text = str(err.value)
    assert "not available on this mission" in text
    assert 'field_model = "constant"' in text
    assert "pos_x, pos_y, pos_z" in text
    assert err.value.key == "state.effects"


def test_an_unknown_effect_still_suggests_the_closest():
    mission = load_mission(MISSION)
    with pytest.raises(ConfigError, match="did you mean 'TAM1.nonorthogonality'"):
        build_problem(mission, options=StateOptions(effects=("TAM1.nonorthogonalty",)))
