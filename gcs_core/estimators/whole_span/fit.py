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
with the batch's robust k-σ rule (:func:`~gcs_core.estimators.batch.least_squares.robust_outliers`); a
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
from dataclasses import dataclass, replace

import numpy as np

from gcs_core.errors import UnobservableError
from gcs_core.estimators import stopping
from gcs_core.estimators.batch.least_squares import (
    BatchOptions,
    _solve_normal,
    batch_fit,
    edit_frames,
    name_combinations,
    suspect_note,
)
from gcs_core.estimators.residuals import residuals_from
from gcs_core.estimators.results import BatchResult, FitResult
from gcs_core.estimators.whole_span import knots as kn
from gcs_core.estimators.whole_span.grid import make_knots, process_noise
from gcs_core.estimators.whole_span.passes import Dynamics, Passes
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
    start: BatchResult | _Restart | None = None,
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
    """
    opts = options or BatchOptions()
    noise = noise if noise is not None else process_noise(problem)
    prev_dyn: Dynamics | None = getattr(previous, "dynamics", None)
    if (
        previous is not None
        and start is None
        and prev_dyn is not None
        and noise is not None
        and not edited
        and spacing is None
        and (prev_dyn.grid.sigma_v, prev_dyn.grid.sigma_u) == (noise.sigma_v, noise.sigma_u)
    ):
        start = _restart(problem, previous, prev_dyn)
    batch: BatchResult | _Restart = (
        start if start is not None else batch_fit(problem, opts, edited=edited, initial=initial)
    )
    if noise is None or not noise.process or not isinstance(problem.attitude, GyroAttitude):
        assert isinstance(batch, BatchResult)  # a restart is made only with process noise
        return batch
    state = problem.state
    names = tuple(batch.solve_for)
    cons = tuple(batch.consider)
    n = len(names)
    x_bar = np.array([state[nm].value for nm in names])
    s0 = np.array([state[nm].sigma0 for nm in names])
    prior_info = np.where(np.isfinite(s0) & (s0 > 0), 1.0 / np.where(s0 > 0, s0, 1.0) ** 2, 0.0)
    warm = getattr(batch, "dynamics", None)
    if (
        warm is not None
        and spacing is None
        and warm.grid.sigma_v == noise.sigma_v
        and warm.grid.sigma_u == noise.sigma_u
    ):
        grid, z = warm.grid, warm.z.copy()  # a whole-span start: its knots too
    else:
        assert isinstance(batch, BatchResult)  # a restart always brings its knots
        grid = make_knots(problem, noise, batch.information, names, spacing=spacing)
        z = np.zeros((grid.K, grid.d))
        warm = None
    passes = Passes(problem, names, grid, x_bar, prior_info, noise.sigma_e**2)
    if warm is not None and warm.R is not None and warm.R.shape[0] == grid.K - 1:
        passes.R_fixed = warm.R  # ... and their drift-bias axes
    x = np.array(batch.x, float)
    preflag = {k: np.asarray(v, bool).copy() for k, v in (edited or {}).items()}
    edits = {nm: r.edited | preflag.get(nm, np.zeros(r.edited.shape, bool)) for nm, r in batch.residuals.items()}
    # what the end needs of the start; its residuals (a week: 32 MB) are not kept alive
    restarted = isinstance(batch, _Restart)
    start_x, start_iterations = np.array(batch.x, float), (0 if restarted else batch.iterations)
    del batch, start
    edits_on = any(opts.k_for(sd.name) for sd in problem.sensors)
    suspect_all: set[str] = set()
    history: list[float] = []
    it_total = 0
    status, message = "max_iterations", ""
    change = 0.0  # the cost's fall in the last accepted iteration
    lin = None  # (A, b, χ², m, system, R) at (x, z) with the edits
    for edit_pass in range(opts.edit_passes if edits_on else 1):
        if lin is None:
            lin = passes.run(x, z, edits)
            if passes.errors is not None and passes.errors.moved(np.sqrt(passes.sig_e2)) > EPS_TOL:
                passes.errors.adopt()  # start about the read-out errors' conditional optimum
                lin = passes.run(x, z, edits)
        A, b, chi2, m_used, sysk, R = lin
        cost = passes.cost(x, chi2, sysk)
        history.append(cost)
        for it in range(opts.max_iterations):
            it_total += 1
            N = A + np.diag(prior_info)
            g = b + prior_info * (x_bar - x)
            N_red, g_red, fac = sysk.eliminate(N, g)
            try:
                dx, P = _solve_normal(N_red, g_red)
            except np.linalg.LinAlgError:
                combos = name_combinations(N_red - np.diag(prior_info), names, opts.rank_tol)
                raise UnobservableError(
                    "the normal matrix is singular: the data cannot separate "
                    + "; ".join(combos or ["(unidentified)"]),
                    combos,
                ) from None
            dz = kn.KnotSystem.back_substitute(fac, dx)
            gain = float(g_red @ dx) + sysk.knot_gain
            sig = np.sqrt(np.diag(P))
            log.debug(
                "whole-span iteration %d: cost %.6g, max |dx|/σ %.2e (%s), predicted gain %.3g",
                it,
                cost,
                float(np.max(np.abs(dx) / np.maximum(sig, 1e-300))),
                names[int(np.argmax(np.abs(dx) / np.maximum(sig, 1e-300)))],
                gain,
            )
            # converged: the next Gauss–Newton step is negligible, below tol_step_sigma of
            # every σ, or lowering the cost by less than GAIN_TOL (its Mahalanobis length is
            # then below sqrt(GAIN_TOL) ≈ 0.03 σ); the solution is this point, whose
            # residuals and normal equations the last pass holds
            if np.all(np.abs(dx) <= opts.tol_step_sigma * np.maximum(sig, 1e-300)) or gain < GAIN_TOL:
                if passes.errors is not None and passes.errors.moved(np.sqrt(passes.sig_e2)) > EPS_TOL:
                    # the read-out errors' linearization point still moves: take it, re-linearize
                    passes.errors.adopt()
                    lin = passes.run(x, z, edits)
                    A, b, chi2, m_used, sysk, R = lin
                    cost = passes.cost(x, chi2, sysk)
                    history.append(cost)
                    continue
                status, message = "converged", f"converged after {it} iterations"
                it_total -= 1
                break
            # the line search holds one linearization at a time (their knot blocks and
            # factors grow with the span: tens of MB each on a week)
            del fac, N_red, A, b, sysk
            lin = trial = None
            step, fresh = 1.0, True  # fresh: ``trial`` holds the Jacobian at (x_try, z_try)
            for attempt in range(10):
                x_try, z_try = x + step * dx, z + step * dz
                trial = None
                trial = passes.run(x_try, z_try, edits, jacobian=attempt == 0)
                cost_t = passes.cost(x_try, trial[2], trial[4])
                fresh = attempt == 0
                if fresh and opts.knot_correction and np.isfinite(cost_t) and cost - cost_t < CORRECT_BELOW * gain:
                    # a curved valley: the knots' first-order compensation of the statics'
                    # step is off at second order; re-solve the knots at the new statics
                    at = z_try  # where ``trial`` holds the Jacobian
                    for _ in range(KNOT_CORRECTIONS):
                        z_c = z_try + _knot_correction(trial, x_try, x_bar, prior_info)
                        trial = None
                        trial, at = passes.run(x_try, z_c, edits), z_c
                        cost_c = passes.cost(x_try, trial[2], trial[4])
                        if not (np.isfinite(cost_c) and cost_c < cost_t):
                            break
                        log.debug("  knots re-solved at the new statics: Δcost %.6g", cost_c - cost)
                        z_try, cost_t, better = z_c, cost_c, cost_t - cost_c
                        if cost - cost_t >= CORRECT_BELOW * gain or better < 0.01 * gain:
                            break  # enough, or the knots no longer move the cost
                    if at is not z_try:  # the last correction was refused
                        if cost_t <= cost * (1 + 1e-12) + 1e-9:
                            trial = None
                            trial = passes.run(x_try, z_try, edits)  # linearized where it stands
                        else:
                            fresh = False
                if np.isfinite(cost_t) and cost_t <= cost * (1 + 1e-12) + 1e-9:
                    break
                step *= 0.5
            else:
                lin = passes.run(x, z, edits)
                if gain <= NOISE_GAIN * cost + GAIN_TOL:
                    # the step the linearization promises is below what the first-order
                    # knot partials resolve at this cost: the minimum, to their accuracy
                    status, message = (
                        "converged",
                        (
                            f"converged after {it} iterations (no shorter "
                            f"step lowers the cost; predicted gain {gain:.3g})"
                        ),
                    )
                else:
                    # the cost is finite and never rose: a stall, not a divergence
                    status, message = stopping.stalled(
                        it_total - 1, cost, change, gain, "no shortened step lowers the cost"
                    )
                break
            change = cost - cost_t
            x, z = x_try, z_try
            lin = trial if fresh else passes.run(x, z, edits)
            if passes.errors is not None:
                # the read-out errors' conditional optimum at (x, z), when it moved (a pass
                # re-linearizes there before the fit may stop)
                if passes.errors.moved(np.sqrt(passes.sig_e2)) > EPS_TOL:
                    passes.errors.adopt()
            A, b, chi2, m_used, sysk, R = lin
            cost = passes.cost(x, chi2, sysk)
            history.append(cost)
            # a model far from the data (χ² > 2 per measurement) stops at a relative change
            tol = opts.tol_chi2 if cost < 2.0 * max(m_used, 1) else max(opts.tol_chi2, 1e-4 * cost)
            if change < tol and gain < 10 * tol and step == 1.0 and it >= 1:
                status, message = "converged", f"converged after {it + 1} iterations"
                break
        else:
            status, message = stopping.iteration_limit(opts.max_iterations, cost, change)
        if not edits_on:
            break
        edits, suspect, changed = edit_frames(problem, passes.buffers, preflag, opts, edits, passes.marginal_sigma())
        suspect_all |= suspect
        if not changed:
            break
        lin = None
        log.info("editing pass %d: %d frames flagged", edit_pass + 1, sum(int(v.sum()) for v in edits.values()))

    # final normal equations at the solution (the last pass when it was there, with these
    # edits and no consider column)
    cols = names + cons
    if cons or lin is None:
        lin = passes.run(x, z, edits, columns=cols)
    A_all, b_all, chi2, m_used, sysk, R = lin
    pi_all = np.concatenate([prior_info, np.zeros(len(cons))])
    N_all = A_all + np.diag(pi_all)
    g_all = b_all.copy()
    g_all[:n] += prior_info * (x_bar - x)
    N_red_all, _, fac = sysk.eliminate(N_all, g_all)
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
    info = N_red - np.diag(prior_info)
    unobs = tuple(name_combinations(info, names, opts.rank_tol * 1e3))
    chi2_proc = sysk.prior_cost()
    message = (
        f"whole-span fit with gyro process noise ({grid.K} knots every "
        f"{float(np.median(np.diff(grid.tau))):.3g} s"
        + (f"; read-out noise σ_e {np.sqrt(passes.sig_e2):.3g} rad per epoch" if passes.sig_e2 else "")
        + f"): {message}"
    )
    message += suspect_note(suspect_all, opts)
    new_state = state.with_values({nm: x[j] for j, nm in enumerate(names)})
    residuals = residuals_from(problem, passes.buffers, edits)
    for nm, sig_row in passes.marginal_sigma().items():  # against each row's marginal σ (readout.py)
        residuals[nm] = replace(residuals[nm], normalized_=residuals[nm].residual / sig_row)
    dyn = Dynamics(grid, z, R, names, fac, P, passes.sig_e2, passes.errors)
    sig = np.sqrt(np.diag(P))
    if not np.isfinite(chi2 + chi2_proc):
        status, message = stopping.diverged(it_total)
    return SmoothedResult(
        new_state,
        names,
        cons,
        x,
        P,
        P_cons,
        residuals,
        chi2 + chi2_proc,
        m_used - n,
        tuple(history),
        it_total + start_iterations,
        status,
        message,
        info,
        unobs,
        budget,
        dynamics=dyn,
        chi2_process=chi2_proc,
        batch_delta_sigma=None if restarted else (start_x - x) / sig,
    )


def _knot_correction(lin, x, x_bar, prior_info) -> np.ndarray:
    """The knots' Gauss–Newton step with the statics held at ``x`` (``δx = 0``), from the
    linearization ``lin`` there: what the knots must add so that they compensate the
    statics' step exactly rather than to first order."""
    A, b, _, _, sysk, _ = lin
    _, _, fac = sysk.eliminate(A + np.diag(prior_info), b + prior_info * (x_bar - x))
    return kn.KnotSystem.back_substitute(fac, np.zeros(A.shape[0]))


@dataclass(frozen=True)
class _Restart:
    """A start for :func:`whole_span_fit` made from a solution under another state
    (:func:`_restart`): what the fit reads of a start result."""

    solve_for: tuple
    consider: tuple
    x: np.ndarray
    residuals: Mapping
    dynamics: Dynamics
    iterations: int = 0


def _restart(problem: Problem, previous: FitResult, dyn: Dynamics) -> _Restart:
    """The previous solution's values (the elements solved for before) and a-priori values
    (the others), its knots and its edits, as a start on ``problem``."""
    state = problem.state
    names, cons = tuple(state.solve_for), tuple(state.consider)
    before = set(previous.solve_for)
    pv = previous.state.values()
    x = np.array([float(pv[nm]) if nm in before and nm in pv else float(state[nm].value) for nm in names])
    return _Restart(names, cons, x, previous.residuals, Dynamics(dyn.grid, dyn.z.copy(), dyn.R))
