"""The gyro's read-out noise σ_e carried by the default (whole-span) fit, against truth (issue 10, point 1).

A 4 h Sun-pointing mission of ``gcs_core.sim`` with a flight-typical IRU (σ_v = 3.162e-7
rad/√s, σ_u = 3.162e-10 rad/s^1.5) whose integrated angle is read with a white error σ_e
(ICD §5 ``electronic``): the simulator adds ``(e_k − e_{k−1})/Δ`` to the rates, so the
attitude the gyro carries is off by a white ``e_k`` at every sample, shared by every
sensor's rows of that epoch (:mod:`gcs_core.estimators.whole_span.readout`). Two levels: σ_e equal to
the star trackers' noise (3.88e-5 rad) and three times it, where the read-out error
dominates every tracker row.

With σ_e carried (the data book = truth):

* every sensor's normalized RMS (each row against its marginal σ, ``sqrt(σ² + σ_e²|D|²)``)
  within ``1 ± 4/sqrt(2 m_s)`` plus its leverage share (m_s its measurements: the RMS² of
  m_s unit normals scatters by ``sqrt(2/m_s)``), and the χ² of the whole fit on its
  effective dof with p not small (> 1e-3);
* every calibrated element within 3σ of the simulator's truth, and the NEES of all of them
  (full covariance) inside its 95 % χ²_k band. The attitude elements are the gyro-carried
  trajectory's reference, which differs from the true attitude at ``t_ref`` by that epoch's
  read-out error: σ_e² is added to their variance for the comparison.

The same data fitted as if the book had no σ_e (``noise=GyroNoise(σ_v, σ_u, 0)``) is
dishonest: the trackers' RMS and χ² far above the noise (p < 1e-6), and the trackers'
scale σ optimistic (smaller than the honest fit's). And ``gcs discover`` on it adds nothing
(the corrected body rate: without it four time offsets and a harmonic were added). The
predicted σ against the scatter
over seeds, and the Kalman filter's σ beside them, are in ``benchmarks/monte_carlo_consistency.py
--electronic`` (docs/benchmarks.md).

Seeds: the simulator's seed 1 for both levels, chosen before looking.
"""

from __future__ import annotations

import json
import math

import honesty_cases as hc
import numpy as np
import pytest
from scipy import stats
from test_truth_recovery import _angle_diff, truth_values

from gcs_core.config_schema import AnalysisConfig
from gcs_core.diagnosis.goodness import goodness_of_fit
from gcs_core.estimators.kalman.mekf import attitude_gyro_noise
from gcs_core.estimators.whole_span.fit import whole_span_fit
from gcs_core.models.gyro_noise import GyroNoise
from gcs_core.session import Analysis
from gcs_core.sim.scenarios import nominal_threeaxis
from gcs_core.sim.writer import write_mission

FOUR_HOURS = 4 * 3600.0
SEED = 1
#: the star trackers' noise in the scenario [rad] (8 arc-seconds)
TRACKER_NOISE = 3.878509e-05
three_sigma = 3.0
#: a χ² p-value below this is "small"
small_p = 1e-3
#: ... and below this the fit is plainly inadequate
tiny_p = 1e-6


def _mission(tmp_path, sigma_e: float):
    cfg = nominal_threeaxis("sun_pointing", seed=SEED, duration_s=FOUR_HOURS)
    for s in cfg.sensors:
        if s.type == "gyro":
            s.book["electronic"] = sigma_e
    mission = write_mission(cfg, tmp_path / "mission", truth_path=tmp_path / "truth.json")
    return mission, json.loads((tmp_path / "truth.json").read_text())


def _errors(res, truth: dict, sig_e2: float):
    """(names, x̂ − x, covariance with σ_e² on the attitude) over the elements with a truth."""
    names = [n for n in res.solve_for if n in truth]
    idx = [res.solve_for.index(n) for n in names]
    e = np.array(
        [_angle_diff(res.x[i], truth[n]) if n.startswith("att.") else res.x[i] - truth[n] for n, i in zip(names, idx)]
    )
    P = np.asarray(res.P)[np.ix_(idx, idx)].copy()
    for j, n in enumerate(names):
        if n.startswith("att."):
            P[j, j] += sig_e2
    return names, e, P


@pytest.mark.parametrize("ratio", [1.0, 3.0], ids=["sigma_e=tracker", "sigma_e=3x_tracker"])
def test_whole_span_fit_carries_the_read_out_noise(ratio, tmp_path):
    sigma_e = ratio * TRACKER_NOISE
    mission, truth = _mission(tmp_path, sigma_e)
    a = Analysis(AnalysisConfig(mission=mission))  # the default estimator
    res = a.fit(holdout=False)
    assert res.dynamics is not None and res.dynamics.sig_e2 == pytest.approx(sigma_e**2)
    assert "read-out noise" in res.message

    gof = goodness_of_fit(a.problem, res)
    assert gof.fit.p_value > small_p, gof.verdict
    for name, t in gof.sensors.items():
        m = t.n
        rms = res.residuals[name].rms_normalized
        bound = 4.0 / math.sqrt(2.0 * m) + (m - t.dof) / m
        assert abs(rms - 1.0) <= bound, (name, rms, bound)

    tv = truth_values(truth, a.problem, "whole_span")
    names, e, P = _errors(res, tv, sigma_e**2)
    z = e / np.sqrt(np.diag(P))
    outside = {n: round(float(v), 2) for n, v in zip(names, z) if abs(v) > three_sigma}
    assert not outside, f"outside 3σ of truth: {outside}"
    nees = float(e @ np.linalg.solve(P, e))
    lo, hi = stats.chi2.ppf([0.025, 0.975], len(names))
    assert lo < nees < hi, (nees, lo, hi, len(names))

    # the same data, the read-out noise ignored: residuals above the noise, σ optimistic
    book = attitude_gyro_noise(a.problem)
    blind = whole_span_fit(a.problem, a.batch_options(), noise=GyroNoise(book.sigma_v, book.sigma_u, 0.0))
    assert blind.dynamics is not None and blind.dynamics.sig_e2 == 0.0
    gof_blind = goodness_of_fit(a.problem, blind)
    assert gof_blind.fit.p_value < tiny_p, gof_blind.verdict
    for tracker in ("FHST1", "FHST2"):
        assert blind.residuals[tracker].rms_normalized > 1.2
        for c in ("scale_h", "scale_v"):
            el = f"{tracker}.{c}"
            assert blind.sigma[el] < res.sigma[el], (el, blind.sigma[el], res.sigma[el])


def test_discovery_adds_nothing_under_read_out_noise(tmp_path):
    """``gcs discover`` (the default config) on the nominal 4 h mission with σ_e = the
    trackers' noise adds no effect, and every calibrated element stays within 3σ of truth.
    Linearized with the gyro's raw rate, the time-tag offsets' partials ``−ω × v`` carried
    ``(e_k − e_{k−1})/Δ`` and discovery added FSS1.time_offset, FSS1.harmonic and both
    trackers' time offsets on every seed tried (readout.py, the corrected body rate)."""
    cfg = hc.nominal("sun_pointing", SEED, FOUR_HOURS / 3600.0)
    for s in cfg.sensors:
        if s.type == "gyro":
            s.book["electronic"] = TRACKER_NOISE
    rec = hc.run_discovery(cfg, tmp_path, "whole_span")
    assert rec["status"] == "ok", rec["status"]
    assert rec["added"] == [], rec["added"]
    outside = {k: round(v, 2) for k, v in hc.calibrated_z(rec).items() if abs(v) > three_sigma}
    assert not outside, outside
    assert rec["adequate"], rec["verdict"]


def test_kalman_residuals_are_normalized_by_the_marginal_sigma(tmp_path):
    """The Kalman method's residuals against the same marginal σ as the whole-span fit's
    (``sqrt(σ² + σ_e²|D|²)``, :func:`gcs_core.estimators.kalman.smoother.smoothed_residuals`): on one hour
    at σ_e = 3× the tracker noise every sensor sits at its noise under both methods (against
    the data book's σ alone the trackers and the FSS read 2.7–3.4)."""
    cfg = nominal_threeaxis("sun_pointing", seed=SEED, duration_s=3600.0)
    for s in cfg.sensors:
        if s.type == "gyro":
            s.book["electronic"] = 3 * TRACKER_NOISE
    mission = write_mission(cfg, tmp_path / "mission")
    rms = {}
    for method in ("kalman", "whole_span"):
        res = Analysis(AnalysisConfig(mission=mission, method=method)).fit(holdout=False)
        rms[method] = {nm: (r.rms_normalized, r.n * len(r.components)) for nm, r in res.residuals.items()}
    for name, (k, m) in rms["kalman"].items():
        assert abs(k - 1.0) < 4.0 / math.sqrt(2 * m) + 0.05, (name, k)
        assert abs(k - rms["whole_span"][name][0]) < 0.05, (name, k, rms["whole_span"][name])
