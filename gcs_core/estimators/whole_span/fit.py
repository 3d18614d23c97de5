"""Whole-span least squares with gyro process noise: the default estimator (seed §3.2.1).

The batch (:mod:`gcs_core.estimators.batch.least_squares`, Eq 3-1/3-2) carries the attitude with the
gyros and takes that propagation as exact. Here the gyro's angle and rate random walks
(σ_v, σ_u, ICD §5 ``arw``, ``rrw``) enter as process noise: dynamic attitude and
drift-bias corrections at knots along the span, tied together by Farrenkopf's Q on their
increments (:mod:`gcs_core.estimators.whole_span.knots`), estimated jointly with the static elements.
The problem is one maximum a posteriori fit over the whole span::

    J(x, z) = Σ ‖R^-1/2 (y − h(x, z))‖² + ‖x − x̄‖²_{P̄⁻¹} + Σ_j ‖z_{j+1} − Φ_j z_j‖²_{Q_j⁻¹}

solved by Gauss–Newton: every iteration linearizes all sensors about the current
whole-span solution (the gyro-carried attitude corrected by ``z``), eliminates the knots
(information filter forward, RTS back-substitution) and steps ``x`` with the reduced
normal matrix, whose inverse is the covariance of ``x``. The iterated Kalman smoother is
this Gauss–Newton method (Bell 1994); the minimum, covariance and residuals do not
depend on how the span is cut into blocks.

The iteration starts from the batch solution (never from a one-pass filter's track),
and a step that raises ``J`` is shortened. Before it is: a static step along a direction
the knots can compensate (the gyro bias and its drift against the knots' walk) moves the
gyro-carried attitude by far more than the noise, and the knots' corrections, applied as
first-order rotations about the old trajectory, undo it only to first order. The
directional derivative of ``J`` is then exact, but its curvature along the Gauss–Newton
step is many times the model's (BROAD trial 02 whole: the full step raised ``J`` by 5900
where it predicted a fall of 360, statics-only and knots-only steps each 1.4·10⁸), and
halving the step took 60 iterations without converging. So a full step that lowers ``J``
by less than :data:`CORRECT_BELOW` of its predicted gain first has its knots re-solved
with the statics held at the new point (a Gauss–Newton step in ``z`` alone,
:func:`_knot_correction`, up to :data:`KNOT_CORRECTIONS` times while ``J`` falls): the
curved valley is followed instead of cut (``benchmarks/broad_convergence.py``). Steps the
linearization sizes well are untouched. Data are edited on the whole-span residuals
with the batch's robust k-σ rule (:func:`~gcs_core.estimators.batch.editing.robust_outliers`); a
sensor with more than ``max_edit_fraction`` of its frames beyond k σ is not edited but
reported (the model, not the data, is wrong). With no gyro noise in the data book the
knots are empty and the fit is the batch's.

``chi2`` of the result is the data χ² plus the process term (``J`` without the static
prior), on ``m − n`` degrees of freedom: the increments are pseudo-measurements that
bring as many equations as knot unknowns.

The gyro's read-out (electronic) noise σ_e (ICD §5 ``electronic``) does not accumulate:
it is a white attitude error ``ε_k ~ N(0, σ_e² I)`` at every epoch, shared by the rows of
every sensor sampled then (:mod:`gcs_core.estimators.whole_span.readout`), so ``J`` gains
``Σ_k ‖ε_k‖²/σ_e²`` and the rows of one epoch the covariance ``R + σ_e² D Dᵀ``. Each pass
eliminates ε_k per epoch in closed form (Woodbury, three pseudo-rows per epoch) about its
current estimate ε̂_k, which follows the solution (the gyro-carried attitude is a noisy
regressor: linearized at ε = 0 the fit is biased, errors in variables). ``chi2`` is then
the generalized ``Σ rᵀ (R + σ_e² D Dᵀ)⁻¹ r`` plus the process term, the residuals are
reported at ε = 0 and normalized by each row's marginal σ ``sqrt(σ² + σ_e² |D|²)``, and the
editing, the score tests and the leverage read the same covariance. σ_e = 0 is the
common case and runs the σ_e-free code.

References
----------
Bell, B. M., "The iterated Kalman smoother as a Gauss–Newton method", SIAM J. Optim.
4(3), 1994. Crassidis & Junkins, *Optimal Estimation of Dynamic Systems*, 2nd ed.,
CRC 2012, §5.3 (fixed-interval smoothing), §7.2 (attitude estimation with gyros).
"""

from __future__ import annotations

import logging
from collections.abc import Mapping
from dataclasses import dataclass, field, replace
from typing import cast

import numpy as np

from gcs_core.errors import UnobservableError
from gcs_core.estimators import stopping
from gcs_core.estimators.batch.editing import edit_frames, suspect_note
from gcs_core.estimators.batch.least_squares import (
    BatchOptions,
    _solve_normal,
    batch_fit,
    name_combinations,
)
from gcs_core.estimators.residuals import residuals_from
from gcs_core.estimators.results import BatchResult, FitResult
from gcs_core.estimators.whole_span import knots as kn
from gcs_core.estimators.whole_span.grid import make_knots, process_noise
from gcs_core.estimators.whole_span.passes import Dynamics, Passes, SpanLinearization
from gcs_core.estimators.whole_span.readout import seed_errors
from gcs_core.estimators.whole_span.restart import Restart, start_from
from gcs_core.estimators.whole_span.result import SmoothedResult
from gcs_core.models.gyro_noise import GyroNoise
from gcs_core.problem.build import Problem
from gcs_core.problem.gyro_attitude import GyroAttitude

log = logging.getLogger(__name__)

#: a Gauss–Newton step that would lower the cost by less than this is negligible
GAIN_TOL = 1e-3
#: ... and, when no shortened step lowers the cost, a predicted gain below this fraction
#: of the cost (the first-order knot partials' accuracy where the corrections are large)
NOISE_GAIN = 1e-6
#: ... with the per-epoch read-out errors ε̂ (readout.py) moving by less than this, in σ_e
EPS_TOL = 0.02
#: a full step that lowers the cost by less than this fraction of the predicted gain has
#: its knots re-solved at the new statics before it is shortened (:func:`_knot_correction`)
CORRECT_BELOW = 0.5
#: ... at most this many times (each a pass over the data), while the cost falls
KNOT_CORRECTIONS = 3


def whole_span_fit(
    problem: Problem,
    options: BatchOptions | None = None,
    *,
    edited: Mapping[str, np.ndarray] | None = None,
    initial: Mapping[str, float] | None = None,
    noise: GyroNoise | None = None,
    spacing: float | None = None,
    start: BatchResult | Restart | None = None,
    previous: FitResult | None = None,
) -> BatchResult:
    """The whole-span fit with gyro process noise (module docstring).

    ``noise`` overrides the data book's gyro noise (None: the book's); ``spacing`` the
    knot spacing [s]; ``start`` a result on the same problem to start from, with its edits
    (a batch result, or a whole-span one whose knots are reused; else the batch is run
    first). ``previous`` is a whole-span solution of the same data under another state (the
    step before an effect was added or removed): the fit starts at it — its values, knots
    and edits, each new element at its a-priori value — so the refit starts at the previous
    minimum's cost and, its steps only ever lowering the cost, ends at or below it (with
    the same edits). Without gyro noise the batch's result is returned.

    The steps: the start (:func:`.restart.start_from`), the knots and the first point
    (:func:`_begin`), Gauss–Newton iterations with a line search in each editing pass
    (:func:`_edit_passes`, :func:`_iterate`, :func:`_line_search`), and the covariance and
    result at the solution (:func:`_finish`).
    """
    opts = options or BatchOptions()
    noise = noise if noise is not None else process_noise(problem)
    start = start_from(problem, noise, start, previous, edited, spacing)
    # with the read-out noise the batch keeps its attitude partials: the read-out errors'
    # first optimum needs only them and its residuals (_first_linearization)
    partials: dict[str, np.ndarray] | None = {} if start is None and noise is not None and noise.sigma_e else None
    batch: BatchResult | Restart = (
        start
        if start is not None
        else batch_fit(problem, _start_options(opts, noise), edited=edited, initial=initial, attitude_partials=partials)
    )
    if noise is None or not noise.process or not isinstance(problem.attitude, GyroAttitude):
        return cast(BatchResult, batch)  # a restart is made only with process noise
    it = _begin(problem, opts, noise, batch, edited, spacing)
    if partials and it.passes.errors is not None:
        seed_errors(it.passes.errors, problem.sensors, cast(BatchResult, batch).residuals, partials, noise.sigma_e**2)
    del batch, start  # its residuals (a week: 32 MB) are not kept alive
    _edit_passes(problem, it)
    return _finish(problem, it)


#: Gauss–Newton iterations of the batch that starts a fit carrying the read-out noise
START_ITERATIONS_READOUT = 1


def _start_options(opts: BatchOptions, noise: GyroNoise | None) -> BatchOptions:
    """The options of the batch the fit starts from. With the read-out noise its first
    iteration is enough: the batch's minimum is not the fit's (it takes the gyro-carried
    attitude as exact, and its partials at ε = 0 are the errors-in-variables regression,
    :mod:`.readout`), so the fit's first step moves the statics by more than the batch's
    later iterations would, and its passes cost two to three of the batch's."""
    if noise is None or not noise.sigma_e:
        return opts
    return replace(opts, max_iterations=min(opts.max_iterations, START_ITERATIONS_READOUT))


@dataclass
class _Iterate:
    """The state of a whole-span fit as it iterates: the point ``(x, z)``, the
    linearization there (``lin``, or a trial point's, ``trial``: one at a time is kept,
    their knot blocks and factors grow with the span), the edits and what is reported."""

    opts: BatchOptions
    passes: Passes
    grid: kn.KnotGrid
    names: tuple[str, ...]
    cons: tuple[str, ...]
    x_bar: np.ndarray
    prior_info: np.ndarray
    x: np.ndarray
    z: np.ndarray
    preflag: dict[str, np.ndarray]
    edits: dict[str, np.ndarray]
    start_x: np.ndarray
    start_iterations: int
    restarted: bool
    lin: SpanLinearization | None = None
    trial: SpanLinearization | None = None
    cost: float = 0.0
    history: list[float] = field(default_factory=list)
    it_total: int = 0
    status: str = "max_iterations"
    message: str = ""
    change: float = 0.0  # the cost's fall in the last accepted iteration
    suspect: set[str] = field(default_factory=set)

    def relinearize(self) -> None:
        """Linearize at ``(x, z)`` and take the cost there."""
        self.lin = None
        self.lin = self.passes.run(self.x, self.z, self.edits)
        self.cost = self.passes.cost(self.x, self.lin.chi2, self.lin.system)
        self.history.append(self.cost)

    def adopt_readout(self) -> bool:
        """When the read-out errors' conditional optimum has moved from where the passes
        linearize (:mod:`.readout`) by more than :data:`EPS_TOL` of σ_e, take it there;
        True when it moved."""
        errors = self.passes.errors
        if errors is None or errors.moved(np.sqrt(self.passes.sig_e2)) <= EPS_TOL:
            return False
        errors.adopt()
        return True


def _begin(problem: Problem, opts: BatchOptions, noise: GyroNoise, batch, edited, spacing) -> _Iterate:
    """The knots (the start's own when it brings them, else laid out from the batch's
    information), the passes over the data and the first point with the start's edits."""
    state = problem.state
    names, cons = tuple(batch.solve_for), tuple(batch.consider)
    x_bar = np.array([state[nm].value for nm in names])
    s0 = np.array([state[nm].sigma0 for nm in names])
    prior_info = np.where(np.isfinite(s0) & (s0 > 0), 1.0 / np.where(s0 > 0, s0, 1.0) ** 2, 0.0)
    warm: Dynamics | None = batch.dynamics
    if (
        warm is not None
        and spacing is None
        and (warm.grid.sigma_v, warm.grid.sigma_u) == (noise.sigma_v, noise.sigma_u)
    ):
        grid, z = warm.grid, warm.z.copy()  # a whole-span start: its knots too
    else:
        grid = make_knots(problem, noise, cast(BatchResult, batch).information, names, spacing=spacing)
        z = np.zeros((grid.K, grid.d))
        warm = None
    passes = Passes(problem, names, grid, x_bar, prior_info, noise.sigma_e**2)
    if warm is not None and warm.R is not None and warm.R.shape[0] == grid.K - 1:
        passes.R_fixed = warm.R  # ... and their drift-bias axes
    preflag = {k: np.asarray(v, bool).copy() for k, v in (edited or {}).items()}
    edits = {nm: r.edited | preflag.get(nm, np.zeros(r.edited.shape, bool)) for nm, r in batch.residuals.items()}
    restarted = isinstance(batch, Restart)
    return _Iterate(
        opts=opts,
        passes=passes,
        grid=grid,
        names=names,
        cons=cons,
        x_bar=x_bar,
        prior_info=prior_info,
        x=np.array(batch.x, float),
        z=z,
        preflag=preflag,
        edits=edits,
        start_x=np.array(batch.x, float),
        start_iterations=0 if restarted else batch.iterations,
        restarted=restarted,
    )


def _edit_passes(problem: Problem, it: _Iterate) -> None:
    """Iterate to the minimum, edit the frames beyond k σ of the whole-span residuals, and
    again while the edits change (``edit_passes`` at most)."""
    opts = it.opts
    edits_on = any(opts.k_for(sd.name) for sd in problem.sensors)
    for edit_pass in range(opts.edit_passes if edits_on else 1):
        lin = it.lin if it.lin is not None else _first_linearization(it)
        it.cost = it.passes.cost(it.x, lin.chi2, lin.system)
        it.history.append(it.cost)
        _iterate(it)
        if not edits_on:
            break
        passes = it.passes
        it.edits, suspect, changed = edit_frames(
            problem, passes.buffers, it.preflag, opts, it.edits, passes.marginal_sigma()
        )
        it.suspect |= suspect
        if not changed:
            break
        it.lin = None
        log.info("editing pass %d: %d frames flagged", edit_pass + 1, sum(int(v.sum()) for v in it.edits.values()))


def _first_linearization(it: _Iterate) -> SpanLinearization:
    """Linearize at the pass's first point, about the read-out errors' conditional optimum
    there when σ_e is carried (:mod:`.readout`). From ``ε̂ = 0`` (a fresh start) that
    optimum needs only the residuals and the attitude partials: a pass without the
    Jacobian finds it (the same per-epoch sums, :meth:`.readout.ReadoutEpochs.add`), and
    the one full pass is made about it."""
    errors = it.passes.errors
    if errors is not None and not errors.nonzero:
        if errors.seeded:  # from the batch's pass at this point (readout.seed_errors)
            errors.seeded = False
        else:
            it.passes.run(it.x, it.z, it.edits, jacobian=False)
        it.adopt_readout()
        it.lin = it.passes.run(it.x, it.z, it.edits)
        return it.lin
    it.lin = it.passes.run(it.x, it.z, it.edits)
    if it.adopt_readout():  # start about the read-out errors' conditional optimum
        it.lin = None
        it.lin = it.passes.run(it.x, it.z, it.edits)
    return it.lin


@dataclass(frozen=True)
class _Step:
    """A Gauss–Newton step of the statics ``dx`` and the knots ``dz``, with the cost's fall
    the linearization predicts (``gain``) and the statics' σ there."""

    dx: np.ndarray
    dz: np.ndarray
    gain: float
    sigma: np.ndarray


def _iterate(it: _Iterate) -> None:
    """Gauss–Newton iterations from ``it.lin`` until converged, stalled or at the limit; the
    outcome in ``it.status``, ``it.message``."""
    opts = it.opts
    for k in range(opts.max_iterations):
        it.it_total += 1
        step = _gauss_newton_step(it, k)
        # converged: the next Gauss–Newton step is negligible, below tol_step_sigma of
        # every σ, or lowering the cost by less than GAIN_TOL (its Mahalanobis length is
        # then below sqrt(GAIN_TOL) ≈ 0.03 σ); the solution is this point, whose
        # residuals and normal equations the last pass holds
        if np.all(np.abs(step.dx) <= opts.tol_step_sigma * np.maximum(step.sigma, 1e-300)) or step.gain < GAIN_TOL:
            if it.adopt_readout():
                # the read-out errors' linearization point still moved: re-linearize there
                it.relinearize()
                continue
            it.status, it.message = "converged", f"converged after {k} iterations"
            it.it_total -= 1
            return
        it.lin = None  # the line search holds one linearization at a time
        found = _line_search(it, step)
        if found is None:
            _no_step_lowers_the_cost(it, step, k)
            return
        x_try, z_try, cost_t, scale, fresh = found
        it.change = it.cost - cost_t
        it.x, it.z = x_try, z_try
        it.lin, it.trial = (it.trial if fresh else None), None
        if it.lin is None:
            # a trial without its Jacobian (always, with the read-out noise): linearized
            # here about the read-out errors' conditional optimum the trial found
            it.adopt_readout()
            it.lin = it.passes.run(it.x, it.z, it.edits)
        # the read-out errors' conditional optimum at (x, z), when it moved (a pass
        # re-linearizes there before the fit may stop)
        it.adopt_readout()
        it.cost = it.passes.cost(it.x, it.lin.chi2, it.lin.system)
        it.history.append(it.cost)
        # a model far from the data (χ² > 2 per measurement) stops at a relative change
        tol = opts.tol_chi2 if it.cost < 2.0 * max(it.lin.m_used, 1) else max(opts.tol_chi2, 1e-4 * it.cost)
        if it.change < tol and step.gain < 10 * tol and scale == 1.0 and k >= 1:
            it.status, it.message = "converged", f"converged after {k + 1} iterations"
            return
    it.status, it.message = stopping.iteration_limit(opts.max_iterations, it.cost, it.change)


def _gauss_newton_step(it: _Iterate, k: int) -> _Step:
    """The Gauss–Newton step at ``it.lin``: the knots eliminated, the statics solved with
    their prior, the knots back-substituted."""
    assert it.lin is not None
    sysk = it.lin.system
    N = it.lin.A + np.diag(it.prior_info)
    g = it.lin.b + it.prior_info * (it.x_bar - it.x)
    N_red, g_red, fac = sysk.eliminate(N, g)
    try:
        dx, P = _solve_normal(N_red, g_red)
    except np.linalg.LinAlgError:
        combos = name_combinations(N_red - np.diag(it.prior_info), it.names, it.opts.rank_tol)
        raise UnobservableError(
            "the normal matrix is singular: the data cannot separate " + "; ".join(combos or ["(unidentified)"]),
            combos,
        ) from None
    dz = kn.KnotSystem.back_substitute(fac, dx)
    gain = float(g_red @ dx) + sysk.knot_gain
    sig = np.sqrt(np.diag(P))
    worst = np.abs(dx) / np.maximum(sig, 1e-300)
    log.debug(
        "whole-span iteration %d: cost %.6g, max |dx|/σ %.2e (%s), predicted gain %.3g",
        k,
        it.cost,
        float(np.max(worst)),
        it.names[int(np.argmax(worst))],
        gain,
    )
    return _Step(dx, dz, gain, sig)


def _line_search(it: _Iterate, step: _Step):
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


def _joint_readout(it: _Iterate, step: _Step) -> np.ndarray | None:
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


def _correct_knots(it: _Iterate, x_try, z_try, cost_t: float, gain: float):
    """A curved valley: the knots' first-order compensation of the statics' step is off at
    second order; re-solve the knots at the new statics (:func:`_knot_correction`, at most
    :data:`KNOT_CORRECTIONS` times while the cost falls). Returns (z, cost, fresh)."""
    passes, cost = it.passes, it.cost
    at = z_try  # where ``it.trial`` holds the Jacobian
    for _ in range(KNOT_CORRECTIONS):
        assert it.trial is not None
        z_c = z_try + _knot_correction(it.trial, x_try, it.x_bar, it.prior_info)
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


def _no_step_lowers_the_cost(it: _Iterate, step: _Step, k: int) -> None:
    """No shortened step lowers the cost: the minimum to the knot partials' accuracy when
    the predicted gain is below it, else a stall (the cost is finite and never rose)."""
    it.trial = None
    it.lin = it.passes.run(it.x, it.z, it.edits)
    if step.gain <= NOISE_GAIN * it.cost + GAIN_TOL:
        # the step the linearization promises is below what the first-order
        # knot partials resolve at this cost: the minimum, to their accuracy
        it.status = "converged"
        it.message = f"converged after {k} iterations (no shorter step lowers the cost; predicted gain {step.gain:.3g})"
    else:
        it.status, it.message = stopping.stalled(
            it.it_total - 1, it.cost, it.change, step.gain, "no shortened step lowers the cost"
        )


@dataclass(frozen=True)
class _Covariance:
    """The statics' covariance at the solution: noise only (``P``) and with the consider
    elements (``P_consider``, ``budget``), the data information, and the knots' factors."""

    P: np.ndarray
    P_consider: np.ndarray
    budget: dict[str, np.ndarray]
    information: np.ndarray
    factors: tuple


def _covariance(it: _Iterate, lin: SpanLinearization, state) -> _Covariance:
    """The reduced normal matrix at the solution, inverted (Eq 3-2 with the knots
    eliminated), and the consider elements' contribution ``S σ_c² Sᵀ``."""
    n, cons = len(it.names), it.cons
    pi_all = np.concatenate([it.prior_info, np.zeros(len(cons))])
    N_all = lin.A + np.diag(pi_all)
    g_all = lin.b.copy()
    g_all[:n] += it.prior_info * (it.x_bar - it.x)
    N_red_all, _, fac = lin.system.eliminate(N_all, g_all)
    N_red = N_red_all[:n, :n]
    _, P = _solve_normal(N_red, np.zeros(n))
    P_cons, budget = P.copy(), {}
    if cons:
        S = -P @ N_red_all[:n, n:]
        for j, c in enumerate(cons):
            contrib = np.outer(S[:, j], S[:, j]) * state[c].sigma0 ** 2
            budget[c] = np.sqrt(np.diag(contrib))
            P_cons += contrib
        fac = (fac[0], np.concatenate([fac[1][:, :, :n], fac[1][:, :, -1:]], axis=2), fac[2])
    return _Covariance(P, P_cons, budget, N_red - np.diag(it.prior_info), fac)


def _finish(problem: Problem, it: _Iterate) -> SmoothedResult:
    """The result at the solution: the final normal equations (the last pass when it was
    there, with these edits and no consider column), the covariance, the residuals
    normalized by each row's marginal σ (:mod:`.readout`) and the knots."""
    state, passes, grid, names = problem.state, it.passes, it.grid, it.names
    n = len(names)
    lin = it.lin
    if it.cons or lin is None:
        it.lin = lin = None
        lin = passes.run(it.x, it.z, it.edits, columns=names + it.cons)
    cov = _covariance(it, lin, state)
    unobs = tuple(name_combinations(cov.information, names, it.opts.rank_tol * 1e3))
    chi2_proc = lin.system.prior_cost()
    message = (
        f"whole-span fit with gyro process noise ({grid.K} knots every "
        f"{float(np.median(np.diff(grid.tau))):.3g} s"
        + (f"; read-out noise σ_e {np.sqrt(passes.sig_e2):.3g} rad per epoch" if passes.sig_e2 else "")
        + f"): {it.message}"
    ) + suspect_note(it.suspect, it.opts)
    residuals = residuals_from(problem, passes.buffers, it.edits)
    for nm, sig_row in passes.marginal_sigma().items():  # against each row's marginal σ (readout.py)
        residuals[nm] = replace(residuals[nm], normalized_=residuals[nm].residual / sig_row)
    status = it.status
    if not np.isfinite(lin.chi2 + chi2_proc):
        status, message = stopping.diverged(it.it_total)
    return SmoothedResult(
        state=state.with_values({nm: it.x[j] for j, nm in enumerate(names)}),
        solve_for=names,
        consider=it.cons,
        x=it.x,
        P=cov.P,
        P_consider=cov.P_consider,
        residuals=residuals,
        chi2=lin.chi2 + chi2_proc,
        dof=lin.m_used - n,
        cost_history=tuple(it.history),
        iterations=it.it_total + it.start_iterations,
        status=status,
        message=message,
        information=cov.information,
        unobservable=unobs,
        consider_budget=cov.budget,
        dynamics=Dynamics(grid, it.z, lin.R, names, cov.factors, cov.P, passes.sig_e2, passes.errors),
        chi2_process=chi2_proc,
        batch_delta_sigma=None if it.restarted else (it.start_x - it.x) / np.sqrt(np.diag(cov.P)),
    )


def _knot_correction(lin: SpanLinearization, x, x_bar, prior_info) -> np.ndarray:
    """The knots' Gauss–Newton step with the statics held at ``x`` (``δx = 0``), from the
    linearization ``lin`` there: what the knots must add so that they compensate the
    statics' step exactly rather than to first order."""
    _, _, fac = lin.system.eliminate(lin.A + np.diag(prior_info), lin.b + prior_info * (x_bar - x))
    return kn.KnotSystem.back_substitute(fac, np.zeros(lin.A.shape[0]))
