"""Monte Carlo of a data plan (a small slice; ``benchmarks/optimizer_montecarlo.py`` runs 100+).

A 10-minute Sun-pointing plan with a yaw slew (TAM, gyro, two trackers), simulated by the
truth simulator and fitted with the default (whole-span) method:

* every run's seed comes from one ``SeedSequence`` and is stored with its result; a run
  replayed from the file gives the same estimates;
* ``--resume`` computes only the runs the file lacks;
* each fit's own σ equals the predictor's σ for the plan (the simulator flies the plan the
  predictor models), and each error is within 4σ of the simulator's truth, the gyro bias
  and the attitude compared in the estimator's own parameterization (the bias at ``t_ref``
  carried by the data-book drift, the attitude at ``t_ref``).
"""

from __future__ import annotations

import numpy as np
import pytest
from repo_paths import ROOT

from gcs_core.trade import montecarlo as mc_mod
from gcs_core.trade import store
from gcs_core.trade.montecarlo import MonteCarlo, replay, run_montecarlo

#: a predicted σ and a fit's σ for the same plan agree to this fraction (the trackers'
#: scale factors depend on exactly which stars a 10-minute still pointing sees; the
#: predictor draws them from the same catalog ∝ brightness: up to ~12 % apart here)
same_sigma = 0.15
#: no error beyond this many σ in a handful of runs (|z| > 4: 6e-5 per element)
four_sigma = 4.0

CONFIG = """
[analysis]
mission = "{mission}"
[models]
FSS1 = "off"
CSS1 = "off"
[prediction]
start = 0.0
end = 600.0
step = 60.0
[[prediction.maneuvers]]
start = 200.0
duration = 150.0
axis = "yaw"
rate_deg_s = 0.1
[trade.orbit]
a_km = 6898.137
e = 0.0012
i_deg = 28.5
raan_deg = 35.0
argp_deg = 60.0
mean_anomaly_deg = 10.0
"""


@pytest.fixture(scope="module")
def config(tmp_path_factory):
    d = tmp_path_factory.mktemp("mc")
    path = d / "plan.toml"
    path.write_text(CONFIG.format(mission=ROOT / "sample_data" / "missions" / "nominal-sunpoint"))
    return path


def test_runs_seeded_stored_replayable_and_resumable(config, tmp_path, monkeypatch):
    out = tmp_path / "mc.h5"
    run_montecarlo(MonteCarlo(str(config), 2, 11), out)
    calls = []
    real = mc_mod.one_run
    monkeypatch.setattr(mc_mod, "one_run", lambda mc, i: calls.append(i) or real(mc, i))
    res = run_montecarlo(MonteCarlo(str(config), 3, 11), out, resume=True)
    assert calls == [2]
    assert res.runs == 3
    monkeypatch.setattr(mc_mod, "one_run", real)

    _, recs = store.read(out, store.MONTECARLO)
    recs = sorted(recs, key=lambda r: r["index"])
    children = np.random.SeedSequence(11).spawn(3)
    for r, child in zip(recs, children):
        assert r["entropy"] == 11 and r["spawn_key"] == list(child.spawn_key)
        assert r["seed"] == int(child.generate_state(1, dtype=np.uint32)[0])
    assert len({r["seed"] for r in recs}) == 3
    assert "identical" in " ".join(replay(out, 1))

    # the fit's σ is the predictor's σ; errors against the simulator's truth in σ
    det = res.determined
    assert np.all(np.abs(res.fit_sigma[det] / res.predicted[det] - 1.0) <= same_sigma), dict(
        zip(np.array(res.names)[det], (res.fit_sigma / res.predicted)[det])
    )
    for r in recs:
        z = np.array(r["error"]) / np.sqrt(np.diag(np.array(r["P"])))
        bad = {n: round(float(v), 2) for n, v in zip(r["names"], z) if abs(v) > four_sigma}
        assert not bad, (r["index"], bad)


#: a seeded slice of the bundled TAM-bias study (benchmarks/montecarlo_bundled.py runs 200+)
SLICE_RUNS = 16
BUNDLED = ROOT / "sample_data" / "trade" / "smm-tam-bias.toml"


def test_bundled_study_slice_agrees_with_its_prediction():
    """The bundled TAM-bias plan, 16 runs with the truth's a priori drawn: every determined
    element inside its sampling band and the NEES inside its own."""
    res = run_montecarlo(MonteCarlo(str(BUNDLED), SLICE_RUNS, 20261204))
    assert res.runs == SLICE_RUNS and res.failed == 0
    assert res.consistent, "\n".join(mc_mod.summary_lines(res))


def test_ratio_band_is_the_chi2_band_of_a_sample_sigma_widened_by_15_percent():
    from scipy import stats

    lo, hi = mc_mod.ratio_band(200, 1)
    assert lo == pytest.approx(0.85 * np.sqrt(stats.chi2.ppf(0.025, 199) / 199))
    assert hi == pytest.approx(1.15 * np.sqrt(stats.chi2.ppf(0.975, 199) / 199))
    # more elements compared: a wider band (Bonferroni); more runs: a narrower one
    assert mc_mod.ratio_band(200, 10)[1] > hi and mc_mod.ratio_band(1000, 1)[1] < hi


def test_truth_drawn_from_the_a_priori_consider_elements_too():
    from types import SimpleNamespace as El

    state = [
        El(name="TAM1.bias_x", role="solve-for", sigma0=200.0),
        El(name="TAM1.align_1", role="consider", sigma0=1e-3),
        El(name="IRU.bias_x", role="held", sigma0=1e-6),
        El(name="att.roll", role="solve-for", sigma0=np.inf),
    ]
    truth = {"TAM1.bias_x": 5.0, "TAM1.align_1": 0.0, "IRU.bias_x": 0.0, "att.roll": 0.1}
    draws = [mc_mod.draw_prior(state, truth, np.random.default_rng([s, 1]), {"TAM1.bias_x": 2.0}) for s in range(400)]
    assert all(set(d) == {"TAM1.bias_x", "TAM1.align_1"} for d in draws)
    bias = np.array([d["TAM1.bias_x"] for d in draws]) - 5.0
    align = np.array([d["TAM1.align_1"] for d in draws])
    # the draw's σ (the capped 2 nT; the consider element's own a priori), χ² on 399 dof
    for x, sigma in ((bias, 2.0), (align, 1e-3)):
        p = stats_chi2_p(x, sigma)
        assert 1e-3 < p < 1 - 1e-3, p


def test_predicted_sigma_counts_the_a_priori_as_drawn():
    """A linear model ``y = H x + v`` with the a priori drawn at ``σ_d``: the estimate's error
    covariance is ``P Hᵀ R⁻¹ H P + P P₀⁻¹ D P₀⁻¹ P`` (``P`` the posterior, ``D = diag(σ_d²)``),
    which ``drawn_sigma`` gives from ``P`` and σ̄ alone; drawn at every σ̄ it is ``P``."""
    from types import SimpleNamespace

    from gcs_core.trade.mc_summary import drawn_sigma

    rng = np.random.default_rng(4)
    H = rng.normal(size=(6, 3)) * np.array([1.0, 0.05, 0.3])  # one weakly observed, correlated
    prior = np.array([2.0, 1.0, 0.5])
    P = np.linalg.inv(H.T @ H + np.diag(1 / prior**2))  # R = I
    pred = SimpleNamespace(names=("a", "b", "c"), sigma=np.sqrt(np.diag(P))[None, :], P=P, prior=prior)
    draw = {"a": 0.2, "b": 0.1}  # two capped; "c" at its a priori
    D = np.diag([0.2, 0.1, 0.5]) ** 2
    Pi = np.diag(1 / prior**2)
    exact = np.sqrt(np.diag(P @ H.T @ H @ P + P @ Pi @ D @ Pi @ P))
    np.testing.assert_allclose(drawn_sigma(pred, draw), exact, rtol=1e-12)
    np.testing.assert_allclose(drawn_sigma(pred, None), np.sqrt(np.diag(P)), rtol=1e-12)
    np.testing.assert_allclose(drawn_sigma(pred, {"a": 2.0, "b": 1.0, "c": 0.5}), np.sqrt(np.diag(P)), rtol=1e-12)


def stats_chi2_p(x, sigma):
    from scipy import stats

    return float(stats.chi2.cdf(np.sum(np.square(x / sigma)), x.size))


def test_config_error_writes_no_failed_runs(tmp_path):
    from gcs_core.errors import InputError

    cfg = tmp_path / "no_orbit.toml"
    cfg.write_text(
        CONFIG.format(mission=ROOT / "sample_data" / "missions" / "nominal-sunpoint").split("[trade.orbit]")[0]
    )
    out = tmp_path / "mc.h5"
    with pytest.raises(InputError, match="trade.orbit"):
        run_montecarlo(MonteCarlo(str(cfg), 5, 1), out)
    assert not out.exists()
