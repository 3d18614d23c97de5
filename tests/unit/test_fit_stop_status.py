"""How a fit stops, and refits that start at the previous minimum (gcs_core.estimators.stopping).

* A fit whose steps are accepted only when they lower the cost cannot rise: when no step
  lowers it, the status is ``stalled`` with the relative change and the gain the
  linearization still predicts, never ``diverged`` (which a non-finite cost alone means);
  the iteration limit says so with the cost's last relative change.
* A refit after adding an effect starts at the previous whole-span solution (values, knots,
  edits; the new elements at their a priori), so its first cost is the previous minimum's
  and its χ² ends at or below it (a refit with one more free element cannot end above).

Fifteen minutes of the Sun-pointing scenario with its flight-typical IRU, seed 5.
"""

from __future__ import annotations

import numpy as np
import pytest

from gcs_core.config_schema import AnalysisConfig
from gcs_core.estimators import stopping
from gcs_core.estimators.batch.least_squares import BatchOptions
from gcs_core.estimators.whole_span import fit as smoothing_batch
from gcs_core.estimators.whole_span import passes as whole_span_passes
from gcs_core.session import Analysis
from gcs_core.sim.scenarios import nominal_threeaxis, with_effect
from gcs_core.sim.writer import write_mission

#: the refit's first cost against the previous minimum (round-off of one pass)
same_cost = 1e-9


@pytest.fixture(scope="module")
def analysis(tmp_path_factory):
    cfg = with_effect(nominal_threeaxis("sun_pointing", seed=5, duration_s=900.0), "TAM1.scale", 2e-3)
    a = Analysis(
        AnalysisConfig(mission=write_mission(cfg, tmp_path_factory.mktemp("stop") / "m")).with_changes(
            diagnosis={"holdout_fraction": 0.0}
        )
    )
    a.fit(holdout=False)
    return a


def test_a_refit_starts_at_the_previous_minimum_and_cannot_end_above_it(analysis):
    before = analysis.result
    assert before.status == "converged" and before.dynamics is not None
    step = analysis.add_effect("TAM1.scale")
    after = analysis.result
    assert after.cost_history[0] == pytest.approx(before.cost_history[-1], rel=same_cost)
    assert step.delta_chi2 > 0.0 and after.chi2 <= before.chi2
    assert after.status == "converged", after.message
    assert after.dynamics.grid is before.dynamics.grid  # the knots carried over


def test_no_step_lowering_the_cost_is_a_stall_not_a_divergence(analysis, monkeypatch):
    problem = analysis.problem
    honest = whole_span_passes.Passes.cost
    first = {}

    def jagged(self, x, chi2, sysk):
        # a cost with a cliff beside the start: every step along the direction rises
        c = honest(self, x, chi2, sysk)
        first.setdefault("x", x.copy())
        return c if np.array_equal(x, first["x"]) else c + 1e6

    monkeypatch.setattr(whole_span_passes.Passes, "cost", jagged)
    res = smoothing_batch.whole_span_fit(problem, BatchOptions(edit_k=None))
    assert res.status == stopping.STALLED, res.message
    assert "stalled after" in res.message and "relative cost change" in res.message
    assert "the linearization still predicts" in res.message


def test_the_iteration_limit_is_named_with_the_last_change(analysis):
    res = smoothing_batch.whole_span_fit(
        analysis.problem, BatchOptions(edit_k=None, max_iterations=1, tol_chi2=0.0, tol_step_sigma=0.0)
    )
    if res.status == stopping.ITERATION_LIMIT:
        assert res.message.endswith("per iteration") and "iteration limit" in res.message
    else:  # one Gauss–Newton step from the batch can already be the minimum
        assert res.status == stopping.CONVERGED, res.message


def test_stall_and_limit_messages_state_their_numbers():
    status, msg = stopping.stalled(7, 2.0e5, 4.0, 100.0, "no shortened step lowers the cost")
    assert status == "stalled" and "2.0e-05" in msg and "5.0e-04 of the cost" in msg
    assert stopping.stalled(3, float("inf"), 0.0, 1.0, "x")[0] == "diverged"
    status, msg = stopping.iteration_limit(20, 1e3, 1.0)
    assert status == "max_iterations" and "1.0e-03" in msg
