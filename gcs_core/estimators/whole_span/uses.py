"""What the knots of a whole-span fit give the rest of GCS (:mod:`.fit`), through its result
(:class:`.result.SmoothedResult`) and the predictor.

* :func:`smoothed_holdout_rms` — held-out residuals standardized by noise, static and knot
  uncertainty together;
* :func:`attitude_covariance` — the knots' share of the ground attitude's σ (VERIF);
* :func:`batch_wander_cost` — what taking the gyro as exact costs a batch solution on its
  data (the batch method's computed warning);
* :func:`predicted_covariance` — the whole-span covariance without data (the predictor).
"""

from __future__ import annotations

from collections.abc import Mapping
from typing import TYPE_CHECKING

import numpy as np

from gcs_core.estimators.batch.least_squares import _solve_normal
from gcs_core.estimators.results import FitResult
from gcs_core.estimators.whole_span import knots as kn
from gcs_core.estimators.whole_span.grid import make_knots, process_noise
from gcs_core.estimators.whole_span.passes import Dynamics, Passes
from gcs_core.estimators.whole_span.readout import row_variance
from gcs_core.problem.build import Problem
from gcs_core.problem.linearization import iter_blocks

if TYPE_CHECKING:  # the result reads its algebra from here
    from gcs_core.estimators.whole_span.result import SmoothedResult


def knot_variance(dyn: Dynamics, U: np.ndarray, j: np.ndarray, HJ: np.ndarray | None = None, cols=None) -> np.ndarray:
    """Variance added to predictions by the knot corrections' uncertainty.

    U (N, m, d) rows of ``∂y/∂z_j`` (:func:`knots.knot_rows`, unweighted); HJ (N, m, k)
    partials over the static ``cols`` (positions in ``dyn.names``). Returns (N, m)::

        u Σ_j uᵀ + 2 u Cov(z_j, x)[:, cols] hᵀ
    """
    Sig, X = dyn.covariance()
    out = np.einsum("nma,nab,nmb->nm", U, Sig[j], U, optimize=True)
    if HJ is not None and HJ.shape[2]:
        Xc = X[j][:, :, np.asarray(cols, int)]
        out += 2.0 * np.einsum("nma,nak,nmk->nm", U, Xc, HJ, optimize=True)
    return out


def smoothed_frames(problem: Problem, res: SmoothedResult, select: Mapping[str, np.ndarray]):
    """(sensor, residual (k, m), noise variance (k, m), prediction variance (k, m)) of the
    ``select``-ed valid frames of a whole-span fit, chunk by chunk: the noise variance
    ``σ² + σ_e² |D|²`` (the data book's σ plus the gyro's read-out error the fit carried,
    :mod:`gcs_core.estimators.whole_span.readout`), the prediction variance
    ``h P hᵀ + u Σ_j uᵀ + 2 u Cov(z_j, x) hᵀ`` of the static elements and the knots."""
    dyn = res.dynamics
    assert dyn is not None  # a whole-span fit with knots (callers check)
    names = tuple(res.solve_for)
    for blk in iter_blocks(dyn.problem(problem), res.state.values(), names, weighted=False):
        m = select.get(blk.name)
        if m is None:
            continue
        sel = m[blk.lo : blk.hi] & blk.valid
        if not np.any(sel):
            continue
        sd = blk.sensor
        c = blk.cols
        H = np.nan_to_num(blk.H[sel]) if blk.H is not None else np.zeros((int(sel.sum()), len(sd.sigma), 0))
        var = np.einsum("nmk,kl,nml->nm", H, res.P[np.ix_(c, c)], H, optimize=True)
        D = getattr(blk.pred, "d_att", None)
        noise = np.broadcast_to(sd.sigma[None, :] ** 2, var.shape)
        if D is not None and blk.geom.C_BI is not None:
            t = sd.t[blk.lo : blk.hi][sel]
            j = dyn.grid.index(t)
            C = kn.chained_attitude(blk.geom.C_BI[sel], dyn.grid, dyn.z, dyn.R, t)
            U = kn.knot_rows(np.nan_to_num(D[sel]), C, t, j, dyn.grid, dyn.R)
            var = var + knot_variance(dyn, U, j, H, c)
            if dyn.sig_e2:
                noise = noise + row_variance(D[sel], dyn.sig_e2)
        yield blk.name, blk.r[sel], noise, np.clip(var, 0, None)


def smoothed_holdout_rms(problem: Problem, res: SmoothedResult, masks: Mapping[str, np.ndarray]) -> dict[str, float]:
    """Normalized RMS of the held-out frames of a whole-span fit trained without them.

    Each residual (at the smoothed attitude, whose knots cross the held-out span on the
    process prior alone) is standardized by its full prediction uncertainty
    ``sqrt(σ² + h P hᵀ + u Σ_j uᵀ + 2 u Cov(z_j, x) hᵀ)``: noise, static elements and the
    knot corrections (:func:`smoothed_frames`), so 1.0 is the expected value for a right model.
    """
    sums: dict[str, list] = {}
    for name, r, noise, var in smoothed_frames(problem, res, masks):
        zz = r / np.sqrt(noise + var)
        acc = sums.setdefault(name, [0.0, 0])
        acc[0] += float(np.sum(zz**2))
        acc[1] += zz.size
    return {k: float(np.sqrt(v[0] / v[1])) for k, v in sums.items() if v[1]}


def batch_wander_cost(problem: Problem, res: FitResult) -> dict | None:
    """What ignoring the gyro noise costs a batch solution on these data (one pass).

    At the batch solution the knots of the whole-span problem are added and eliminated:
    ``P_q`` (the reduced normal matrix with the process noise, inverted) against the
    batch's ``P_b``. The batch estimate is a linear estimator of the same data, so its
    error covariance is at least ``P_q``: its σ are too small by ``sqrt(P_q,ii/P_b,ii)``
    and the wander adds an expected error of ``sqrt((P_q,ii − P_b,ii)/P_b,ii)`` batch σ.
    ``delta_chi2`` is the χ² the knot corrections remove in one Gauss–Newton step (the
    residual signature of the wander the batch leaves to the diagnosis).
    """
    noise = process_noise(problem)
    if noise is None or not res.solve_for or res.information is None:
        return None
    state = problem.state
    names = tuple(res.solve_for)
    x_bar = np.array([state[nm].value for nm in names])
    s0 = np.array([state[nm].sigma0 for nm in names])
    prior_info = np.where(np.isfinite(s0) & (s0 > 0), 1.0 / np.where(s0 > 0, s0, 1.0) ** 2, 0.0)
    grid = make_knots(problem, noise, res.information, names)
    passes = Passes(problem, names, grid, x_bar, prior_info, noise.sigma_e**2)
    passes.keep = False
    edits = {nm: r.edited for nm, r in res.residuals.items()}
    x = np.asarray(res.x, float)
    lin = passes.run(x, np.zeros((grid.K, grid.d)), edits)
    A, b, sysk = lin.A, lin.b, lin.system
    N_red, g_red, _ = sysk.eliminate(A + np.diag(prior_info), b + prior_info * (x_bar - x))
    dx, P_q = _solve_normal(N_red, g_red)
    pb = np.clip(np.diag(res.P), 1e-300, None)
    ratio = np.sqrt(np.diag(P_q) / pb)
    extra = np.sqrt(np.clip(np.diag(P_q) - pb, 0, None) / pb)
    order = np.argsort(-ratio)
    return {
        "sigma_ratio": [(names[i], float(ratio[i])) for i in order],
        "bias_sigma": {names[i]: float(extra[i]) for i in order},
        "worst_bias_sigma": float(extra.max()) if extra.size else 0.0,
        "delta_chi2": float(g_red @ dx) + sysk.knot_gain,
    }


def attitude_covariance(dyn: Dynamics, C: np.ndarray, t: np.ndarray, J: np.ndarray) -> np.ndarray:
    """(N, 3, 3) body-frame attitude error covariance added by the knots at times ``t``:
    ``δθ = C [I | Γ_j(t)] z_j`` with ``J`` (N, 3, n) the static partials over ``dyn.names``,
    plus the gyro's read-out error ``σ_e² I`` the fit carried (:mod:`gcs_core.estimators.whole_span.readout`)."""
    eye = np.broadcast_to(np.eye(3), (t.size, 3, 3))
    j = dyn.grid.index(t)
    U = kn.knot_rows(
        eye, kn.chained_attitude(C, dyn.grid, dyn.z, dyn.R, t), t, j, dyn.grid, dyn.R
    )  # (N, 3, d): ∂δθ/∂z_j
    Sig, X = dyn.covariance()
    S = np.einsum("nia,nab,njb->nij", U, Sig[j], U, optimize=True)
    cross = np.einsum("nia,nak,njk->nij", U, X[j], J, optimize=True)
    out = S + cross + np.swapaxes(cross, 1, 2)
    if dyn.sig_e2:  # the read-out error of the epoch, white (readout.py)
        out += dyn.sig_e2 * np.eye(3)
    return out


def predicted_covariance(
    problem: Problem,
    values: Mapping[str, float],
    names,
    cons,
    exclude,
    information: np.ndarray,
    sigma0: np.ndarray,
    sigma_c: np.ndarray,
):
    """Covariance of the whole-span fit at ``values`` without data (the predictor).

    One linearization with the knots at zero, eliminated: ``P = N_red⁻¹`` over ``names``,
    and the consider elements' ``S P_c Sᵀ`` with ``S = −P N_red[x, c]``. ``exclude``
    flags frames outside the plan; ``information`` (n, n) the statics' data information
    (for the knot spacing). Returns (P, P_consider, budget (c, n) σ) or None when the
    gyro carries no process noise.
    """
    noise = process_noise(problem)
    if noise is None:
        return None
    names, cons = tuple(names), tuple(cons)
    n = len(names)
    prior = np.where(np.isfinite(sigma0) & (sigma0 > 0), 1.0 / np.where(sigma0 > 0, sigma0, 1.0) ** 2, 0.0)
    grid = make_knots(problem, noise, information, names)
    passes = Passes(problem, names, grid, np.array([values[nm] for nm in names]), prior, noise.sigma_e**2)
    passes.values = dict(values)
    passes.keep = False
    x = np.array([values[nm] for nm in names])
    lin = passes.run(x, np.zeros((grid.K, grid.d)), exclude, columns=names + cons)
    A, sysk = lin.A, lin.system
    N = A + np.diag(np.concatenate([prior, np.zeros(len(cons))]))
    N_red, _, _ = sysk.eliminate(N, np.zeros(N.shape[0]))
    _, P = _solve_normal(N_red[:n, :n], np.zeros(n))
    P_cons = P.copy()
    budget = np.zeros((len(cons), n))
    if cons:
        S = -P @ N_red[:n, n:]
        for j in range(len(cons)):
            contrib = np.outer(S[:, j], S[:, j]) * sigma_c[j] ** 2
            budget[j] = np.sqrt(np.diag(contrib))
            P_cons += contrib
    return P, P_cons, budget
