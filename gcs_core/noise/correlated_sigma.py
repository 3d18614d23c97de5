"""The elements' σ under a sensor's Gauss–Markov noise, weighted by its long-run factor.

The ``correlated`` weighting (:mod:`gcs_core.noise.correlated`) gives a sensor
with correlated noise the weight of its *long-run* white noise, ``σ √κ``. That is exact for
what the data determine on time scales longer than τ (a bias, an alignment on a slowly
turning spacecraft), and pessimistic for an element whose signature changes from sample to
sample: a star tracker's scale factor multiplies the position of whichever star is tracked,
and over frames of independent stars the correlated noise averages like white noise. The
weighted fit's estimate is still a linear unbiased estimate; its true covariance is the
sandwich with the noise's own correlation (White 1980; Newey & West 1987), over all the
fit's unknowns, the static elements ``x`` and the whole-span knots ``z``
(:mod:`gcs_core.estimators.whole_span.knots`)::

    A = Σ_s J_sᵀ W'_s J_s + Σ_j (process rows) + P₀⁻¹    W'_s = (κ_s σ_s²)⁻¹ I   (the fit's weights)
    B = Σ_s J_sᵀ W'_s (σ_s² C_s) W'_s J_s + Σ_j (process rows) + P₀⁻¹
    Cov = A⁻¹ B A⁻¹,     s_i = sqrt(Cov_ii / (A⁻¹)_ii)

``J_s = [H_s U_s]`` holds a sensor's partials in the static columns and in its frame's knot
(the knots' per-frame partials as the whole-span linearization forms them,
:func:`~gcs_core.estimators.whole_span.knots.knot_rows`). The process noise between knots
and the a priori are pseudo-observations, independent and white as stated: their
information is in both ``A`` and ``B``. ``C_s`` has ``1`` on the diagonal and
``a·exp(−|t_k − t_l|/τ)`` off it (white sensors: ``I``), so ``B`` differs from ``A`` only
in the carried sensors' rows, and the statics' block of the sandwich needs no knot × knot
matrix::

    Cov_xx = P + Σ_s G_sᵀ (C_s/κ_s − I) G_s,      G_s = J_s A⁻¹ E_x = H_s P + U_s X_j

``P = (A⁻¹)_xx`` is the fit's covariance and ``X_j = Cov(z_j, x)`` the knots' cross-covariance
(:meth:`~gcs_core.estimators.whole_span.passes.Dynamics.covariance`, the RTS backward
recursion): ``G_s`` is each row's influence on the estimates, its knot's share included, so
the ratio is marginal over the static attitude and the knots alike (with the gyro's
read-out noise carried the rows of one epoch are coupled in ``A``; ``G_s`` neglects that
coupling in the correction term). ``Gᵀ C G`` is a forward first-order recursion over the
sensor's frames (exact at any spacing) per component, as scaled cumulative sums
(:func:`_forward_sum`). Unlike the residual-based sandwich (:mod:`gcs_core.noise.correlation`)
this one is formed from the partials and the noise model, not the residuals, so what the
attitude absorbed does not bias it. Without a knot covariance (a batch fit: exact; a filter, or a
whole-span result without its factors) ``P`` is the inverse over the static columns alone,
conditional on any process states (:func:`_static_inverse`). The fit's σ are scaled by ``min(1, s_i)``: never
inflated here (a slow signature's σ is the long-run weight's already).

History: conditional on the static attitude, as first built, FHST1.scale_v's ratio read
0.48 where the marginal one reads 0.36 on a τ = 60 s seed (its Monte Carlo predicted /
scatter was 1.61). Conditional on the knots (the static attitude among the columns) the
tracker scales' ratios were within 1 % of the marginal ones, while the gyro bias and its
rate read 0.93–0.95 instead of 0.98–0.99 (``docs/benchmarks.md``, correlated-noise section).
With white noise (no sensor carried) nothing is computed and nothing changes.
"""

from __future__ import annotations

import logging
import math
from collections.abc import Mapping
from dataclasses import fields, replace

import numpy as np

from gcs_core.noise.correlation import equilibrated_inverse
from gcs_core.problem.linearization import iter_blocks

log = logging.getLogger(__name__)

#: a ratio below this is not applied (a numerical failure, not a finding)
S_MIN = 1e-3


#: the forward sum is formed in runs of at most this many τ (``exp`` of it stays finite)
RUN_TAUS = 300.0


def _forward_sum(t: np.ndarray, h: np.ndarray, tau_s: float) -> np.ndarray:
    """``F_k = Σ_{l ≤ k} exp(−(t_k − t_l)/τ) h_l`` for (n, p) rows ``h`` at increasing times
    ``t``: the forward first-order recursion, exact at any spacing, as scaled cumulative
    sums (``exp(−s_k) Σ_{l≤k} exp(s_l) h_l``, ``s = t/τ``) over runs of at most
    :data:`RUN_TAUS` τ, each carrying the last one's sum."""
    s = (t - t[0]) / tau_s
    out = np.empty_like(h)
    carry = np.zeros(h.shape[1])
    s_prev = s[0]
    lo = 0
    while lo < s.size:
        hi = max(int(np.searchsorted(s, s[lo] + RUN_TAUS, side="right")), lo + 1)
        e = s[lo:hi] - s[lo]
        F = np.cumsum(h[lo:hi] * np.exp(e)[:, None], axis=0)
        F += carry * math.exp(-(s[lo] - s_prev))
        F *= np.exp(-e)[:, None]
        out[lo:hi] = F
        carry, s_prev, lo = F[-1], s[hi - 1], hi
    return out


def _knot_covariance(result):
    """``(dynamics, X)`` of a whole-span result with knots, ``X`` (K, d, p) ``Cov(z_j, x)``
    over its solve-for columns (:meth:`Dynamics.covariance`); ``(None, None)`` otherwise."""
    dyn = result.dynamics  # the result protocol's (None without knots)
    if dyn is None or dyn.factors is None or tuple(dyn.names) != tuple(result.solve_for):
        return None, None
    cov = dyn.covariance()
    return (dyn, cov[1]) if cov is not None else (None, None)


def _static_inverse(problem, result, columns, exclude) -> np.ndarray:
    """``(Σ Hᵀ W' H + P₀⁻¹)⁻¹`` over the static columns alone: the inverse whose rows' influence
    is ``H A⁻¹`` when no knot covariance is at hand (a batch fit: the fit's own ``P``; a
    filter, or a whole-span result without its factors: conditional on their process states)."""
    k = len(columns)
    A = np.zeros((k, k))
    for blk in iter_blocks(problem, result.state.values(), columns, weighted=True, exclude=exclude):
        if blk.H is not None and blk.cols.size:
            Hf = blk.H.reshape(-1, blk.cols.size)
            A[np.ix_(blk.cols, blk.cols)] += Hf.T @ Hf
    s0 = np.array([result.state[n].sigma0 for n in columns])
    A += np.diag(np.where(np.isfinite(s0) & (s0 > 0), 1.0 / np.where(s0 > 0, s0, 1.0) ** 2, 0.0))
    d = np.sqrt(np.diag(A))
    d = np.where(np.isfinite(d) & (d > 0), d, 1.0)
    return equilibrated_inverse(A / np.outer(d, d)) / np.outer(d, d)


def _influence(blk, P: np.ndarray, dyn, X) -> np.ndarray:
    """(n, m, p) the block's weighted rows times the statics' columns of the full inverse
    normal matrix, ``[H_x  U_z] [P; X_j]`` (module docstring): each row's influence on the
    estimates, the knots' share through ``Cov(z_j, x)``."""
    g = np.einsum("nmc,cp->nmp", blk.H, P[blk.cols])
    knots = dyn.knot_partials(blk) if X is not None else None
    if knots is None:
        return g
    U, j = knots
    return g + np.einsum("nmd,ndp->nmp", U, X[j])


def _excess(t: np.ndarray, g: np.ndarray, tau: float, share: float, kappa: float) -> np.ndarray:
    """(p,) ``diag(gᵀ (C/κ − I) g)`` summed over the components of one sensor's rows ``g``
    (n, m, p) at increasing times ``t``: the variance its correlated noise adds to (or takes
    from) what the fit's white weights ``(σ² κ)⁻¹`` predict. The kernel being symmetric,
    ``Σ_kl g_k g_l exp(−|t_k − t_l|/τ) = 2 Σ_k g_k F_k − Σ_k g_k²`` (:func:`_forward_sum`)."""
    out = np.zeros(g.shape[2])
    for c in range(g.shape[1]):
        h = g[:, c, :]
        hh = np.einsum("np,np->p", h, h)
        hCh = 2.0 * np.einsum("np,np->p", h, _forward_sum(t, h, tau)) - hh
        out += ((1.0 - share) * hh + share * hCh) / kappa - hh
    return out


def sigma_ratios(problem, result, carried: Mapping[str, tuple[float, float, float]]) -> dict[str, float]:
    """Element -> ``s_i`` (module docstring) of the solve-for elements other than the attitude's
    (whose σ are left as the fit gives them), marginal over the static attitude and the
    whole-span knots. ``carried``: sensor -> ``(τ [s], share a, κ)`` of the sensors the fit
    weighted by ``σ √κ`` (the problem's σ are those weights)."""
    state = result.state
    columns = list(result.solve_for)
    if not columns or not carried:
        return {}
    exclude = {n: ~np.asarray(r.used, bool) for n, r in result.residuals.items()}
    dyn, X = _knot_covariance(result)
    if dyn is not None:
        P, prob = np.asarray(result.P, float), dyn.problem(problem, readout=True)
    else:
        P, prob = _static_inverse(problem, result, columns, exclude), problem
    rows: dict[str, list] = {}
    blocks = iter_blocks(prob, state.values(), columns, weighted=True, exclude=exclude, sensors=list(carried))
    for blk in blocks:
        if blk.H is None or not blk.cols.size or not np.any(blk.used):
            continue
        keep = blk.used
        t = blk.sensor.t[blk.lo : blk.hi][keep]
        rows.setdefault(blk.sensor.name, []).append((t, _influence(blk, P, dyn, X)[keep]))
    cov = np.diag(P).copy()
    for name, parts in rows.items():
        tau, share, kappa = carried[name]
        t = np.concatenate([p[0] for p in parts])
        g = np.concatenate([p[1] for p in parts])
        order = np.argsort(t, kind="stable")
        cov += _excess(t[order], g[order], tau, share, kappa)
    s = np.sqrt(np.maximum(cov, 0.0) / np.maximum(np.diag(P), 1e-300))
    return {n: float(v) for n, v in zip(columns, s) if math.isfinite(v) and state[n].kind != "attitude"}


def rescaled(result, ratios: Mapping[str, float]):
    """``result`` with its covariance rescaled by ``D = diag(min(1, s_i))`` (``D P D``, also
    ``P_consider`` where the result has it): σ shrink where the long-run weight was
    pessimistic, correlations are kept."""
    if not ratios:
        return result
    d = np.array([min(1.0, ratios.get(n, 1.0)) if ratios.get(n, 1.0) > S_MIN else 1.0 for n in result.solve_for])
    if np.all(d == 1.0):
        return result
    names = {f.name for f in fields(result)}
    ch = {key: getattr(result, key) * np.outer(d, d) for key in ("P", "P_consider") if key in names}
    return replace(result, **ch)


def honest(problem, result, corr, scale: Mapping[str, float]):
    """``result`` with the σ of its elements from the sandwich with each carried sensor's
    Gauss–Markov correlation (``corr``: sensor -> its correlation, with ``tau_s``, ``share``,
    ``significant``; ``scale``: the factors ``√κ`` the fit weighted with)."""
    carried = {}
    for n, k in scale.items():
        c = corr.get(n)
        if c is not None and c.significant and math.isfinite(c.tau_s) and c.tau_s > 0 and k > 1.0:
            carried[n] = (c.tau_s, c.share, k * k)
    return rescaled(result, sigma_ratios(problem, result, carried))
