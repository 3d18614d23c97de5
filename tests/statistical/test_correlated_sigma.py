"""The σ of the elements under Gauss–Markov noise (gcs_core/noise/correlated_sigma.py): the
sandwich's correlated sums against their brute-force forms, and its rows' influence on a
whole-span fit (knots included) against the identity the full inverse normal matrix obeys.

The influence of a row on the statics is ``G = J A⁻¹ E_x = H P + U X_j`` (``X_j`` the knot's
cross-covariance with the statics). Since ``A⁻¹ A = I`` and the process rows between knots
have no static column, ``Σ_rows Gᵀ H + P P₀⁻¹ = I`` over every sensor's rows: it holds only
when the knots' share ``U X_j`` is in ``G`` (without it ``H P`` is no influence at all: the
sum is off by 10⁴ σ_i/σ_j on the gyro's bias). The Monte Carlo of ``benchmarks/correlated_noise.py``
(``--part mc``) is the statistical check; docs/benchmarks.md, "Correlated sensor noise".
"""

from __future__ import annotations

import json
from dataclasses import replace
from types import SimpleNamespace

import honesty_cases as hc
import numpy as np
import pytest

from gcs_core.config_schema import AnalysisConfig
from gcs_core.noise import correlated_sigma as cs
from gcs_core.problem.linearization import iter_blocks
from gcs_core.session import Analysis
from gcs_core.sim.gauss_markov import with_gauss_markov
from gcs_core.sim.writer import write_mission

TAU_S = 60.0
#: round-off of the influence identity in units of σ_i/σ_j (P and X from the fit's
#: elimination, H re-formed at its solution; 2e-11 seen)
IDENTITY_TOL = 1e-8


def _dense(t, tau):
    return np.exp(-np.abs(t[:, None] - t[None, :]) / tau)


@pytest.mark.parametrize(("n", "tau", "span"), [(400, 60.0, 86400.0), (300, 5.0, 200.0), (200, 1.0, 3 * 86400.0)])
def test_forward_sum_is_the_exponential_kernel(n, tau, span):
    rng = np.random.default_rng(n)
    t = np.sort(rng.uniform(0.0, span, n))
    t[n // 2 + 1] = t[n // 2]  # two rows at one time are fully correlated
    h = rng.standard_normal((n, 3))
    F = cs._forward_sum(t, h, tau)
    assert np.allclose(F, np.tril(_dense(t, tau)) @ h, rtol=1e-12, atol=1e-12)
    g = rng.standard_normal((n, 2, 3))
    share, kappa = 0.8, 7.0
    C = share * _dense(t, tau) + (1.0 - share) * np.eye(n)
    want = sum(np.diag(g[:, c].T @ (C / kappa - np.eye(n)) @ g[:, c]) for c in range(2))
    assert np.allclose(cs._excess(t, g, tau, share, kappa), want, rtol=1e-10)


@pytest.fixture(scope="module")
def fitted(tmp_path_factory):
    cfg = with_gauss_markov(hc.nominal("sun_pointing", 2, 4.0), TAU_S)
    d = tmp_path_factory.mktemp("gm60_sigma")
    m = write_mission(cfg, d / "mission", truth_path=d / "truth.json")
    a = Analysis(AnalysisConfig(mission=m, method="whole_span"))
    seen = {}
    honest = cs.honest

    def spy(problem, result, corr, scale):  # the fit's result before its σ are rescaled
        seen.update(problem=problem, result=result, corr=corr, scale=scale)
        return honest(problem, result, corr, scale)

    cs.honest = spy
    try:
        a.fit(holdout=False)
    finally:
        cs.honest = honest
    return SimpleNamespace(**seen), json.loads((d / "truth.json").read_text())


def test_influence_rows_invert_the_normal_matrix_with_the_knots(fitted):
    a, _ = fitted
    res = a.result
    dyn, X = cs._knot_covariance(res)
    assert dyn is not None and X is not None and dyn.grid.K > 10
    P = np.asarray(res.P)
    names = list(res.solve_for)
    prior = np.array([1.0 / res.state[n].sigma0 ** 2 if np.isfinite(res.state[n].sigma0) else 0.0 for n in names])
    exclude = {n: ~np.asarray(r.used, bool) for n, r in res.residuals.items()}
    total, statics_only = P * prior[None, :], P * prior[None, :]
    for blk in iter_blocks(
        dyn.problem(a.problem, readout=True), res.state.values(), names, weighted=True, exclude=exclude
    ):
        if blk.H is None or not blk.cols.size:
            continue
        G = cs._influence(blk, P, dyn, X)
        total[:, blk.cols] += np.einsum("nmp,nmc->pc", G, blk.H)
        statics_only[:, blk.cols] += np.einsum("nmp,nmc->pc", cs._influence(blk, P, dyn, None), blk.H)
    eye, sig = np.eye(len(names)), np.sqrt(np.diag(P))
    unit = sig[None, :] / sig[:, None]  # (A⁻¹A)_ij in units of σ_i/σ_j
    assert np.max(np.abs((total - eye) * unit)) < IDENTITY_TOL, np.max(np.abs((total - eye) * unit))
    assert np.max(np.abs((statics_only - eye) * unit)) > 1.0  # the knots' share matters


def test_tracker_scales_shrink_and_white_sensors_are_not_computed(fitted):
    a, _ = fitted
    carried = {n: (a.corr[n].tau_s, a.corr[n].share, k * k) for n, k in a.scale.items() if a.corr[n].significant}
    assert set(carried) == {"FHST1", "FHST2", "TAM1"}
    s = cs.sigma_ratios(a.problem, a.result, carried)
    for n in ("FHST1.scale_h", "FHST1.scale_v", "FHST2.scale_h", "FHST2.scale_v"):
        assert 0.2 < s[n] < 0.7, (n, s[n])  # 1/√κ ≈ 0.29 for a signature white frame to frame
    assert all(0.9 < s[n] <= 1.05 for n in ("IRU.bias_x", "IRU.bias_y", "IRU.bias_z")), s
    assert cs.sigma_ratios(a.problem, a.result, {}) == {}


def test_without_the_knots_the_ratios_are_conditional_and_the_scales_barely_move(fitted):
    """The knots take the gyro's slow signatures, not a tracker scale's frame-to-frame one:
    conditional on them (the static-columns inverse) the scales' ratios are within 3 % of the
    marginal ones, the gyro bias's lower (docs/benchmarks.md, "Correlated sensor noise")."""
    a, _ = fitted
    carried = {n: (a.corr[n].tau_s, a.corr[n].share, k * k) for n, k in a.scale.items() if a.corr[n].significant}
    marginal = cs.sigma_ratios(a.problem, a.result, carried)
    conditional = cs.sigma_ratios(a.problem, replace(a.result, dynamics=None), carried)
    for n in ("FHST1.scale_h", "FHST1.scale_v", "FHST2.scale_h", "FHST2.scale_v"):
        assert abs(conditional[n] / marginal[n] - 1.0) < 0.03, (n, conditional[n], marginal[n])
    assert conditional["IRU.bias_x"] < marginal["IRU.bias_x"]
