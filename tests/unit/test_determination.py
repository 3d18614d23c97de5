"""Elements a fit does not determine (gcs_core.diagnosis.determination).

The fine Sun sensor's frequencies ``k_α``, ``k_β`` reach the data only through the sine
amplitudes ``A3``, ``B3`` of Eq 4-23. With the data-book amplitudes 0 they are held by
default (``problem.unseen_at_prior``); solved for on request, the fitted amplitudes are
noise (0 is the truth here), so the frequencies are flagged; with a hidden amplitude of
many σ (the transfer-function effect) they are not.
"""

from __future__ import annotations

import math

import numpy as np
import pytest

from gcs_core.config_schema import AnalysisConfig, ElementConfig
from gcs_core.diagnosis import determination
from gcs_core.reporting import analysis_report
from gcs_core.session import Analysis
from gcs_core.sim.scenarios import nominal_threeaxis, with_effect
from gcs_core.sim.writer import write_mission
from gcs_tui.cli.tables import state_table

FREQUENCIES = ("FSS1.k_alpha", "FSS1.k_beta")


def _fit(folder, cfg, *, solve_k=True):
    elements = {n: ElementConfig(role="solve-for") for n in FREQUENCIES} if solve_k else {}
    a = Analysis(
        AnalysisConfig(mission=write_mission(cfg, folder)).with_changes(
            diagnosis={"holdout_fraction": 0.0}, state={"elements": elements}
        )
    )
    a.fit(holdout=False)
    return a


@pytest.fixture(scope="module")
def nominal(tmp_path_factory):
    return _fit(tmp_path_factory.mktemp("det") / "m", nominal_threeaxis("sun_pointing", seed=4, duration_s=1200.0))


def test_frequencies_of_zero_book_amplitudes_are_held_by_default(tmp_path):
    a = Analysis(
        AnalysisConfig(
            mission=write_mission(nominal_threeaxis("sun_pointing", seed=4, duration_s=600.0), tmp_path / "m")
        ).with_changes(diagnosis={"holdout_fraction": 0.0})
    )
    state = a.problem.state
    assert all(state[n].role == "held" and state[n].value == 50.0 for n in FREQUENCIES)
    assert state["FSS1.A3"].role == "solve-for"


def test_frequencies_with_zero_amplitude_are_not_determined(nominal):
    loose = nominal.not_determined()
    assert {"FSS1.k_alpha", "FSS1.k_beta"} <= set(loose)
    assert "FSS1.B3" in loose["FSS1.k_beta"] and "consistent with 0" in loose["FSS1.k_beta"]
    assert all(n.startswith("FSS1.k_") for n in loose)  # nothing else is flagged
    rows = {r["name"]: r for r in analysis_report(nominal)["state"]}
    assert rows["FSS1.k_beta"]["determined"] is False and "note" in rows["FSS1.k_beta"]
    assert rows["att.roll"]["determined"] is True
    assert any("not determined by the data" in line for line in state_table(nominal))


def test_a_clear_amplitude_determines_its_frequency(tmp_path):
    cfg = with_effect(nominal_threeaxis("sun_pointing", seed=4, duration_s=1200.0), "FSS1.transfer_function", 2e-3)
    a = _fit(tmp_path / "m", cfg)
    loose = a.not_determined()
    assert "FSS1.k_alpha" not in loose


def test_a_held_zero_amplitude_counts_as_zero(nominal):
    res = nominal.result
    values = res.state.values()
    sigma = dict(res.sigma)
    sigma["FSS1.A3"] = abs(values["FSS1.A3"]) / (2 * determination.AMPLITUDE_Z)  # A3 now "clear"
    assert "FSS1.k_alpha" not in determination.not_determined(nominal.problem, values, sigma)


def _searched_amplitude_z(rng, t, k0, sigma_k0, ks, S, SS):
    """One fit of ``y = a sin(k t) + noise`` (unit noise, a = 0 true) with ``k`` searched under
    its a priori: the profile χ² over a fine grid, its minimum, and there the amplitude's
    ``z`` and the posterior σ of ``k`` from the profile's curvature."""
    e = rng.standard_normal(t.size)
    proj = S @ e
    J = -(proj**2) / SS + ((ks - k0) / sigma_k0) ** 2
    i = int(np.argmin(J[1:-1])) + 1
    h = ks[1] - ks[0]
    d2 = (J[i + 1] - 2 * J[i] + J[i - 1]) / h**2
    sk = min(math.sqrt(2.0 / d2), sigma_k0) if d2 > 0 else sigma_k0
    return proj[i] / math.sqrt(SS[i]), sk, ks[i]


def test_a_searched_frequency_keeps_the_amplitude_test_near_its_level():
    """With the frequency fitted, "|z| > 1.96" calls a zero amplitude clear on ≈16 % of
    draws (the largest of many correlated z); the bound over the frequencies searched
    (:func:`determination.amplitude_p_value`) brings it near its 5 % (6.6 ± 0.6 % over 2000
    draws of this geometry)."""
    rng = np.random.default_rng(7)
    k0, sigma_k0 = 50.0, 5.0  # the data book's k and its a priori
    t = rng.uniform(-0.3, 0.3, 600)  # tan α across the field
    ks = np.linspace(k0 - 5 * sigma_k0, k0 + 5 * sigma_k0, 801)
    S = np.sin(np.outer(ks, t))
    SS = np.sum(S * S, axis=1)
    trials = 300
    plain = bound = 0
    for _ in range(trials):
        z, sk, k = _searched_amplitude_z(rng, t, k0, sigma_k0, ks, S, SS)
        plain += abs(z) > determination.AMPLITUDE_Z
        bound += determination.amplitude_p_value(z, sk, sigma_k0, k) < determination.AMPLITUDE_ALPHA
    assert plain / trials > 0.10  # the plain test's false "clear" rate
    assert bound / trials < 0.09  # ≈ 5 %: within 2 binomial σ of 300 draws at 6.6 %


def test_amplitude_p_value_without_a_search_is_the_normal_two_sided():
    p = determination.amplitude_p_value(1.96, 5.0, 5.0, 50.0)  # no data information on k
    assert p == pytest.approx(0.05, abs=1e-3)
    assert determination.amplitude_p_value(1.96, 1.0, 5.0, 50.0) > 0.05  # searched: larger
    assert determination.amplitude_p_value(8.0, 1.0, 5.0, 50.0) < 1e-9  # a clear amplitude
