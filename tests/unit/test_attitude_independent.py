"""Attitude-independent calibrations of seed §2.1.2 and §2.2.2 on simulated truth."""

from __future__ import annotations

import json

import numpy as np
import pytest

from gcs_core.config_schema import AnalysisConfig
from gcs_core.estimators.batch.attitude_independent import (
    magnetometer_bias_from_magnitude,
    star_tracker_scales_from_separations,
)
from gcs_core.session import Analysis
from gcs_core.sim.scenarios import nominal_threeaxis, with_effect
from gcs_core.sim.writer import write_mission

three_sigma = 3.0


@pytest.fixture(scope="module")
def mission(tmp_path_factory):
    folder = tmp_path_factory.mktemp("indep")
    cfg = nominal_threeaxis("sun_pointing", seed=5, duration_s=5400.0)
    for s in cfg.sensors:
        if s.type == "star_tracker":
            s.cadence_s = 1.0
    cfg = with_effect(cfg, "TAM1.bias", 150.0)
    cfg = with_effect(cfg, "FHST1.scale", 2e-3)
    path = write_mission(cfg, folder / "m", truth_path=folder / "truth.json")
    return Analysis(AnalysisConfig(mission=path)), json.loads((folder / "truth.json").read_text())


def test_tam_bias_from_field_magnitude(mission):
    """§2.1.2: the bias is found from |B| alone, whatever the attitude."""
    a, truth = mission
    res = magnetometer_bias_from_magnitude(a.problem, "TAM1")
    b_true = np.array(truth["sensors"]["TAM1"]["true"]["bias"])
    sig = np.sqrt(np.diag(res.P))
    assert np.all(np.abs(res.x - b_true) <= three_sigma * sig), (res.x, b_true, sig)
    assert 0.8 < res.residual_rms_normalized < 1.2


def test_fhst_scale_from_star_separations(mission):
    """§2.2.2: scale factors from angular separations, independent of attitude and alignment."""
    a, truth = mission
    res = star_tracker_scales_from_separations(a.problem, "FHST1")
    s_true = np.array(truth["sensors"]["FHST1"]["true"]["scale"])
    sig = np.sqrt(np.diag(res.P))
    assert np.all(np.abs(res.x - s_true) <= three_sigma * sig), (res.x, s_true, sig)
    assert np.all(sig < 1e-3)
