"""A hidden FSS transfer-function harmonic is found, and its amplitude recovered (issue 10).

The simulator (``gcs_core/sim/sensors.py``) and the model (``gcs_core/models/fine_sun.py``)
carry the same Eq 4-23 harmonic, ``H sin(2k tan α)`` on the tangent of the Sun angle, in
phase, with the data book's ``k``. With the book's fundamental amplitude ``A3 = 0`` that
harmonic is exactly the seed's own term ``A3' sin(k' tan α)`` at ``k' = 2k``: a free
frequency slid along that alias (k = 50 → 6, FSS1 at normalized RMS 8.8, the trackers
pulled to 2–3) or to its sign mirror (``k → −k``, the amplitude reported 10²σ off). The
frequency is now held while every amplitude carrying it is 0 in the book
(``problem.unseen_at_prior``), and discovery adds exactly ``FSS1.harmonic``.

Seeded slice of ``benchmarks/hidden_effects_vs_span.py`` (Sun-pointing, seed 1 of the
simulator, chosen before looking): 4 h with the 3° calibration sweep, the default method
(the case without the sweep, and 8 h, are the benchmark's: docs/benchmarks.md).
"""

from __future__ import annotations

import honesty_cases as hc
import pytest

FOUR_HOURS = 4.0
SEED = 1


def _check(case: str, tmp_path):
    h = hc.HIDDEN_BY_ID[case]
    rec = hc.run_discovery(h.build("sun_pointing", SEED, FOUR_HOURS), tmp_path, "whole_span")
    carrier = tuple({c[0].split(".")[0] for c in h.changes})
    checks = hc.verdicts(rec, expected=h.expected, carrier=carrier, recover=h.recover)
    z = {n: round(rec["z"].get(n, float("nan")), 2) for n in h.recover}
    assert checks["added"], (rec["added"], rec.get("status"))
    assert checks["no_divergence"], rec.get("peak_rms")
    # fitted RMS against the fixed bound; the held-out span through its χ² test (a star tracker
    # with ≈300 held-out measurements exceeds 1.05 on ≈10 % of right fits: hc.rms_ideal_share)
    assert all(v <= hc.rms_limit for v in rec["rms"].values()), rec.get("rms")
    assert rec.get("verdict", "").startswith("consistent with noise"), (
        rec.get("verdict"),
        rec.get("holdout_rms"),
        hc.rms_ideal_share(rec),
    )
    assert checks["hidden"], f"the harmonic's amplitudes against truth (z): {z}"
    assert rec["fit_status"] == "converged", rec.get("fit_status")
    return rec


@pytest.mark.slow
def test_hidden_harmonic_with_a_sweep_is_added_and_recovered(tmp_path):
    rec = _check("FSS1.harmonic", tmp_path)
    assert "FSS1.k_alpha" not in rec["z"]  # held: its book amplitude is 0
