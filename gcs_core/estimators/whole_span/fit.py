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
and a step that raises ``J`` is shortened; before it is, a full step that falls short of
its predicted gain has its knots re-solved at the new statics, following a curved valley
instead of cutting it (:mod:`.line_search`). Data are edited on the whole-span residuals
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
from gcs_core.estimators.batch.editing import edit_frames
from gcs_core.estimators.batch.least_squares import (
    BatchOptions,
    _solve_normal,
    batch_fit,
    name_combinations,
)
from gcs_core.estimators.results import BatchResult, FitResult
from gcs_core.estimators.whole_span import knots as kn
from gcs_core.estimators.whole_span.finish import finish
from gcs_core.estimators.whole_span.grid import make_knots, process_noise
from gcs_core.estimators.whole_span.line_search import Step, line_search
from gcs_core.estimators.whole_span.passes import Dynamics, Passes, SpanLinearization
from gcs_core.estimators.whole_span.readout import seed_errors
from gcs_core.estimators.whole_span.restart import Restart, start_from
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
    (:func:`_edit_passes`, :func:`_iterate`, :func:`.line_search.line_search`), and the
    covariance and result at the solution (:func:`.finish.finish`).
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
    return finish(problem, it)


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
class Iterate:
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


def _begin(problem: Problem, opts: BatchOptions, noise: GyroNoise, batch, edited, spacing) -> Iterate:
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
    return Iterate(
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


def _edit_passes(problem: Problem, it: Iterate) -> None:
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


def _first_linearization(it: Iterate) -> SpanLinearization:
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


def _iterate(it: Iterate) -> None:
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
        found = line_search(it, step)
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


def _gauss_newton_step(it: Iterate, k: int) -> Step:
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
    return Step(dx, dz, gain, sig)


def _no_step_lowers_the_cost(it: Iterate, step: Step, k: int) -> None:
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
