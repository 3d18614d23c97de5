"""The default fit's own problem for ``scipy.optimize.least_squares``
(:mod:`batch_vs_least_squares`): the whole-span MAP cost of
:mod:`gcs_core.estimators.whole_span.fit` as a residual vector, with its Jacobian's
sparsity, as a careful user would hand it over.

Variables: the static elements scaled by their a-priori σ, ``(x − x̄)/σ̄``, and the knot
corrections ``z_1 … z_{K−1}`` (``z_0 = 0``) scaled by their process noise over the
interval that ends at them (``sqrt(a)`` for the attitude, ``sqrt(e)`` for the drift bias of
Farrenkopf's ``Q_j``, :mod:`gcs_core.estimators.whole_span.knots`): both known before any
fit. The knots, their mid-interval axes ``R_j`` and spacing are those the default fit laid
out (the problem, not its solution). Residuals, in order:

* every frame's whitened residual ``(y − h(x, z))/σ`` (0 where the frame is not used), the
  attitude corrected by the knot of its time: it depends on every static and on that
  knot's ``d`` columns only;
* the a-priori rows ``(x − x̄)/σ̄``;
* the process rows ``L_jᵀ e_j``, ``e_j = z_{j+1} − Φ_j z_j``, ``L_j L_jᵀ = Q_j⁻¹``: they
  depend on knots j and j + 1.

``‖f‖² = J`` (the fit's cost: data χ², static prior, process term). The sparsity lets
``least_squares`` difference the knot columns in groups (knots two apart share no row):
the statics' columns plus ``2d`` evaluations per Jacobian, not one per column; with a
sparse Jacobian its trust-region steps use LSMR.
"""

from __future__ import annotations

import time
from dataclasses import replace

import numpy as np
from scipy.optimize import least_squares
from scipy.sparse import coo_matrix

from gcs_core.estimators.whole_span import knots as kn
from gcs_core.estimators.whole_span.passes import CorrectedAttitude
from gcs_core.problem.linearization import iter_blocks


def whole_span_residuals(problem, names, grid: kn.KnotGrid, R: np.ndarray):
    """``(fun, unpack, v0, sparsity, counter)`` for ``least_squares`` on the whole-span
    problem over ``names`` with the knots ``grid`` and axes ``R`` (module docstring);
    ``unpack(v)`` gives ``(x, z)``; ``v0`` is the a priori with no correction."""
    state = problem.state
    x_bar = np.array([state[n].value for n in names])
    s_bar = np.array([state[n].sigma0 for n in names])
    n, K, d = len(names), grid.K, grid.d
    Phi, W = kn.transitions(grid, R)
    L = np.linalg.cholesky(W)  # W_j = L_j L_jᵀ
    dt = np.diff(grid.tau)
    a = grid.sigma_v**2 * dt + grid.sigma_u**2 * dt**3 / 3.0
    s_knot = np.sqrt(a)[:, None] * np.ones((1, 3))
    if d == 6:
        s_knot = np.hstack([s_knot, (grid.sigma_u * np.sqrt(dt))[:, None] * np.ones((1, 3))])
    base = problem.gyro_attitude
    work = state.values()
    count = [0]

    def unpack(v):
        z = np.zeros((K, d))
        z[1:] = v[n:].reshape(K - 1, d) * s_knot
        return x_bar + s_bar * v[:n], z

    def blocks(v):
        x, z = unpack(v)
        for j, nm in enumerate(names):
            work[nm] = x[j]
        prob = replace(problem, attitude=CorrectedAttitude(base, grid, z, R))
        return z, iter_blocks(prob, work, (), jacobian=False)

    def fun(v):
        count[0] += 1
        z, it = blocks(v)
        parts = [np.where(b.valid[:, None], b.r / b.sensor.sigma, 0.0).ravel() for b in it]
        parts.append(np.asarray(v[:n], float).copy())
        e = z[1:] - np.einsum("jab,jb->ja", Phi, z[:-1])
        parts.append(np.einsum("jab,ja->jb", L, e).ravel())  # L_jᵀ e_j
        return np.concatenate(parts)

    v0 = np.zeros(n + (K - 1) * d)
    return fun, unpack, v0, _sparsity(problem, blocks, v0, grid, n), count


def _sparsity(problem, blocks, v0, grid: kn.KnotGrid, n: int):
    """The Jacobian's nonzero pattern (module docstring), from one pass's block layout."""
    K, d = grid.K, grid.d
    layout = [(b.sensor, b.lo, b.hi, b.r.shape[1]) for b in blocks(v0)[1]]
    knot = np.concatenate([np.repeat(grid.index(sd.t[lo:hi]), m) for sd, lo, hi, m in layout])
    m_data = knot.size
    ri, ci = [np.repeat(np.arange(m_data), n)], [np.tile(np.arange(n), m_data)]
    k = np.flatnonzero(knot >= 1)  # z_0 is fixed
    ri.append(np.repeat(k, d))
    ci.append((n + (knot[k] - 1)[:, None] * d + np.arange(d)[None, :]).ravel())
    ri.append(m_data + np.arange(n))
    ci.append(np.arange(n))
    for jj in range(K - 1):  # e_j: knots j (when ≥ 1) and j + 1
        rr = m_data + n + jj * d + np.arange(d)
        for kk in (jj, jj + 1):
            if kk >= 1:
                ri.append(np.repeat(rr, d))
                ci.append(np.tile(n + (kk - 1) * d + np.arange(d), d))
    r, c = np.concatenate(ri), np.concatenate(ci)
    shape = (m_data + n + (K - 1) * d, n + (K - 1) * d)
    return coo_matrix((np.ones(r.size, np.int8), (r, c)), shape=shape).tocsr()


#: ``tr_options`` of the trust-region steps: LSMR's default tolerances (1e-6) leave its
#: steps inexact on this problem (the dense static columns against 6 per knot), and
#: ``least_squares`` then stopped at its default ``ftol`` 1.3 σ from the minimum (4 h
#: mission); at 1e-10 it takes Gauss–Newton-accurate steps and reaches it
LSMR_OPTIONS = {"atol": 1e-10, "btol": 1e-10}


def least_squares_whole_span(problem, ws, *, tol: float = 1e-8, repeats: int = 1) -> dict:
    """``least_squares`` (trf, 2-point differences over the sparsity, LSMR steps) on the
    default fit's problem (``ws``'s knots), from the a priori with no correction; the
    best time of ``repeats`` and its distance to ``ws`` in units of ``ws``'s σ."""
    dyn = ws.dynamics
    names = list(ws.solve_for)
    fun, unpack, v0, sparsity, count = whole_span_residuals(problem, names, dyn.grid, dyn.R)
    best, ls = np.inf, None
    for _ in range(repeats):
        count[0] = 0
        t0 = time.perf_counter()
        ls = least_squares(
            fun,
            v0,
            jac="2-point",
            jac_sparsity=sparsity,
            method="trf",
            ftol=tol,
            xtol=tol,
            gtol=tol,
            tr_options=LSMR_OPTIONS,
        )
        best = min(best, time.perf_counter() - t0)
    x, z = unpack(ls.x)
    sig = np.sqrt(np.diag(ws.P))
    dx = float(np.max(np.abs(x - ws.x) / sig))
    z_sig = dyn.knot_sigma()
    dz = float(np.max(np.abs(z - dyn.z)[1:] / np.maximum(z_sig[1:], 1e-300)))
    return dict(
        t_ls=best,
        nfev=count[0],
        njev=int(ls.njev),
        cost=float(ls.fun @ ls.fun),
        dx_sigma=dx,
        dz_sigma=dz,
        columns=sparsity.shape[1],
        rows=sparsity.shape[0],
        nnz=int(sparsity.nnz),
    )
