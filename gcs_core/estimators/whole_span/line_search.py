"""The whole-span fit's step search: a Gauss–Newton step shortened until the cost falls, its
first try followed along a curved valley (:mod:`gcs_core.estimators.whole_span.fit`).

A static step along a direction the knots can compensate (the gyro bias and its drift
against the knots' walk) moves the gyro-carried attitude by far more than the noise, and the
knots' corrections, applied as first-order rotations about the old trajectory, undo it only
to first order. The directional derivative of ``J`` is then exact, but its curvature along
the Gauss–Newton step is many times the model's (BROAD trial 02 whole: the full step raised
``J`` by 5900 where it predicted a fall of 360, statics-only and knots-only steps each
1.4·10⁸), and halving the step took 60 iterations without converging. So a full step that
lowers ``J`` by less than :data:`CORRECT_BELOW` of its predicted gain first has its knots
re-solved with the statics held at the new point (a Gauss–Newton step in ``z`` alone,
:func:`knot_correction`, up to :data:`KNOT_CORRECTIONS` times while ``J`` falls): the curved
valley is followed instead of cut (``benchmarks/broad_convergence.py``). Steps the
linearization sizes well are untouched.

With the gyro's read-out noise the first try is made at the joint step's read-out errors
(:func:`_joint_readout`), so that its linearization is the next iteration's.
"""

from __future__ import annotations

import logging
from dataclasses import dataclass
from typing import TYPE_CHECKING

import numpy as np

from gcs_core.estimators.whole_span import knots as kn
from gcs_core.estimators.whole_span.passes import SpanLinearization

if TYPE_CHECKING:
    from gcs_core.estimators.whole_span.fit import Iterate

log = logging.getLogger(__name__)

#: a full step that lowers the cost by less than this fraction of the predicted gain has
#: its knots re-solved at the new statics before it is shortened (:func:`knot_correction`)
CORRECT_BELOW = 0.5
#: ... at most this many times (each a pass over the data), while the cost falls
KNOT_CORRECTIONS = 3


@dataclass(frozen=True)
class Step:
    """A Gauss–Newton step of the statics ``dx`` and the knots ``dz``, with the cost's fall
    the linearization predicts (``gain``) and the statics' σ there."""

    dx: np.ndarray
    dz: np.ndarray
    gain: float
    sigma: np.ndarray


def line_search(it: Iterate, step: Step):
    """The longest of the steps 1, 1/2, … (ten at most) that does not raise the cost, its
    first try with the knots re-solved when the cost falls short (:func:`_correct_knots`).
    Returns (x, z, cost, scale, fresh: ``it.trial`` holds the Jacobian there), or None."""
    passes, cost = it.passes, it.cost
    scale, fresh = 1.0, True
    before = _joint_readout(it, step)  # the read-out errors before the joint step's, or None
    for attempt in range(10):
        x_try, z_try = it.x + scale * step.dx, it.z + scale * step.dz
        # the first try's Jacobian is the next iteration's. With the read-out noise it is
        # made at the joint step's read-out errors when they were predicted; else the try
        # needs only the cost (a pass without the Jacobian), and the next pass is made
        # about the read-out errors' optimum it finds
        fresh = attempt == 0 and (not passes.sig_e2 or before is not None)
        if attempt == 1 and before is not None and passes.errors is not None:
            passes.errors.move_to(before)  # the shortened steps: about the errors before
        it.trial = None
        it.trial = passes.run(x_try, z_try, it.edits, jacobian=fresh)
        cost_t = passes.cost(x_try, it.trial.chi2, it.trial.system)
        if (
            attempt == 0
            and it.opts.knot_correction
            and np.isfinite(cost_t)
            and cost - cost_t < CORRECT_BELOW * step.gain
        ):
            if not fresh:  # the correction needs the try's Jacobian
                it.trial = None
                it.trial = passes.run(x_try, z_try, it.edits)
            z_try, cost_t, fresh = _correct_knots(it, x_try, z_try, cost_t, step.gain)
        if np.isfinite(cost_t) and cost_t <= cost * (1 + 1e-12) + 1e-9:
            return x_try, z_try, cost_t, scale, fresh
        scale *= 0.5
    return None


def _joint_readout(it: Iterate, step: Step) -> np.ndarray | None:
    """With the read-out noise, move the passes' read-out errors to the joint Gauss–Newton
    step's (:meth:`.epoch_errors.EpochErrors.predicted`: the conditional optimum at the new
    statics and knots, to first order), so that the line search's first try linearizes
    where the next iteration needs it. Returns the errors before, or None when nothing was
    recorded."""
    errors, R = it.passes.errors, it.passes.R_fixed
    if errors is None or R is None:
        return None
    new = errors.predicted(step.dx, step.dz, it.grid, R, 1.0 / it.passes.sig_e2)
    if new is None:
        return None
    before = errors.eps
    errors.move_to(new)
    return before


def _correct_knots(it: Iterate, x_try, z_try, cost_t: float, gain: float):
    """A curved valley: the knots' first-order compensation of the statics' step is off at
    second order; re-solve the knots at the new statics (:func:`_knot_correction`, at most
    :data:`KNOT_CORRECTIONS` times while the cost falls). Returns (z, cost, fresh)."""
    passes, cost = it.passes, it.cost
    at = z_try  # where ``it.trial`` holds the Jacobian
    for _ in range(KNOT_CORRECTIONS):
        assert it.trial is not None
        z_c = z_try + knot_correction(it.trial, x_try, it.x_bar, it.prior_info)
        it.trial = None
        it.trial, at = passes.run(x_try, z_c, it.edits), z_c
        cost_c = passes.cost(x_try, it.trial.chi2, it.trial.system)
        if not (np.isfinite(cost_c) and cost_c < cost_t):
            break
        log.debug("  knots re-solved at the new statics: Δcost %.6g", cost_c - cost)
        z_try, cost_t, better = z_c, cost_c, cost_t - cost_c
        if cost - cost_t >= CORRECT_BELOW * gain or better < 0.01 * gain:
            break  # enough, or the knots no longer move the cost
    fresh = True
    if at is not z_try:  # the last correction was refused
        if cost_t <= cost * (1 + 1e-12) + 1e-9:
            it.trial = None
            it.trial = passes.run(x_try, z_try, it.edits)  # linearized where it stands
        else:
            fresh = False
    return z_try, cost_t, fresh


def knot_correction(lin: SpanLinearization, x, x_bar, prior_info) -> np.ndarray:
    """The knots' Gauss–Newton step with the statics held at ``x`` (``δx = 0``), from the
    linearization ``lin`` there: what the knots must add so that they compensate the
    statics' step exactly rather than to first order."""
    _, _, fac = lin.system.eliminate(lin.A + np.diag(prior_info), lin.b + prior_info * (x_bar - x))
    return kn.KnotSystem.back_substitute(fac, np.zeros(lin.A.shape[0]))
