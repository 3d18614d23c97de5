"""How an iterated least-squares fit stopped, said plainly (batch and whole-span fits).

Every Gauss–Newton fit of GCS ends in one of four states, the result's ``status``:

* ``converged`` — the next Gauss–Newton step is negligible (below ``tol_step_sigma`` of
  every σ, or it would lower the cost by less than the absolute tolerance), or the cost
  stopped moving with the full step taken and nothing more predicted;
* ``stalled`` — the cost still exceeds what the linearization says it could reach, but no
  step along its direction (shortened, or damped) lowers it, or it falls by less than a
  relative tolerance per iteration while the linearization promises much more. The
  solution is usable to the stated relative change; its cost is not the minimum's;
* ``max_iterations`` — the iteration limit came first, with the cost still falling by the
  stated relative amount per iteration;
* ``diverged`` — the cost is not finite at the solution (the model cannot be evaluated
  on these data). A fit whose steps are accepted only when they lower the cost cannot
  otherwise rise: a step that fails to lower it is a stall, never a divergence.

The message states the numbers: iterations, the last relative change of the cost and the
gain the linearization still predicts (``gᵀ δx``, the cost the Gauss–Newton step would
remove if the problem were linear).

References
----------
Nocedal & Wright, *Numerical Optimization*, 2nd ed., Springer 2006, §3.1 and §10.3
(line search and trust region; termination of Gauss–Newton).
"""

from __future__ import annotations

import math

CONVERGED, STALLED, ITERATION_LIMIT, DIVERGED = "converged", "stalled", "max_iterations", "diverged"
STATUSES = (CONVERGED, STALLED, ITERATION_LIMIT, DIVERGED)


def relative(change: float, cost: float) -> float:
    """``change / cost`` (0 for a zero cost)."""
    return float(change) / float(cost) if cost and math.isfinite(cost) else 0.0


def stalled(iterations: int, cost: float, last_change: float, gain: float, why: str) -> tuple[str, str]:
    """(status, message) of a fit that stopped short of its minimum after ``iterations``:
    ``last_change`` is the cost's fall in the last accepted iteration, ``gain`` the fall
    the linearization still predicts, ``why`` what stopped it."""
    if not math.isfinite(cost):
        return diverged(iterations)
    return STALLED, (
        f"stalled after {iterations} iterations at a relative cost change of "
        f"{relative(last_change, cost):.1e}: {why} (the linearization still predicts "
        f"{gain:.3g}, {relative(gain, cost):.1e} of the cost)"
    )


def iteration_limit(iterations: int, cost: float, last_change: float) -> tuple[str, str]:
    """(status, message) of a fit stopped by its iteration limit."""
    return ITERATION_LIMIT, (
        f"iteration limit: stopped after {iterations} iterations with the cost "
        f"still falling by {relative(last_change, cost):.1e} of itself per iteration"
    )


def diverged(iterations: int) -> tuple[str, str]:
    """(status, message) of a fit whose cost is not finite."""
    return DIVERGED, (
        f"diverged after {iterations} iterations: the cost is not finite (the model cannot describe these data)"
    )
