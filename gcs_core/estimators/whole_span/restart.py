"""Where a whole-span fit starts when it refits after a change of state (:mod:`.fit`): the
previous solution's values, knots and edits, each new element at its a-priori value, so
that the refit starts at the previous minimum's cost and ends at or below it."""

from __future__ import annotations

from collections.abc import Mapping
from dataclasses import dataclass

import numpy as np

from gcs_core.estimators.results import BatchResult, FitResult
from gcs_core.estimators.whole_span.passes import Dynamics
from gcs_core.problem.build import Problem


@dataclass(frozen=True)
class Restart:
    """A start for :func:`.fit.whole_span_fit` made from a solution under another state
    (:func:`restart`): what the fit reads of a start result."""

    solve_for: tuple
    consider: tuple
    x: np.ndarray
    residuals: Mapping
    dynamics: Dynamics
    iterations: int = 0


def restart(problem: Problem, previous: FitResult, dyn: Dynamics) -> Restart:
    """The previous solution's values (the elements solved for before) and a-priori values
    (the others), its knots and its edits, as a start on ``problem``."""
    state = problem.state
    names, cons = tuple(state.solve_for), tuple(state.consider)
    before = set(previous.solve_for)
    pv = previous.state.values()
    x = np.array([float(pv[nm]) if nm in before and nm in pv else float(state[nm].value) for nm in names])
    return Restart(names, cons, x, previous.residuals, Dynamics(dyn.grid, dyn.z.copy(), dyn.R))


def start_from(problem, noise, start, previous, edited, spacing) -> BatchResult | Restart | None:
    """The solution to start from: ``start``, else a restart from ``previous`` (a whole-span
    solution under another state, on the same data and knots), else None (the batch)."""
    if start is not None or previous is None or noise is None or edited or spacing is not None:
        return start
    prev_dyn: Dynamics | None = previous.dynamics
    if prev_dyn is None or (prev_dyn.grid.sigma_v, prev_dyn.grid.sigma_u) != (noise.sigma_v, noise.sigma_u):
        return None
    return restart(problem, previous, prev_dyn)
