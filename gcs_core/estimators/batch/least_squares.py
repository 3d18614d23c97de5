"""Batch least squares with an a priori (seed §3.2.1, Eq 3-1 and 3-2).

For the solve-for elements ``x`` with a-priori value ``x̄`` and covariance ``P̄``, each
iteration k linearizes every sensor at ``x_k`` and takes the Gauss–Newton step::

    P_{k+1} = (P̄⁻¹ + Hᵀ R⁻¹ H)⁻¹                                             (Eq 3-2)
    x_{k+1} = x_k + P_{k+1} [Hᵀ R⁻¹ (y − h(x_k)) + P̄⁻¹ (x̄ − x_k)]             (Eq 3-1)

``R`` is diagonal with each sensor's noise variance (seed §4.3). The normal matrix is
equilibrated (scaled to unit diagonal) and solved by Cholesky; nothing is inverted
except the final covariance, which is formed from the Cholesky factor.

Steps. A step that raises the cost is re-solved with Levenberg–Marquardt damping. Near
the noise floor the step adds the Newton terms of the models' parameter pairs
(:mod:`~gcs_core.problem.curvature`) and, after a step that lands there and moves a
sensor's own non-linear parameters (the FSS transfer function), minimizes over those
with everything else held before the next linearization
(:mod:`~gcs_core.estimators.batch.local_refine`). Both only shorten the path: the fixed point is
Eq 3-1's, and the covariance is Eq 3-2's (the Gauss–Newton information). The iteration
stops when the next step is below ``tol_step_sigma`` of every σ (the solution is then the
last linearization point, whose residuals and covariance are those reported) or the cost
stops falling.

Observability. The *data* information ``Hᵀ R⁻¹ H`` is examined after equilibration: an
eigenvalue below ``rank_tol`` of the largest marks a combination of elements the data
cannot separate (e.g. a magnetometer misalignment against the attitude at an inertial
attitude, seed §2.1.2). Such combinations are named in the result; without an a
priori on them the normal matrix is singular and :class:`UnobservableError` is raised
rather than inventing numbers.

Consider elements ``c`` (not estimated, uncertainty carried) add
``S P_c Sᵀ`` with the sensitivity ``S = −P Hᵀ R⁻¹ H_c`` to the covariance.

Data editing: after convergence, frames whose normalized residual lies more than
``edit_k`` robust σ from its median in any component are flagged (never deleted) and the
fit is repeated, until the set of flagged frames stops changing (k-σ editing, iterated;
:func:`.editing.robust_outliers`). The robust σ keeps gross errors from hiding themselves and a
missing physical effect from being edited away.

References
----------
Wertz (ed.) 1978, §13.4 (batch estimators with a priori); Tapley, Schutz & Born,
*Statistical Orbit Determination*, Elsevier 2004, §4.3 (normal equations) and §6.3
(consider covariance).
"""

from __future__ import annotations

import logging
from collections.abc import Mapping, Sequence
from dataclasses import dataclass, field

import numpy as np
from scipy import linalg

from gcs_core.config_schema import FilterConfig
from gcs_core.errors import EstimationError, UnobservableError
from gcs_core.estimators import stopping
from gcs_core.estimators.batch import local_refine
from gcs_core.estimators.batch.editing import edit_frames, suspect_note
from gcs_core.estimators.residuals import Residuals, residuals_from
from gcs_core.estimators.results import BatchResult
from gcs_core.linalg import sparse_basis
from gcs_core.problem import curvature
from gcs_core.problem.build import Problem
from gcs_core.problem.linearization import iter_blocks

log = logging.getLogger(__name__)


@dataclass(frozen=True)
class BatchOptions:
    """Options of :func:`batch_fit`.

    Attributes
    ----------
    max_iterations : Gauss–Newton iterations per editing pass.
    tol_step_sigma : converged when every step is below this fraction of its sigma.
    tol_chi2 : ... or the cost (χ² with prior) changes by less than this (absolute; a
        χ² change of 0.01 carries no statistical meaning).
    edit_k : k of the k-σ editing (None: no editing).
    edit_passes : maximum editing passes.
    max_edit_fraction : if more than this share of a sensor's frames exceed k σ, the
        model (not the data) is wrong: that sensor is not edited, and the result says so.
    edit_k_sensor : sensor name -> its own k (0 or None: that sensor is not edited).
    rank_tol : relative eigenvalue threshold naming unobservable combinations.
    knot_correction : whole-span fit: re-solve the knots at a step's statics when the
        step falls short (:mod:`gcs_core.estimators.whole_span.fit`); False for comparison.
    """

    max_iterations: int = FilterConfig.max_iterations
    tol_step_sigma: float = 1e-4
    tol_chi2: float = 1e-2
    edit_k: float | None = FilterConfig.edit_k
    edit_passes: int = 6
    max_edit_fraction: float = 0.05
    rank_tol: float = 1e-10
    edit_k_sensor: Mapping[str, float | None] = field(default_factory=dict)
    knot_correction: bool = True

    def k_for(self, sensor: str) -> float | None:
        """The editing k of one sensor (None: not edited)."""
        k = self.edit_k_sensor.get(sensor, self.edit_k)
        return k or None


def normal_equations(
    problem: Problem,
    values: Mapping[str, float],
    columns: Sequence[str],
    edited: Mapping[str, np.ndarray] | None = None,
    *,
    jacobian: bool = True,
    store: Residuals | None = None,
    chunk: int | None = None,
    work: dict | None = None,
    second_order: np.ndarray | None = None,
):
    """One streaming pass: ``A = Σ Hᵀ R⁻¹ H``, ``b = Σ Hᵀ R⁻¹ r``, ``χ²`` and the number of
    used measurements, over used frames (valid and not ``edited``), chunk by chunk.

    Each sensor's block adds into the rows and columns it touches only. With ``store``
    the predictions, residuals and validity of every frame are written into its buffers
    (O(N·m), the post-fit residuals). Memory otherwise: one chunk (``work``, a dict the
    caller keeps across passes, holds the chunk buffers so that they are reused).
    ``second_order`` (n, n), if given, receives the Newton terms of the models' parameter
    pairs (:mod:`gcs_core.problem.curvature`).
    """
    n = len(columns) if jacobian else 0
    A = np.zeros((n, n))
    b = np.zeros(n)
    chi2 = 0.0
    m_used = 0
    for blk in iter_blocks(
        problem,
        values,
        columns if jacobian else (),
        exclude=edited or {},
        weighted=True,
        jacobian=jacobian,
        chunk=chunk,
        work=work,
        augmented=True,
        second_order=second_order is not None,
        gram=True,
    ):
        if store is not None:
            if blk.name in store.y_pred:
                store.y_pred[blk.name][blk.lo : blk.hi] = blk.y_pred
            store.r[blk.name][blk.lo : blk.hi] = blk.r
            store.valid[blk.name][blk.lo : blk.hi] = blk.valid
            if blk.name in store.d_att:  # kept when asked (the read-out noise's start)
                D = getattr(blk.pred, "d_att", None)
                store.d_att[blk.name][blk.lo : blk.hi] = D if D is not None and blk.geom.C_BI is not None else 0.0
        nu = int(np.count_nonzero(blk.used))
        if not nu:
            continue
        m_used += nu * blk.r.shape[1]
        if not (n and (blk.Hr is not None or blk.G is not None)):
            rw = blk.weighted_residual()
            chi2 += float(rw @ rw)
            continue
        # [H r]ᵀ [H r] (one symmetric product over the block's columns, BLAS syrk) holds
        # Hᵀ R⁻¹ H, Hᵀ R⁻¹ r and rᵀ R⁻¹ r
        c = blk.cols
        k = c.size
        if blk.curv and second_order is not None:  # curvature is formed only when asked
            curvature.add_block(second_order, c, blk.curv)
        G = blk.gram()
        chi2 += float(G[k, k])
        if k == n and np.array_equal(c, np.arange(n)):
            A += G[:k, :k]
            b += G[:k, k]
        else:
            A[np.ix_(c, c)] += G[:k, :k]
            b[c] += G[:k, k]
    return A, b, chi2, m_used


def name_combinations(A: np.ndarray, names: Sequence[str], rank_tol: float) -> list[str]:
    """Eigen-directions of the (equilibrated) information with no data support."""
    d = np.sqrt(np.clip(np.diag(A), 0, None))
    scale = np.where(d > 0, d, 1.0)
    As = A / np.outer(scale, scale)
    w, V = np.linalg.eigh(As)
    top = max(float(w[-1]), 1e-300)
    out = []
    null = np.nonzero(w <= rank_tol * top)[0]
    # the sparsest basis of the null space: one sensor's aliases apart from another's
    basis = sparse_basis(V[:, null]) if null.size else V[:, null]
    for i in range(basis.shape[1]):
        v = basis[:, i]
        v = -v if v[np.argmax(np.abs(v))] < 0 else v
        order = np.argsort(-np.abs(v))
        terms = [f"{v[j]:+.2f}·{names[j]}" for j in order if abs(v[j]) > 0.1][:6]
        out.append(" ".join(terms))
    for j in np.nonzero(d == 0)[0]:
        out.append(f"{names[int(j)]} (no data depends on it)")
    return out


def _solve_normal(N: np.ndarray, rhs: np.ndarray):
    """Solve ``N x = rhs`` for symmetric positive definite N (equilibrated Cholesky).

    Returns x and the inverse of N (the covariance), formed from the factor.
    """
    d = np.sqrt(np.diag(N))
    if np.any(~np.isfinite(d)) or np.any(d <= 0):
        raise np.linalg.LinAlgError("zero diagonal")
    Ns = N / np.outer(d, d)
    c, low = linalg.cho_factor(Ns, lower=True, check_finite=False)
    x = linalg.cho_solve((c, low), rhs / d, check_finite=False) / d
    Pinv = linalg.cho_solve((c, low), np.eye(N.shape[0]), check_finite=False)
    P = Pinv / np.outer(d, d)
    return x, 0.5 * (P + P.T)  # symmetrize: round-off only


def batch_fit(
    problem: Problem,
    options: BatchOptions | None = None,
    *,
    edited: Mapping[str, np.ndarray] | None = None,
    initial: Mapping[str, float] | None = None,
    attitude_partials: dict[str, np.ndarray] | None = None,
) -> BatchResult:
    """Iterated batch least squares with a priori and k-σ editing (module docstring).

    ``edited`` pre-flags frames (e.g. a held-out span); ``initial`` starts the iteration
    from other values than the a priori (a warm start) without moving the prior mean.
    ``attitude_partials``, a dict, receives each sensor's attitude partials ``D`` (N, m, 3)
    at the solution (0 where a model has none), beside the result's residuals.
    The steps: the passes over the data (:class:`_Passes`), the damped Gauss–Newton
    iterations of each editing pass (:func:`_iterate`, :func:`_damped_step`) and the
    solution (:func:`_solution`).
    """
    opts = options or BatchOptions()
    state = problem.state
    names = tuple(state.solve_for)
    cons = tuple(state.consider)
    if not names:
        raise EstimationError("nothing to estimate: every state element is held or consider")
    ev = _Passes(problem, names, edited)
    if attitude_partials is not None:
        ev.buffers.ensure(problem, attitude_partials=True)
    x = ev.x_bar.copy()
    if initial:
        x = np.array([float(initial.get(nm, ev.x_bar[j])) for j, nm in enumerate(names)])
    rec = _Record()
    groups = local_refine.own_nonlinear(problem, names)  # a sensor's own non-linear elements
    edits_on = any(opts.k_for(sd.name) for sd in problem.sensors)
    for edit_pass in range(opts.edit_passes if edits_on else 1):
        x = _iterate(ev, opts, x, rec, groups)
        ev.set_x(x)
        if not edits_on:
            break
        if not _stored_at(ev.stored, x, ev.edits):
            ev.evaluate(x)
        ev.edits, suspect, changed = edit_frames(problem, ev.buffers, ev.preflag, opts, ev.edits)
        rec.suspect |= suspect
        if not changed:
            break
        log.info("editing pass %d: %d frames flagged", edit_pass + 1, sum(int(v.sum()) for v in ev.edits.values()))
    ev.set_x(x)
    message = rec.message + suspect_note(rec.suspect, opts)
    final = ev.stored if not cons and _stored_at(ev.stored, x, ev.edits) else None
    if attitude_partials is not None:  # the buffers hold the solution's pass (_solution)
        attitude_partials.update(ev.buffers.d_att)
    return _solution(
        problem,
        opts,
        ev.values,
        x,
        ev.prior_info,
        ev.edits,
        ev.buffers,
        ev.work,
        final,
        tuple(rec.history),
        rec.it_total,
        rec.status,
        message,
    )


@dataclass
class _Record:
    """What a batch fit reports of its iterations: the cost per iteration, the count, the
    cost's fall in the last accepted one, the outcome and the sensors too bad to edit."""

    history: list[float] = field(default_factory=list)
    it_total: int = 0
    change: float = 0.0
    status: str = "max_iterations"
    message: str = ""
    suspect: set[str] = field(default_factory=set)


class _Passes:
    """Passes of the batch over the data at a point ``x``: the normal equations and the cost
    (Eq 3-1, 3-2), the residuals in ``buffers``; the last pass with the Jacobian is kept
    (``stored``: ``(x, edits, A, χ², m)``) so that the solution need not repeat it."""

    def __init__(self, problem: Problem, names: tuple[str, ...], edited):
        state = problem.state
        self.problem, self.names = problem, names
        self.x_bar = np.array([state[nm].value for nm in names])
        s0 = np.array([state[nm].sigma0 for nm in names])
        self.prior_info = np.where(np.isfinite(s0) & (s0 > 0), 1.0 / np.where(s0 > 0, s0, 1.0) ** 2, 0.0)
        self.values = state.values()
        self.preflag = {k: np.asarray(v, bool).copy() for k, v in (edited or {}).items()}
        self.edits = {k: v.copy() for k, v in self.preflag.items()}
        self.count = 0  # measurement components of the last pass
        self.buffers = Residuals().ensure(problem)
        self.work: dict = {}  # chunk buffers, reused by every pass
        self.stored: tuple | None = None

    def set_x(self, x) -> None:
        for j, nm in enumerate(self.names):
            self.values[nm] = x[j]

    def evaluate(self, x_eval, with_jacobian=True):
        """(A, b, cost, x̄ − x, K) at ``x_eval``; ``K`` the Newton terms of the models'
        parameter pairs (used near the noise floor), None without the Jacobian."""
        self.set_x(x_eval)
        n = len(self.names)
        K_ = np.zeros((n, n)) if with_jacobian else None
        A_, b_, chi2_, m_ = normal_equations(
            self.problem,
            self.values,
            self.names,
            self.edits,
            jacobian=with_jacobian,
            store=self.buffers if with_jacobian else None,
            work=self.work,
            second_order=K_,
        )
        if with_jacobian:
            self.stored = (x_eval.copy(), self.edits, A_, chi2_, m_)
        self.count = m_
        d_ = self.x_bar - x_eval
        cost_ = chi2_ + float(np.sum(self.prior_info * d_**2))
        return A_, b_, cost_, d_, K_


def _iterate(ev: _Passes, opts: BatchOptions, x: np.ndarray, rec: _Record, groups) -> np.ndarray:
    """Damped Gauss–Newton iterations from ``x`` with the current edits until converged,
    stalled or at the limit (the outcome in ``rec``); returns the last accepted point."""
    names, prior_info = ev.names, ev.prior_info
    A, b, cost, dx_prior, K = ev.evaluate(x)
    lam_state = 0.0
    if not np.isfinite(cost):
        raise EstimationError("the initial state gives non-finite residuals; check the a-priori values")
    rec.history.append(cost)
    for it in range(opts.max_iterations):
        rec.it_total += 1
        Nmat = A + np.diag(prior_info)
        try:
            step, P = _solve_normal(Nmat, b + prior_info * dx_prior)
        except np.linalg.LinAlgError:
            combos = name_combinations(A, names, opts.rank_tol)
            raise UnobservableError(
                "the normal matrix is singular: the data cannot separate " + "; ".join(combos or ["(unidentified)"]),
                combos,
            ) from None
        sig = np.sqrt(np.diag(P))
        N_newton = None if K is None else curvature.newton_matrix(Nmat, K, cost, ev.count)
        if N_newton is not None:  # near the noise floor: the Newton step (curvature.py)
            Nmat = N_newton
            step = _solve_normal(Nmat, b + prior_info * dx_prior)[0]
        if it and np.all(np.abs(step) <= opts.tol_step_sigma * np.maximum(sig, 1e-300)):
            # converged: the next step is negligible against σ; the solution is this
            # point, whose residuals and covariance the last pass already holds
            rec.status, rec.message = "converged", f"converged after {it} iterations"
            rec.it_total -= 1
            break
        rhs = b + prior_info * dx_prior
        found, step = _damped_step(ev, opts, x, cost, Nmat, rhs, step, sig, lam_state, groups)
        if found is None:
            # the cost is finite and never rose (steps are accepted only when they lower
            # it): a stall, reported with its numbers (stopping.py)
            rec.status, rec.message = stopping.stalled(
                rec.it_total - 1, cost, rec.change, float(rhs @ step), "no damped step lowers the cost"
            )
            break
        x_try, trial, lam, first = found
        frac = 1.0 if lam == 0 else 0.0
        lam_state = lam / 10.0 if lam > 1e-4 else 0.0
        rec.change = cost - trial[2]
        A, b, cost, dx_prior, K = trial if first else ev.evaluate(x_try)
        m_meas = ev.count
        x = x_try
        rec.history.append(cost)
        # converged: steps negligible against σ, or the cost no longer moves (absolutely,
        # or relatively for a model far from the data, whose χ² is huge)
        # a model far from the data (χ² > 2 per measurement) crawls along flat valleys;
        # its precise minimum is meaningless, so it stops at a relative change of 1e-4
        tol = opts.tol_chi2 if cost < 2.0 * max(m_meas, 1) else max(opts.tol_chi2, 1e-4 * cost)
        if (frac == 1.0 or it >= 2) and rec.change < tol:
            rec.status, rec.message = "converged", f"converged after {it + 1} iterations"
            break
    else:
        rec.status, rec.message = stopping.iteration_limit(opts.max_iterations, cost, rec.change)
    return x


def _damped_step(ev: _Passes, opts: BatchOptions, x, cost, Nmat, rhs, step, sig, lam, groups):
    """Levenberg–Marquardt safeguard: a Gauss–Newton step that raises the cost (a model far
    from the data, or a nearly unobservable non-linear direction such as an FSS frequency k
    with amplitude A3 ≈ 0) is re-solved with the normal matrix's diagonal inflated by λ
    until the cost falls; λ relaxes after success (the caller's). The first trial point is
    linearized at once (it is usually accepted, and the pass that gives its cost gives its
    Jacobian too); later trials need the cost only. Returns ((x, the pass there, λ, whether
    it was the first trial) or None when 14 tries do not lower the cost, the last step)."""
    names = ev.names
    for attempt in range(14):
        if lam > 0:
            step, _ = _solve_normal(Nmat + lam * np.diag(np.diag(Nmat)), rhs)
        x_try = x + step
        # a step expected to land near the noise floor (the Gauss–Newton prediction
        # cost − rhsᵀ step) that moves a sensor's own non-linear elements: minimize
        # over those first (local_refine)
        if (
            attempt == 0
            and groups
            and curvature.near_floor(cost - float(rhs @ step), ev.count)
            and local_refine.worth(step, sig, names, groups)
        ):
            x_try = local_refine.refine_local(
                ev.problem,
                ev.values,
                names,
                x_try,
                ev.x_bar,
                ev.prior_info,
                ev.edits,
                groups,
                opts.tol_step_sigma,
            )
        trial = ev.evaluate(x_try, with_jacobian=attempt == 0)
        if np.isfinite(trial[2]) and trial[2] <= cost * (1 + 1e-12) + 1e-9:
            return (x_try, trial, lam, attempt == 0), step
        lam = max(lam * 10.0, 1e-4)
    return None, step


def _solution(
    problem: Problem,
    opts: BatchOptions,
    values: dict,
    x: np.ndarray,
    prior_info: np.ndarray,
    edits: Mapping[str, np.ndarray],
    buffers: Residuals,
    work: dict,
    final,
    history: tuple,
    iterations: int,
    status: str,
    message: str,
) -> BatchResult:
    """The :class:`BatchResult` at the converged ``x`` (Eq 3-2): the normal equations there
    with the consider columns, the noise-only covariance ``P = (A + P₀⁻¹)⁻¹``, each consider
    element's contribution ``S σ_c² Sᵀ`` with ``S = −P A_sc``, the combinations the data
    leave undetermined, and the residuals the buffers hold. ``final`` is ``(x, edits, A,
    χ², m)`` of the last pass when it was at this point with these edits and no consider
    element (then no pass is repeated), else None."""
    state = problem.state
    names = tuple(state.solve_for)
    cons = tuple(state.consider)
    n = len(names)
    if final is None:
        A_all, _, chi2, m_used = normal_equations(problem, values, names + cons, edits, store=buffers, work=work)
    else:
        A_all, chi2, m_used = final[2:]
    A = A_all[:n, :n]
    Nmat = A + np.diag(prior_info)
    _, P = _solve_normal(Nmat, np.zeros(n))
    P_cons = P.copy()
    budget = {}
    if cons:
        S = -P @ A_all[:n, n:]
        for j, c in enumerate(cons):
            contrib = np.outer(S[:, j], S[:, j]) * state[c].sigma0 ** 2
            budget[c] = np.sqrt(np.diag(contrib))
            P_cons += contrib
    unobs = tuple(name_combinations(A, names, opts.rank_tol * 1e3))
    new_state = state.with_values({nm: x[j] for j, nm in enumerate(names)})
    residuals = residuals_from(problem, buffers, edits)
    return BatchResult(
        new_state,
        names,
        cons,
        x,
        P,
        P_cons,
        residuals,
        chi2,
        m_used - n,
        history,
        iterations,
        status,
        message,
        A,
        unobs,
        budget,
    )


def _stored_at(stored, x, edits) -> bool:
    return stored is not None and stored[1] is edits and np.array_equal(stored[0], x)
