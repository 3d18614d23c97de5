"""The plan space of trade studies: what each key does to the config, mission and plan."""

from __future__ import annotations

import pytest
from repo_paths import ROOT

from gcs_core.config import load_config
from gcs_core.errors import InputError
from gcs_core.io.mission import read_mission_spec
from gcs_core.predictor.plan import DataPlan
from gcs_core.trade import space
from gcs_core.trade.study import sensor_axes_covariance

CONFIG = ROOT / "sample_data" / "trade" / "smm-fhst.toml"


@pytest.fixture(scope="module")
def base():
    cfg = load_config(CONFIG)
    spec = read_mission_spec(cfg.mission)
    return cfg, spec, DataPlan.from_config(cfg)


def test_passes_become_gaps(base):
    s = space.apply(*base, {"passes": 2, "pass_min": 10, "separation_min": 30, "start_min": 5})
    assert (s.plan.start, s.plan.end) == (300.0, 300.0 + 50 * 60.0)
    assert s.plan.gaps == ((300.0 + 600.0, 300.0 + 2400.0),)


def test_maneuver_keys(base):
    s = space.apply(
        *base,
        {
            "maneuver.axis": "roll",
            "maneuver.rate_deg_s": 0.1,
            "maneuver.angle_deg": 30,
            "maneuver.start_min": 10,
            "maneuver.back": True,
        },
    )
    (out, back) = s.plan.maneuvers
    assert (out.axis, out.start, out.duration, out.rate_deg_s) == ("roll", 600.0, 300.0, 0.1)
    assert (back.start, back.rate_deg_s) == (900.0, -0.1)
    seq = space.apply(*base, {"span_min": 60, "maneuvers": "roll:0.1:5,yaw:-0.1:5"}).plan.maneuvers
    assert [(m.axis, m.start, m.duration) for m in seq] == [("roll", 1500.0, 300.0), ("yaw", 1800.0, 300.0)]
    with pytest.raises(InputError, match="axis:rate_deg_s:minutes"):
        space.apply(*base, {"maneuvers": "roll:fast"})


def test_sensor_keys(base):
    s = space.apply(
        *base,
        {
            "models.FHST2": "off",
            "FHST1.alignment_deg[2]": 5.0,
            "FHST1.noise": 1e-5,
            "IRU.arw": 1e-6,
            "effects": "FHST1.alignment+TAM1.alignment",
        },
    )
    assert s.config.models["FHST2"] == "off"
    fh = s.spec.sensor("FHST1")
    assert fh.alignment_deg[1] == 5.0 and fh.noise == 1e-5
    assert s.spec.sensor("IRU").book["arw"] == 1e-6
    assert "FHST1.alignment" in s.config.state.effects and "TAM1.alignment" not in s.config.state.effects  # TAM1 is off
    d = s.describe()
    assert d["sensors"]["FHST2"]["on"] is False and d["sensors"]["FHST1"]["alignment_deg"][1] == 5.0


def test_unknown_key_named(base):
    cfg, spec, _ = base
    with pytest.raises(InputError, match="trade.vary.FHST9.noise"):
        space.check_key("FHST9.noise", spec)
    with pytest.raises(InputError, match="unknown key"):
        space.check_key("colour", spec)


def test_misalignment_about_the_sensor_axes(base):
    """FHST1 is mounted with a3 = 90°: a small a1 turns about body x, which is the sensor's −y;
    a2 turns about the sensor's x (the boresight)."""
    import numpy as np

    _, spec, _ = base
    P = np.diag([1.0, 4.0, 9.0])
    Q = sensor_axes_covariance(spec, "FHST1", P)
    assert np.allclose(np.diag(Q), [4.0, 1.0, 9.0])
    assert spec.sensor("FHST1").alignment_deg[2] == pytest.approx(90.0)
