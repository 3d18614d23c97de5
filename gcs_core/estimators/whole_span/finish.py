"""The whole-span fit's result at its solution (:mod:`gcs_core.estimators.whole_span.fit`): the
reduced normal matrix inverted (Eq 3-2 with the knots eliminated), the consider elements'
contribution, the residuals against each row's marginal σ (:mod:`.readout`) and the knots.
"""

from __future__ import annotations

from dataclasses import dataclass, replace
from typing import TYPE_CHECKING

import numpy as np

from gcs_core.estimators import stopping
from gcs_core.estimators.batch.editing import suspect_note
from gcs_core.estimators.batch.least_squares import _solve_normal, name_combinations
from gcs_core.estimators.residuals import residuals_from
from gcs_core.estimators.whole_span.passes import Dynamics, SpanLinearization
from gcs_core.estimators.whole_span.result import SmoothedResult
from gcs_core.problem.build import Problem

if TYPE_CHECKING:
    from gcs_core.estimators.whole_span.fit import Iterate


@dataclass(frozen=True)
class _Covariance:
    """The statics' covariance at the solution: noise only (``P``) and with the consider
    elements (``P_consider``, ``budget``), the data information, and the knots' factors."""

    P: np.ndarray
    P_consider: np.ndarray
    budget: dict[str, np.ndarray]
    information: np.ndarray
    factors: tuple


def _covariance(it: Iterate, lin: SpanLinearization, state) -> _Covariance:
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


def finish(problem: Problem, it: Iterate) -> SmoothedResult:
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
