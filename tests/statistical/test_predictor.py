"""Predictor (seed §3.1, §3.2, Eq 3-2, Eq 3-4, §4.3): σ without data, against the calibration.

Acceptance: for the same data plan, the predicted σ of every solve-for element matches
the post-fit σ of a batch calibration on simulated data within 15 %. The simulated
mission (gcs_core.sim) flies exactly the plan's attitude: constant roll/pitch/yaw
offsets from Sun pointing, four constant-rate maneuvers (Eq 4-36, no ramps), no
wobble. The remaining differences are the sky (the simulator's catalog against the
predictor's synthetic sky) and the linearization point (nominal against fitted state).
"""

from __future__ import annotations

from dataclasses import replace
from datetime import UTC
from pathlib import Path

import numpy as np
import pytest

from gcs_core.config_schema import AnalysisConfig, ElementConfig, Maneuver
from gcs_core.ephem.orbit import KeplerOrbit
from gcs_core.io.importer import load_mission
from gcs_core.predictor.plan import DataPlan
from gcs_core.predictor.predict import predict
from gcs_core.session import Analysis
from gcs_core.sim.config import Slew, ThreeAxisProfile
from gcs_core.sim.scenarios import nominal_threeaxis
from gcs_core.sim.writer import write_mission
from gcs_core.units import DEG

FIFTEEN_PERCENT = 0.15
SPAN_S = 3600.0
RPY0_DEG = (1.0, 3.0, -2.0)
SLEWS = [
    Slew(792.0, 600.0, "roll", 0.04, ramp_s=0.0),
    Slew(1620.0, 300.0, "pitch", 0.02, ramp_s=0.0),
    Slew(2160.0, 300.0, "yaw", -0.02, ramp_s=0.0),
    Slew(2700.0, 600.0, "roll", -0.04, ramp_s=0.0),
]
MANEUVERS = tuple(Maneuver(s.t_start, s.duration_s, s.axis, s.rate_deg_s) for s in SLEWS)


@pytest.fixture(scope="module")
def sim_dir(tmp_path_factory) -> Path:
    """One hour, Sun pointing, TAM + IRU + 2 FHST + FSS + CSS, the plan's attitude exactly."""
    cfg = nominal_threeaxis("sun_pointing", seed=1, duration_s=SPAN_S)
    cfg.attitude = ThreeAxisProfile(rpy0_deg=RPY0_DEG, wobble_amp_deg=(0.0, 0.0, 0.0), slews=list(SLEWS))
    return write_mission(cfg, tmp_path_factory.mktemp("sim") / "plan-mission")


@pytest.fixture(scope="module")
def sim_mission(sim_dir):
    return load_mission(sim_dir)


def the_plan(**kw) -> DataPlan:
    base = dict(start=0.0, end=SPAN_S, step=60.0, maneuvers=MANEUVERS, rpy0=tuple(a * DEG for a in RPY0_DEG))
    base.update(kw)
    return DataPlan(**base)


def test_plan_prediction_matches_simulated_calibration_within_15_percent(sim_dir):
    analysis = Analysis(AnalysisConfig(mission=sim_dir).with_changes(diagnosis={"holdout_fraction": 0.0}))
    fit = analysis.fit(holdout=False)
    assert fit.status == "converged"
    pred = predict(analysis, plan=the_plan())
    assert pred.names == fit.solve_for
    ratio = pred.noise_only / np.sqrt(np.diag(fit.P))
    worst = int(np.argmax(np.abs(ratio - 1.0)))
    assert np.all(np.abs(ratio - 1.0) < FIFTEEN_PERCENT), (pred.names[worst], ratio[worst])
    # the plan's data modeling finds the frames the simulator delivered (eclipse, FOV,
    # tracker exclusions), within 1 %
    for name, r in fit.residuals.items():
        assert pred.frames[name] == pytest.approx(r.n, rel=0.01), name


def test_problem_frames_reproduce_batch_covariance_and_ignore_values(example_dir):
    """Seed Eq 3-2 at the solution is the batch covariance: predicting the example
    mission's own frames (values ignored) gives the fit's P."""
    analysis = Analysis(
        AnalysisConfig(mission=example_dir, method="batch").with_changes(
            diagnosis={"holdout_fraction": 0.0}, filter={"edit_k": 0.0}
        )
    )
    fit = analysis.fit(holdout=False)
    problem = analysis.problem.with_state(fit.state)
    pred = predict(problem)
    np.testing.assert_allclose(pred.P, fit.P, rtol=1e-6, atol=0.0)
    # the default whole-span fit: its covariance (knots eliminated) is predicted the same way
    # (the prediction linearizes with the knot corrections at zero: agreement to 1 %)
    a_ws = Analysis(
        AnalysisConfig(mission=example_dir).with_changes(diagnosis={"holdout_fraction": 0.0}, filter={"edit_k": 0.0})
    )
    ws = a_ws.fit(holdout=False)
    pred_ws = predict(a_ws.problem.with_state(ws.state), method="whole_span")
    np.testing.assert_allclose(np.sqrt(np.diag(pred_ws.P)), np.sqrt(np.diag(ws.P)), rtol=1e-2)
    # the measured values play no part
    problem.sensors = [replace(sd, y=np.zeros_like(sd.y)) for sd in problem.sensors]
    again = predict(problem)
    np.testing.assert_array_equal(again.sigma, pred.sigma)
    assert pred.method == "information"


def test_consider_budget_matches_batch_and_adds_up(sim_dir):
    cfg = AnalysisConfig(mission=sim_dir, method="batch").with_changes(
        diagnosis={"holdout_fraction": 0.0},
        filter={"edit_k": 0.0},
        state={"elements": {f"TAM1.bias_{a}": ElementConfig(role="consider") for a in "xyz"}},
    )
    analysis = Analysis(cfg)
    fit = analysis.fit(holdout=False)
    pred = predict(analysis.problem.with_state(fit.state))
    assert set(pred.budget) == {"TAM1.bias_x", "TAM1.bias_y", "TAM1.bias_z"}
    for c, contrib in pred.budget.items():
        np.testing.assert_allclose(contrib, fit.consider_budget[c], rtol=1e-6, atol=1e-300)
    # σ² = noise-only² + Σ consider contributions² (uncorrelated error sources)
    total2 = pred.noise_only**2 + sum(v**2 for v in pred.budget.values())
    np.testing.assert_allclose(pred.sigma[-1] ** 2, total2, rtol=1e-9)
    rows = pred.budget_rows()
    assert rows[0]["name"] == "att.roll" and set(rows[0]["consider"]) == set(pred.budget)


def test_gaps_make_sigma_larger(sim_mission):
    plain = predict(sim_mission, plan=the_plan(end=1800.0))
    gapped = predict(sim_mission, plan=the_plan(end=1800.0, gaps=((300.0, 1200.0),)))
    assert gapped.frames["TAM1"] < plain.frames["TAM1"]
    assert gapped.availability["FSS1"] < plain.availability["FSS1"]
    relative_round_off = 1e-9
    assert np.all(gapped.sigma[-1] >= plain.sigma[-1] * (1 - relative_round_off))
    assert gapped.sigma_of("TAM1.bias_x")[-1] > 1.1 * plain.sigma_of("TAM1.bias_x")[-1]
    # information only accumulates: every static σ history is non-increasing
    assert np.all(np.diff(plain.sigma, axis=0) <= plain.sigma[1:] * relative_round_off)


def test_roll_maneuver_makes_gyro_alignment_observable(sim_dir):
    """Gyro misalignment about y and z shows only while the body turns about x."""
    cfg = AnalysisConfig(mission=sim_dir).with_changes(
        state={"effects": ("IRU.alignment",), "exclude": ("IRU.scale_misalignment",)}
    )
    still = predict(cfg, plan=the_plan(end=1500.0, maneuvers=()))
    rolled = predict(cfg, plan=the_plan(end=1500.0, maneuvers=(Maneuver(600.0, 600.0, "roll", 0.04),)))
    prior = 1e-3  # the gyro alignment's a-priori σ [rad]
    for k in (2, 3):
        assert still.sigma_of(f"IRU.align_{k}")[-1] > 0.9 * prior
        assert rolled.sigma_of(f"IRU.align_{k}")[-1] < 0.1 * prior
    assert rolled.sigma_of("IRU.align_1")[-1] > 0.9 * prior  # a roll says nothing about x


def test_kalman_recursion_without_process_noise_equals_information_form(sim_mission):
    """Eq 3-4 with Q = 0 is Eq 3-2 carried to the current time."""
    spec = sim_mission.spec
    quiet = tuple(replace(s, book={**s.book, "arw": 0.0, "rrw": 0.0}) if s.type == "gyro" else s for s in spec.sensors)
    mission = replace(sim_mission, spec=replace(spec, sensors=quiet))
    plan = the_plan(end=1500.0, maneuvers=(Maneuver(600.0, 600.0, "roll", 0.04),))
    info = predict(mission, plan=plan)
    kal = predict(mission, plan=plan, method="kalman")
    assert kal.method == "kalman"
    params = [i for i, n in enumerate(info.names) if not n.startswith("att.")]
    np.testing.assert_allclose(kal.sigma[:, params], info.sigma[:, params], rtol=1e-6)
    np.testing.assert_allclose(kal.attitude_sigma, info.attitude_sigma, rtol=1e-6)
    # the real gyro noise only adds uncertainty to the attitude
    noisy = predict(sim_mission, plan=plan, method="kalman")
    assert np.all(noisy.attitude_sigma[-1] > info.attitude_sigma[-1])


def test_prelaunch_prediction_from_an_orbit(sim_mission):
    """No ephemeris file: a Kepler orbit and the analytic Sun (build_ephemeris)."""
    spec = replace(sim_mission.spec, ephemeris_file=None)
    orbit = KeplerOrbit(6898.137, 0.0012, 28.5, 35.0, 60.0, 10.0, spec.epoch)
    pred = predict(spec, plan=the_plan(end=6000.0), orbit=orbit)
    assert pred.availability["TAM1"] == 1.0
    assert 0.3 < pred.availability["FSS1"] < 0.9  # eclipse: no Sun data
    assert np.all(np.isfinite(pred.sigma[-1]))
    with pytest.raises(Exception, match="ephemeris"):
        predict(spec, plan=the_plan(end=6000.0))


def test_prelaunch_spinner_from_the_data_book_alone(tmp_path):
    """A spinner described only by its data book (no files): one frame per spin, the spin
    rate from ``spin_rate_rpm``, no frames in shadow (the horizon timing needs the Sun)."""
    from datetime import datetime

    from gcs_core.io.types import MissionSpec, SensorSpec

    pss = SensorSpec(
        "PSS1",
        "plane_field_sun",
        tmp_path / "none.csv",
        noise=np.radians(0.05),
        book={"tilt_deg": 0.0, "bias": 0.0, "spin_rate_rpm": 10.0},
    )
    hs = SensorSpec(
        "HS1",
        "horizon",
        tmp_path / "none.csv",
        noise=0.0015,
        book={"gamma_deg": 80.0, "phi_h_deg": 40.0, "horizon_height_km": 40.0, "sun_sensor": "PSS1"},
    )
    epoch = datetime(2024, 9, 2, 10, tzinfo=UTC)
    spec = MissionSpec(tmp_path, "spinner", epoch, "spinning", None, (pss, hs), spin_axis_guess_deg=(320.0, 50.0))
    orbit = KeplerOrbit(7078.137, 0.001, 28.5, 35.0, 60.0, 10.0, epoch)
    pred = predict(spec, plan=DataPlan(0.0, 7200.0, step=600.0), orbit=orbit)
    spin_period = 6.0
    assert pred.frames["PSS1"] <= 7200.0 / spin_period
    assert 0.3 < pred.availability["PSS1"] < 1.0
    assert 0 < pred.frames["HS1"] <= pred.frames["PSS1"]
    prior = 1.0 * DEG
    assert pred.sigma_of("att.ra")[-1] < 0.1 * prior and pred.sigma_of("att.dec")[-1] < 0.1 * prior
    assert pred.sigma_of("att.ra")[0] == pytest.approx(prior)  # no data yet at the start


def test_an_element_without_prior_is_infinite_until_data_arrive(sim_dir):
    cfg = AnalysisConfig(mission=sim_dir).with_changes(
        state={"elements": {"TAM1.bias_x": ElementConfig(sigma=float("inf"))}}
    )
    pred = predict(cfg, plan=the_plan(end=600.0, gaps=((0.0, 300.0),)))
    s = pred.sigma_of("TAM1.bias_x")
    before, after = pred.times < 300.0, pred.times >= 300.0
    assert np.all(np.isinf(s[before])) and np.all(np.isfinite(s[after]))
    assert np.all(np.isfinite(pred.sigma_of("att.roll")))
