"""The elements' σ under a sensor's Gauss–Markov noise, weighted by its long-run factor.

The ``correlated`` weighting (:mod:`gcs_core.noise.correlated`) gives a sensor
with correlated noise the weight of its *long-run* white noise, ``σ √κ``. That is exact for
what the data determine on time scales longer than τ (a bias, an alignment on a slowly
turning spacecraft), and pessimistic for an element whose signature changes from sample to
sample: a star tracker's scale factor multiplies the position of whichever star is tracked,
and over frames of independent stars the correlated noise averages like white noise. The
weighted fit's estimate is still a linear unbiased estimate; its true covariance is the
sandwich with the noise's own correlation (White 1980; Newey & West 1987)::

    A = Σ_s H_sᵀ W'_s H_s + P₀⁻¹                     W'_s = (κ_s σ_s²)⁻¹ I   (the fit's weights)
    B = Σ_s H_sᵀ W'_s (σ_s² C_s) W'_s H_s           C_s: the sensor's Gauss–Markov correlation
    Cov = A⁻¹ B A⁻¹,     s_i = sqrt(Cov_ii / (A⁻¹)_ii)

``C_s`` has ``1`` on the diagonal and ``a·exp(−|t_k − t_l|/τ)`` off it (white sensors: ``I``),
so ``H_sᵀ C_s H_s`` needs no n × n matrix: ``Σ_l exp(−|t_k − t_l|/τ) h_l`` is a forward
plus a backward first-order recursion over the sensor's frames (exact at any spacing), per
component. Unlike the residual-based sandwich (:mod:`gcs_core.noise.correlation`) this
one is formed from the partials and the noise model, not the residuals, so what the attitude
absorbed does not bias it. The static attitude (roll, pitch, yaw) is among its columns, so
the ratio is marginal over it; it is conditional on the whole-span knots (not eliminated
here): their freedom takes the slow part of a signature, where the correlation costs most,
so the marginal ratio is at most this one, and scaling the fit's σ by ``min(1, s_i)`` stays
on the safe side. (Conditional on the static attitude too, as first built, FHST1.scale_v's
ratio read 0.48 where the marginal one reads 0.36 on a τ = 60 s seed: its Monte Carlo
predicted/scatter was 1.61.) With
white noise (no sensor carried) nothing is computed and nothing changes.
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


def _correlated_sum(t: np.ndarray, H: np.ndarray, tau_s: float) -> np.ndarray:
    """``U_k = Σ_l exp(−|t_k − t_l|/τ) H_l`` for (n, k) rows ``H`` at increasing times ``t``
    (forward and backward recursions; the k = l term counted once)."""
    n = t.shape[0]
    decay = np.exp(-np.diff(t) / tau_s)
    f = np.empty_like(H)
    b = np.empty_like(H)
    f[0] = H[0]
    for k in range(1, n):
        f[k] = H[k] + decay[k - 1] * f[k - 1]
    b[-1] = H[-1]
    for k in range(n - 2, -1, -1):
        b[k] = H[k] + decay[k] * b[k + 1]
    return f + b - H


def sigma_ratios(problem, result, carried: Mapping[str, tuple[float, float, float]]) -> dict[str, float]:
    """Element -> ``s_i`` (module docstring) of the solve-for elements other than the attitude's
    (whose σ are left as the fit gives them), the static attitude among the sandwich's
    columns. ``carried``: sensor -> ``(τ [s], share a, κ)`` of the sensors the fit weighted
    by ``σ √κ`` (the problem's σ are those weights)."""
    state = result.state
    columns = list(result.solve_for)
    if not columns or not carried:
        return {}
    k = len(columns)
    A = np.zeros((k, k))
    B = np.zeros((k, k))
    rows: dict[str, list] = {}
    exclude = {n: ~np.asarray(r.used, bool) for n, r in result.residuals.items()}
    for blk in iter_blocks(problem, state.values(), columns, weighted=True, exclude=exclude):
        if blk.H is None or not blk.cols.size:
            continue
        H, c = blk.H, blk.cols
        Hf = H.reshape(-1, c.size)
        G = Hf.T @ Hf
        A[np.ix_(c, c)] += G
        name = blk.sensor.name
        if name in carried:
            rows.setdefault(name, []).append((blk.sensor.t[blk.lo : blk.hi].copy(), H.copy(), c))
        else:
            B[np.ix_(c, c)] += G
    for name, parts in rows.items():
        tau, share, kappa = carried[name]
        cols = np.unique(np.concatenate([c for _, _, c in parts]))
        pos = {int(j): i for i, j in enumerate(cols)}
        t = np.concatenate([p[0] for p in parts])
        Hs = np.zeros((t.size, parts[0][1].shape[1], cols.size))
        r0 = 0
        for tt, H, c in parts:
            Hs[r0 : r0 + tt.size][:, :, [pos[int(j)] for j in c]] = H
            r0 += tt.size
        order = np.argsort(t, kind="stable")
        t, Hs = t[order], Hs[order]
        keep = np.any(Hs != 0.0, axis=(1, 2))  # used rows only (unused rows are zero)
        t, Hs = t[keep], Hs[keep]
        Bs = np.zeros((cols.size, cols.size))
        for j in range(Hs.shape[1]):
            h = Hs[:, j, :]
            U = _correlated_sum(t, h, tau) if t.size > 1 else h
            Bs += (1.0 - share) * (h.T @ h) + share * (h.T @ U)
        B[np.ix_(cols, cols)] += 0.5 * (Bs + Bs.T) / kappa  # σ²C in units of the weight σ²κ: C/κ
    prior = [
        1.0 / state[n].sigma0 ** 2 if np.isfinite(state[n].sigma0) and state[n].sigma0 > 0 else 0.0 for n in columns
    ]
    A += np.diag(prior)
    d = np.sqrt(np.diag(A))
    d = np.where(np.isfinite(d) & (d > 0), d, 1.0)
    Ainv = equilibrated_inverse(A / np.outer(d, d))
    Bd = B / np.outer(d, d) + np.diag(np.asarray(prior) / d**2)  # the a priori's share is as stated
    cov = np.einsum("ij,jk,ki->i", Ainv, Bd, Ainv)
    s = np.sqrt(np.maximum(cov, 0.0) / np.maximum(np.diag(Ainv), 1e-300))
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
