"""Spinners on the real horizon: discovery and the estimates against the truth (issue 11).

A seeded slice of ``benchmarks/spinner_truth_sweep.py`` (the full 4 inclinations × 4 hidden
errors × 3 seeds, with its table in ``docs/benchmarks.md``): 3 h of a 10 rpm spinner with
two horizon scanners (cones 60°, 110°) and a plane-field Sun sensor, the simulator crossing
the WGS-84 ellipsoid exactly. Each case asserts what discovery added (the hidden effect, or
for an error the state absorbs, the alias it names), the noise floor on the fitted and the
held-out spans, and every determined element against the answer file in σ: against the
truth itself, and, where the state absorbs the hidden error, against the truth as the state
expresses it (:func:`spinner_cases.expected_estimates`).
"""

from __future__ import annotations

import pytest
from spinner_cases import HIDDEN, run_case

noise_floor_bound = 1.05  # normalized RMS, fitted and held-out (issue 11)
z_bound = 3.0  # every determined element within 3σ of the truth (issue 11)

# a nominal Sun-synchronous spinner is tested on independent data (test_conformance_spinner)
SLICE = [(90.0, "d_gamma", 2), (51.6, "height", 2)]


@pytest.mark.slow
@pytest.mark.parametrize("inclination,hidden,seed", SLICE, ids=[f"{i}-{h}-{s}" for i, h, s in SLICE])
def test_spinner_discovery_and_truth(inclination, hidden, seed, tmp_path):
    o = run_case(inclination, hidden, seed, tmp_path)
    effect = HIDDEN[hidden][0]
    if hidden == "height":
        # an 18 km horizon change is a near-constant Earth-radius bias on a near-circular orbit:
        # HS1.d_rho absorbs it, and discovery names that alias instead of adding the height
        assert o.added == [] and "HS1.d_rho" in o.hidden_aliases
        z = o.z_expected
    else:
        assert o.added == ([effect] if effect else [])
        z = o.z
    for name, v in {**o.rms, **o.holdout}.items():
        assert v <= noise_floor_bound, f"{name} normalized RMS {v:.3f}"
    bad = {k: round(v, 2) for k, v in z.items() if abs(v) > z_bound}
    assert not bad, f"elements more than {z_bound:g}σ from the truth: {bad}"
    # the spinner's exact alias is named and its members left to the a priori
    assert {"HS1.d_phi", "HS1.eps_H", "HS2.d_phi", "HS2.eps_H"} <= set(o.set_by_prior)
    assert any("ΔΦ − asin(cot γ' tan ε_H)" in text for text in o.aliases)
    assert "att.ra" in o.z and "HS1.d_gamma" in o.z and "HS2.d_rho" in o.z
