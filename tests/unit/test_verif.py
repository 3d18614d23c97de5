"""VERIF (seed §3.2.2, §4.4): the §4.4 statistic, the flag rule at its boundaries, slerp,
and whole missions whose onboard attitude carries (or not) an injected error.

Seed §4.4: "If this standard deviation is higher than both the ground attitude
determination accuracy and the attitude accuracy requirement, then a flag will be set",
with ``σ = [Σ (θ_i − θ_g)² / (N − 1)]^{1/2}``.
"""

from __future__ import annotations

import copy
from dataclasses import replace

import numpy as np
import pytest

from gcs_core import units
from gcs_core.config_schema import AnalysisConfig
from gcs_core.frames.rotations import euler123_to_dcm, quat_from_dcm, quat_to_dcm, rotvec_to_dcm
from gcs_core.session import Analysis
from gcs_core.sim.config import OnboardConfig
from gcs_core.sim.scenarios import nominal_threeaxis
from gcs_core.sim.writer import write_mission
from gcs_core.verif.analysis import verify_analysis
from gcs_core.verif.compare import flag_rule, seed_sigma, slerp, verify

one_arcsecond = units.ARCSEC
INJECTED_DEG = 0.05
ROUND_OFF_RAD = 1e-12


# --------------------------------------------------------------------- the rule itself
@pytest.mark.parametrize(
    "sigma, ground, req, expected",
    [
        (1.0001e-4, 1.0e-4, 0.5e-4, True),  # just above the ground accuracy, above the requirement
        (0.9999e-4, 1.0e-4, 0.5e-4, False),  # just below the ground accuracy
        (1.0e-4, 1.0e-4, 0.5e-4, False),  # equal is not "higher than"
        (2.0001e-4, 1.0e-4, 2.0e-4, True),  # just above the requirement, above the ground
        (1.9999e-4, 1.0e-4, 2.0e-4, False),  # just below the requirement
        (5.0e-4, 1.0e-3, 1.0e-4, False),  # exceeds only the requirement
        (5.0e-4, 1.0e-4, 1.0e-3, False),  # exceeds only the ground accuracy
        (np.nan, 1.0e-4, 1.0e-4, False),  # too few points never flags
    ],
)
def test_flag_rule_needs_both_thresholds_strictly(sigma, ground, req, expected):
    assert bool(flag_rule(sigma, ground, req)) is expected


def test_seed_sigma_uses_n_minus_one_and_keeps_the_mean():
    """A constant offset c over N points: σ = c·sqrt(N/(N−1)) (no mean removed)."""
    c, n = 3e-4, 10
    diff = np.full((n, 3), c)
    np.testing.assert_allclose(seed_sigma(diff), c * np.sqrt(n / (n - 1)), rtol=1e-15)
    assert np.all(np.isnan(seed_sigma(diff[:1])))


def test_slerp_reproduces_a_constant_rate_rotation():
    rate = np.array([1e-3, -2e-3, 0.5e-3])  # rad/s
    t_knots = np.arange(0.0, 101.0, 10.0)
    t = np.linspace(0.0, 100.0, 37)
    q_knots = quat_from_dcm(rotvec_to_dcm(rate[None] * t_knots[:, None]))
    exact = quat_from_dcm(rotvec_to_dcm(rate[None] * t[:, None]))
    got = slerp(t_knots, q_knots, t)
    np.testing.assert_allclose(np.abs(np.sum(got * exact, axis=1)), 1.0, atol=1e-12)


# --------------------------------------------------------------------- verify()
def _inertial_pair(n=301, offset_rad=(0.0, 0.0, 0.0), noise_rad=0.0, seed=3):
    rng = np.random.default_rng(seed)
    t = np.arange(n, dtype=float)
    rpy = np.column_stack([0.2 + 1e-4 * t, -0.1 + 2e-4 * t, 0.3 - 1e-4 * t])
    C_g = euler123_to_dcm(rpy[:, 0], rpy[:, 1], rpy[:, 2])
    rpy_ob = rpy + np.asarray(offset_rad)[None] + noise_rad * rng.standard_normal((n, 3))
    C_ob = euler123_to_dcm(rpy_ob[:, 0], rpy_ob[:, 1], rpy_ob[:, 2])
    return t, quat_from_dcm(C_ob), quat_from_dcm(C_g)


def test_verify_flag_at_the_requirement_boundary():
    """A constant yaw offset a: σ_yaw = a·sqrt(N/(N−1)); the requirement just below/above."""
    a = 0.02 * units.DEG
    t, q_ob, q_g = _inertial_pair(offset_rad=(0.0, 0.0, a))
    s_yaw = a * np.sqrt(t.size / (t.size - 1))
    ground = np.full(3, 1e-6)
    below = verify(t, q_ob, t, q_g, ground, requirement_rad=s_yaw * (1 - 1e-6), mode="inertial")
    above = verify(t, q_ob, t, q_g, ground, requirement_rad=s_yaw * (1 + 1e-6), mode="inertial")
    assert below.sigma[2] == pytest.approx(s_yaw, rel=1e-9)
    assert below.flag and list(below.flag_axes) == [False, False, True]
    assert "yaw" in below.reason
    assert not above.flag
    # the same σ against a ground accuracy just above/below it (requirement well under)
    g_hi = verify(t, q_ob, t, q_g, np.full(3, s_yaw * (1 + 1e-6)), requirement_rad=1e-9, mode="inertial")
    g_lo = verify(t, q_ob, t, q_g, np.full(3, s_yaw * (1 - 1e-6)), requirement_rad=1e-9, mode="inertial")
    assert not g_hi.flag and g_lo.flag


def test_verify_interpolates_the_ground_and_reports_a_trend():
    a = INJECTED_DEG * units.DEG
    t, q_ob, q_g = _inertial_pair(n=1201, offset_rad=(0.0, 0.0, 0.0))
    # the onboard attitude goes bad half-way: a roll offset after t = 600 s
    late = t >= 600.0
    _, q_bad, _ = _inertial_pair(n=1201, offset_rad=(a, 0.0, 0.0))
    q_ob = np.where(late[:, None], q_bad, q_ob)
    g_t = t[::5]  # ground every 5 s, slerped to onboard times
    res = verify(
        t,
        q_ob,
        g_t,
        q_g[::5],
        np.full(3, 1 * one_arcsecond),
        requirement_rad=0.01 * units.DEG,
        mode="inertial",
        window_s=300.0,
    )
    slerp_error = 0.2 * one_arcsecond  # Euler angles linear in t are not a constant-rate turn
    np.testing.assert_allclose(res.diff[~late], 0.0, atol=slerp_error)
    np.testing.assert_allclose(res.diff[late][:, 0], a, atol=slerp_error)
    assert res.flag and list(res.flag_axes) == [True, False, False]
    assert list(res.trend_flag) == [False, False, True, True]
    assert res.trend_n.sum() == res.n == t.size
    body = verify(
        t,
        q_ob,
        g_t,
        q_g[::5],
        np.full(3, 1 * one_arcsecond),
        requirement_rad=0.01 * units.DEG,
        mode="inertial",
        angles="body",
    )
    # body axes differ from the roll axis by the Eq 4-22 Jacobian at (0.2, -0.1, 0.3) rad
    assert body.flag and body.sigma[0] == pytest.approx(res.sigma[0], rel=0.1)


# --------------------------------------------------------------------- whole missions
def _rotate_onboard(mission, angle_rad, axis=(1.0, 0.0, 0.0)):
    """Onboard quaternions rotated by ``angle_rad`` about a body axis (C ← exp(−[δ×]) C)."""
    ob = mission.onboard
    q = np.column_stack([ob.columns[c] for c in ("q1", "q2", "q3", "q4")])
    C = rotvec_to_dcm(angle_rad * np.asarray(axis))[None] @ quat_to_dcm(q)
    q2 = quat_from_dcm(C)
    cols = dict(ob.columns)
    cols.update({c: q2[:, i] for i, c in enumerate(("q1", "q2", "q3", "q4"))})
    return replace(mission, onboard=replace(ob, columns=cols))


@pytest.fixture(scope="module")
def sim_pair(tmp_path_factory):
    """The same simulated mission with an exact onboard attitude and with 0.05° injected."""
    root = tmp_path_factory.mktemp("verif")
    out = {}
    for label, err in (("clean", (0.0, 0.0, 0.0)), ("injected", (INJECTED_DEG, 0.0, 0.0))):
        cfg = nominal_threeaxis("sun_pointing", seed=4, duration_s=1800.0, name=f"verif-{label}")
        cfg.onboard = OnboardConfig(cadence_s=10.0, error_deg=err, noise_arcsec=2.0)
        out[label] = write_mission(cfg, root / label)
    return out


def test_simulated_onboard_error_is_flagged_and_clean_one_is_not(sim_pair):
    clean = verify_analysis(
        Analysis(AnalysisConfig(mission=sim_pair["clean"]).with_changes(diagnosis={"holdout_fraction": 0.0}))
    )
    bad = verify_analysis(
        Analysis(AnalysisConfig(mission=sim_pair["injected"]).with_changes(diagnosis={"holdout_fraction": 0.0}))
    )
    assert not clean.flag, clean.reason
    assert np.all(clean.sigma < 0.01 * units.DEG)
    assert bad.flag and bad.flag_axes[0], bad.reason
    assert bad.mean[0] == pytest.approx(INJECTED_DEG * units.DEG, abs=20 * one_arcsecond)
    assert np.all(bad.ground_accuracy < 0.01 * units.DEG)


def test_example_mission_and_its_rotated_onboard_attitude(example_dir):
    """sunpoint-nominal: its onboard yaw differs from the ground fit by about 0.02°, so it
    passes a 0.03° requirement; the same quaternions turned 0.05° about x do not."""
    cfg = AnalysisConfig(mission=example_dir).with_changes(
        diagnosis={"holdout_fraction": 0.0}, verification={"requirement_deg": 0.03}
    )
    analysis = Analysis(cfg)
    ok = verify_analysis(analysis)
    assert not ok.flag, ok.reason
    assert ok.n == len(analysis.mission.onboard)
    rotated = copy.copy(analysis)  # same fit, other onboard file
    rotated.mission = _rotate_onboard(analysis.mission, INJECTED_DEG * units.DEG)
    bad = verify_analysis(rotated)
    assert bad.flag and list(bad.flag_axes) == [True, False, False], bad.reason
    assert bad.sigma[0] == pytest.approx(INJECTED_DEG * units.DEG, rel=0.02)
