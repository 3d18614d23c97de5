"""The gyro's bias along the span (gcs_core.estimators.gyro_bias) and the rate random walk the
data support (gcs_core.estimators.whole_span.process_likelihood), against the simulator's truth.

In-memory inertial missions of ``test_filter_consistency`` (two star trackers, a 1 Hz gyro
whose bias walks with σ_u = 3e-7 rad/s^1.5: 7.3e-6 rad/s over the 10 minutes, four times
the σ the data leave on the bias), fitted by the whole-span estimator. At five times along
the span the NEES of ``b(t)`` summed over 12 seeded runs lies in its 95 % χ² band (3·12
dof), the normalized errors scatter as N(0, 1) within 15 %, and the static ``bias``
element taken for the bias at the end of the span (what a comparison of two fits' static
biases assumes) fails that test by far. The evidence over σ_u picks the simulated σ_u.

Reference: Bar-Shalom, Li & Kirubarajan, *Estimation with Applications to Tracking and
Navigation*, Wiley 2001, §5.4 (NEES over Monte-Carlo runs).
"""

from __future__ import annotations

import numpy as np
import pytest
from test_filter_consistency import PHYSICS, chi2_band, sim_problem, simulate

from gcs_core.errors import InputError
from gcs_core.estimators.batch.least_squares import BatchOptions, batch_fit
from gcs_core.estimators.gyro_bias import gyro_bias_at
from gcs_core.estimators.whole_span import fit as sb
from gcs_core.estimators.whole_span.process_likelihood import neg2_log_evidence, rrw_profile
from gcs_core.problem.build import build_problem

#: a MEMS-like rate random walk for a 10-minute span [rad/s^1.5]
RRW = 3e-7
TIMES = (0.0, 150.0, 300.0, 450.0, 598.0)
RUNS = 12
SCATTER_TOL = 0.15


def _runs():
    for seed in range(RUNS):
        mission, truth = simulate(300 + seed, duration_s=600.0, rrw=RRW)
        problem = sim_problem(mission)
        res = sb.whole_span_fit(problem, BatchOptions(edit_k=None))
        assert res.status == "converged", res.message
        yield problem, res, truth


def test_bias_along_the_span_is_consistent_with_truth():
    t = np.array(TIMES)
    k = t.astype(int)
    nees = np.zeros(t.size)
    naive = 0.0
    zs = []
    for problem, res, truth in _runs():
        gb = gyro_bias_at(problem, res, t)
        true_b = 0.5 * (truth.bias[k] + truth.bias[k + 1])  # the walk over the 1-s row ending at t + 1
        e = true_b - gb.b
        nees += np.einsum("ni,ni->n", e, np.linalg.solve(gb.cov, e[..., None])[..., 0])
        zs.append(e / gb.sigma)
        static = np.array([res.state.values()[f"IRU.bias_{a}"] for a in "xyz"])
        P = gb.cov[0]  # the static's own covariance: b(τ_0) is the static bias (β_0 = 0)
        e_end = true_b[-1] - static
        naive += float(e_end @ np.linalg.solve(P, e_end))
    lo, hi = chi2_band(3 * RUNS)
    for ti, v in zip(TIMES, nees, strict=True):
        assert lo < v < hi, f"NEES of b({ti:g} s) {v:.1f} outside [{lo:.1f}, {hi:.1f}] ({3 * RUNS} dof)"
    scatter = float(np.std(np.concatenate(zs)))
    assert abs(scatter - 1.0) < SCATTER_TOL, scatter
    assert naive > 3 * hi, f"the static bias taken for b(end) gave NEES {naive:.1f}: the walk is not visible"


def test_batch_bias_drifts_on_its_line_with_the_statics_covariance():
    """With the bias-instability effect the batch's b(t) is ``bias + ḃ (t − t_mid)``, its
    covariance ``J P Jᵀ`` with ``J = [I, (t − t_mid) I]`` on the bias and drift columns."""
    mission, _ = simulate(6, duration_s=300.0, rrw=RRW)
    problem = build_problem(mission, physics=PHYSICS)  # the seed's bias_instability in the state
    res = batch_fit(problem, BatchOptions(edit_k=None))
    names = list(res.solve_for)
    assert "IRU.bias_rate_x" in names
    v = res.state.values()
    knots = problem.gyro_attitude.knots
    t_mid = 0.5 * (knots[0] + knots[-1])
    t = np.array([0.0, 123.0, 299.0])
    gb = gyro_bias_at(problem, res, t)
    bias = np.array([v[f"IRU.bias_{a}"] for a in "xyz"])
    rate = np.array([v[f"IRU.bias_rate_{a}"] for a in "xyz"])
    np.testing.assert_allclose(gb.b, bias + np.outer(t - t_mid, rate), rtol=0, atol=1e-15)
    ib = [names.index(f"IRU.bias_{a}") for a in "xyz"]
    ir = [names.index(f"IRU.bias_rate_{a}") for a in "xyz"]
    for k, tk in enumerate(t):
        J = np.zeros((3, len(names)))
        J[np.arange(3), ib] = 1.0
        J[np.arange(3), ir] = tk - t_mid
        np.testing.assert_allclose(gb.cov[k], J @ res.P @ J.T, rtol=1e-10, atol=1e-30)


def test_batch_bias_is_the_static_line_and_needs_a_gyro():
    mission, _ = simulate(5, duration_s=300.0, rrw=RRW)
    problem = sim_problem(mission)
    res = batch_fit(problem, BatchOptions(edit_k=None))
    gb = gyro_bias_at(problem, res, [0.0, 299.0])
    static = np.array([res.state.values()[f"IRU.bias_{a}"] for a in "xyz"])
    np.testing.assert_allclose(gb.b, np.vstack([static, static]), rtol=0, atol=1e-15)
    i = [res.solve_for.index(f"IRU.bias_{a}") for a in "xyz"]
    np.testing.assert_allclose(gb.cov[0], res.P[np.ix_(i, i)], rtol=1e-12)
    mission, _ = simulate(5, duration_s=60.0, gyro=False, rate_scale=0.0)
    problem = sim_problem(mission)
    with pytest.raises(InputError, match="gyro"):
        gyro_bias_at(problem, batch_fit(problem, BatchOptions(edit_k=None)), 0.0)


def test_rrw_evidence_recovers_the_simulated_walk():
    """The evidence over σ_u (gcs_core.estimators.whole_span.process_likelihood), summed over 6 seeded runs,
    is smallest at the simulated σ_u among factors 0.5–2 of it (the book holds the truth),
    and each run's best is within a factor 1.5 of it."""
    scales = (0.5, 0.7, 1.0, 1.4, 2.0)
    total = np.zeros(len(scales))
    for seed in range(6):
        mission, _ = simulate(300 + seed, duration_s=600.0, rrw=RRW)
        problem = sim_problem(mission)
        res = sb.whole_span_fit(problem, BatchOptions(edit_k=None))
        prof = rrw_profile(problem, res, scales)
        assert all(r.status == "converged" for r in prof.results)
        assert 1 / 1.5 <= prof.best <= 1.5, (seed, prof.best, prof.neg2_log_evidence)
        total += prof.neg2_log_evidence
    assert scales[int(np.argmin(total))] == 1.0, total - total.min()


def test_evidence_needs_the_walk():
    mission, _ = simulate(5, duration_s=120.0, rrw=RRW)
    problem = sim_problem(mission)
    with pytest.raises(InputError, match="rrw"):
        neg2_log_evidence(problem, batch_fit(problem, BatchOptions(edit_k=None)))
