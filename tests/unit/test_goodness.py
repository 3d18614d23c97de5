"""Goodness of fit (gcs_core.diagnosis.goodness) and the elements set by the a priori.

* the held-out χ² from the held-out normal equations (Woodbury) equals the quadratic form
  ``r_hᵀ (R + H P Hᵀ)⁻¹ r_h`` it stands for, and is χ²_{m_h} over random draws of a
  linear problem (mean m_h within 4 standard errors);
* the effective parameters ``tr(P A)`` equal ``n − Σ P_ii / σ̄_i²`` (Eq 3-2);
* on the bundled missions: the nominal one reads "consistent with noise"; the one with a
  hidden TAM torquer coupling reads "model inadequate" naming TAM1, and after discovery
  adds the coupling, "consistent with noise"; the JSON report keeps its ICD §7 fields and
  carries the tests; the FSS frequencies are named at the a-priori linearization.
"""

from __future__ import annotations

import numpy as np
import pytest
from repo_paths import SAMPLE_MISSIONS

from gcs_core.config_schema import AnalysisConfig
from gcs_core.diagnosis import determination, goodness
from gcs_core.estimators import static_algebra
from gcs_core.reporting import analysis_report, icd_report_problems
from gcs_core.session import Analysis
from gcs_tui.cli.tables import (
    fit_table,
    state_table,
)

#: round-off of the Woodbury identity against the direct solve (relative)
round_off = 1e-9


def _linear_problem(rng, n=6, m=40):
    H = rng.standard_normal((m, n))
    sigma = rng.uniform(0.5, 2.0, m)
    s0 = rng.uniform(0.3, 3.0, n)
    A = (H / sigma[:, None] ** 2).T @ H
    P = np.linalg.inv(A + np.diag(1 / s0**2))
    return H, sigma, s0, A, P


def test_holdout_chi2_is_the_quadratic_form_it_stands_for():
    rng = np.random.default_rng(7)
    H, sigma, _, _, P = _linear_problem(rng)
    r = rng.standard_normal(H.shape[0]) * sigma
    Hw, rw = H / sigma[:, None], r / sigma
    direct = r @ np.linalg.solve(np.diag(sigma**2) + H @ P @ H.T, r)
    L = static_algebra.chol_cov(P)
    woodbury = static_algebra.woodbury_chi2(L, Hw.T @ Hw, Hw.T @ rw, float(rw @ rw))
    assert woodbury == pytest.approx(direct, rel=round_off)


def test_holdout_chi2_has_its_degrees_of_freedom():
    """Held-out residuals of a linear fit, over 2000 draws: mean χ² = m_h (4 standard errors)."""
    rng = np.random.default_rng(11)
    H, sigma, s0, A, P = _linear_problem(rng)
    Hh, sh = rng.standard_normal((30, H.shape[1])), rng.uniform(0.5, 2.0, 30)
    L = static_algebra.chol_cov(P)
    Hw = Hh / sh[:, None]
    vals = []
    for _ in range(2000):
        x = rng.standard_normal(H.shape[1]) * s0  # truth drawn from the a priori
        y = H @ x + rng.standard_normal(H.shape[0]) * sigma
        x_hat = P @ ((H / sigma[:, None] ** 2).T @ y)  # prior mean 0
        rh = (Hh @ x + rng.standard_normal(30) * sh - Hh @ x_hat) / sh
        vals.append(static_algebra.woodbury_chi2(L, Hw.T @ Hw, Hw.T @ rh, float(rh @ rh)))
    vals = np.array(vals)
    assert abs(vals.mean() - 30) < 4 * np.sqrt(2 * 30 / len(vals))


def test_effective_parameters_are_the_data_share_of_the_elements():
    rng = np.random.default_rng(3)
    _, _, s0, A, P = _linear_problem(rng)
    shares = determination.prior_shares([f"x{i}" for i in range(len(s0))], P, s0)
    assert static_algebra.effective_parameters(P, A) == pytest.approx(len(s0) - sum(shares.values()), rel=1e-9)


def test_verdict_reads_inadequate_only_past_the_family_level():
    ok = goodness.ChiSquare("S1", 1000.0, 1000, 995.0)
    bad = goodness.ChiSquare("S2", 1300.0, 1000, 995.0)
    fit = goodness.ChiSquare(goodness.ALL, 2300.0, 2000, 1990.0)
    g = goodness.GoodnessOfFit(fit, {"S1": ok, "S2": bad}, alpha=1e-3)
    assert not g.adequate and g.verdict.startswith("model inadequate") and "worst sensor S2" in g.verdict
    g2 = goodness.GoodnessOfFit(goodness.ChiSquare(goodness.ALL, 2000.0, 2000, 1990.0), {"S1": ok}, alpha=1e-3)
    assert g2.adequate and g2.verdict.startswith("consistent with noise")


@pytest.fixture(scope="module")
def contaminated():
    a = Analysis(AnalysisConfig(mission=SAMPLE_MISSIONS / "hidden-tam-contamination"))
    a.fit()
    return a


def test_a_missing_effect_reads_inadequate_then_noise_once_added(contaminated):
    a = contaminated
    g = a.goodness()
    assert not g.adequate and "worst sensor TAM1" in g.verdict, g.verdict
    assert any(line.startswith("goodness of fit: model inadequate") for line in fit_table(a))
    a.discover()
    assert a.goodness().adequate, a.goodness().verdict
    assert "what remains: consistent with noise" in a.stop_reason
    rep = analysis_report(a, command="discover")
    assert icd_report_problems(rep) == []
    assert rep["goodness_of_fit"]["adequate"] is True and rep["verdict"].startswith("consistent")
    tam = rep["sensors"]["TAM1"]
    assert {"chi2", "dof", "p_value", "holdout_chi2", "holdout_p_value"} <= set(tam)
    assert rep["goodness_of_fit"]["holdout"]["n"] > 0


def test_nominal_sample_reads_noise_and_names_what_the_a_priori_set():
    a = Analysis(AnalysisConfig(mission=SAMPLE_MISSIONS / "nominal-sunpoint"))
    a.fit()
    assert a.goodness().adequate, a.goodness().verdict
    rep = analysis_report(a, command="batch")
    rows = {r["name"]: r for r in rep["state"]}
    marked = {n for n, r in rows.items() if r.get("set_by_prior")}
    assert marked == set(a.set_by_prior())
    for n in marked:  # the a priori gives more than half of what is known about them
        assert rows[n]["prior_share"] > determination.PRIOR_SHARE
    # the FSS frequencies reach the data only through amplitudes that are 0 a priori:
    # held by default
    assert a.problem.state["FSS1.k_alpha"].role == "held"
    assert len(state_table(a)) > len(rows)
