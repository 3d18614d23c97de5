"""Honest at 4 hours: discovery, final RMS and truth recovery on a flight-typical IRU (issue 10).

A seeded slice of ``benchmarks/false_alarms_vs_span.py`` and
``benchmarks/hidden_effects_vs_span.py`` (``tests/helpers/honesty_cases.py`` builds the missions
and compares every estimate with the simulator's truth), run with every estimator:

* a nominal 4 h Sun-pointing mission: nothing added; every sensor at normalized RMS
  ≤ 1.05 fitted and held-out; every calibrated element within 3σ of truth
  (``z = (x̂ − x)/σ``); the goodness-of-fit verdict "consistent with noise";
* a 1 % symmetric TAM matrix error (scale and non-orthogonality), 4 h: exactly those two
  effects added, no step with another sensor above 10 normalized RMS (no divergence),
  final and held-out RMS ≤ 1.05, the six TAM elements within 3σ of truth;
* a 0.1° roll of FHST1 about its boresight, 4 h: ``FHST1.alignment`` added, its angles
  within 3σ of truth.

Every case runs with the batch and the default estimator (the Kalman method's 13–40 s per
case is the sweeps' business: ``benchmarks/false_alarms_vs_span.py``,
``benchmarks/hidden_effects_vs_span.py``).

Seeds: the simulator's seed 1 for every case, chosen before looking. A correct estimator
puts any one |z| above 3 with probability 0.27 %; with 37 elements a nominal mission fails
by chance about once in ten seeds, which the sweep (≥ 40 seeds per mode) measures.

Expected failures (``xfail``, not strict) pin today's limits by method: the batch
propagates the attitude with the gyros at Q = 0, so at 4 h its gyro elements miss the
truth by ~12σ (IRU.G_32 at seed 1; the χ² verdict cannot see it: the gyro elements absorb
the wander, χ²/dof 1.0095).
"""

from __future__ import annotations

import honesty_cases as hc
import pytest

from gcs_core.config_schema import AnalysisConfig

FOUR_HOURS = 4.0
SEED = 1
#: each sensor's held-out share of its measurements (holdout_fraction 0.25, in 5-min blocks)
held_share_range = (0.18, 0.33)
#: the batch and the default estimator, whatever it is (the Kalman method's 13–25 s per
#: 4 h case is the sweeps' business: benchmarks/false_alarms_vs_span.py --method kalman)
METHODS = tuple(dict.fromkeys(("batch", AnalysisConfig().method)))

LIMITS = {
    ("nominal", "batch"): "the batch ignores the gyro's random walks (Q = 0): at 4 h its gyro "
    "elements miss the truth by ~12σ",
}


def _params(case: str):
    return [
        pytest.param(
            m, id=m, marks=[pytest.mark.xfail(strict=False, reason=LIMITS[(case, m)])] if (case, m) in LIMITS else []
        )
        for m in METHODS
    ]


def _explain(rec) -> str:
    return (
        f"added {rec['added']}; rms {rec.get('rms')}; held-out {rec.get('holdout_rms')}; "
        f"worst z {hc.worst(hc.calibrated_z(rec))}; {rec.get('verdict')}; {rec.get('status')}"
    )


@pytest.mark.slow
@pytest.mark.parametrize("method", _params("nominal"))
def test_nominal_four_hours_adds_nothing_and_recovers_the_truth(method, tmp_path):
    rec = hc.run_discovery(hc.nominal("sun_pointing", SEED, FOUR_HOURS), tmp_path, method)
    checks = hc.verdicts(rec)
    assert checks["added"], _explain(rec)
    assert checks["rms"], _explain(rec)
    outside = {k: round(v, 2) for k, v in hc.calibrated_z(rec).items() if abs(v) > hc.three_sigma}
    assert not outside, f"{method}: outside 3σ of truth {outside}"
    assert rec["adequate"], rec["verdict"]
    # every sensor keeps about the configured quarter of its measurements held out (the
    # held-out blocks sample the whole orbit: docs/statistics.md)
    shares = {k: held / n for k, (n, _, held) in rec["chi2_n"].items()}
    assert all(held_share_range[0] < v < held_share_range[1] for v in shares.values()), shares


@pytest.mark.slow
@pytest.mark.parametrize("case", ["TAM1.matrix_1pct", "FHST1.roll"])
@pytest.mark.parametrize("method", METHODS)
def test_hidden_effect_four_hours_is_found_without_divergence(case, method, tmp_path, request):
    if (case, method) in LIMITS:
        request.applymarker(pytest.mark.xfail(strict=False, reason=LIMITS[(case, method)]))
    h = hc.HIDDEN_BY_ID[case]
    rec = hc.run_discovery(h.build("sun_pointing", SEED, FOUR_HOURS), tmp_path, method, exclude=h.exclude)
    carrier = tuple({c[0].split(".")[0] for c in h.changes})
    checks = hc.verdicts(rec, expected=h.expected, carrier=carrier, recover=h.recover)
    assert checks["no_divergence"], f"peak normalized RMS {rec.get('peak_rms')}"
    assert checks["added"], _explain(rec)
    assert checks["rms"], _explain(rec)
    z = {n: round(rec["z"].get(n, float("nan")), 2) for n in h.recover}
    assert checks["hidden"], f"hidden parameters against truth (z): {z}"
