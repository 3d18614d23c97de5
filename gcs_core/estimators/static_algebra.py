"""The algebra of a fit whose state is static between its parameters (the batch, Eq 3-1,
3-2; the whole-span fit without process noise; the Kalman smoother's final statics): what
:class:`~gcs_core.estimators.results.FitResult` answers for such a fit.

* :func:`leverage` — each sensor's share ``tr(P A_s)`` of the effective parameters;
* :func:`holdout_rms` and :func:`holdout_chi2` — the held-out frames standardized by noise
  and the training fit's uncertainty ``H P Hᵀ`` carried to them;
* :class:`NoElimination` — a static fit has no nuisance columns to eliminate from the score
  tests of candidate effects (the whole-span fit's knots are one:
  :mod:`gcs_core.estimators.whole_span.elimination`).

The whole-span fit with its knots answers the same questions in
:mod:`gcs_core.estimators.whole_span.uses`.
"""

from __future__ import annotations

from collections.abc import Mapping
from dataclasses import dataclass
from typing import Protocol

import numpy as np
from scipy import linalg

from gcs_core.problem.build import Problem
from gcs_core.problem.linearization import iter_blocks, linearize

#: the influence of a static fit: ``tr(P A_s)`` per sensor
STATIC_SOURCE = "trace of P A"


@dataclass(frozen=True)
class Influence:
    """How much of the data a fit spends on its own parameters (its effective parameters).

    per_sensor : sensor -> its share; source : how it was formed (reports quote it);
    static : True when the shares are ``tr(P A_s)`` of the static elements alone (then
    ``P`` may be a smoother's, and the goodness of fit caps their sum at the count of
    elements).
    """

    per_sensor: dict[str, float]
    source: str
    static: bool


@dataclass(frozen=True)
class HoldoutChi2:
    """Held-out χ² sums of a training fit: sensor -> (χ², measurements), and all sensors
    together (with their correlation through the fit's common errors where it is formed)."""

    per_sensor: dict[str, tuple[float, int]]
    total: tuple[float, int]


def effective_parameters(P: np.ndarray, A: np.ndarray) -> float:
    """``tr(P A)``: the effective number of parameters of a static-state fit; ``P`` (n, n)
    the posterior covariance, ``A`` (n, n) the data information."""
    return float(np.sum(np.asarray(P) * np.asarray(A).T))


def leverage(problem: Problem, result) -> Influence:
    """Sensor -> ``tr(P A_s)``, its share of the fit's effective parameters.

    ``A_s = Σ Hᵀ R⁻¹ H`` over the sensor's used frames at the fitted state, one
    streaming pass (:func:`~gcs_core.problem.linearization.iter_blocks`); ``P`` the fit's
    noise-only covariance over ``result.solve_for``.
    """
    names = tuple(result.solve_for)
    n = len(names)
    if not n:
        return Influence({name: 0.0 for name in result.residuals}, STATIC_SOURCE, True)
    P = np.asarray(result.P)
    edited = {k: np.asarray(r.edited, bool) for k, r in result.residuals.items()}
    A = {sd.name: np.zeros((n, n)) for sd in problem.sensors}
    for blk in iter_blocks(
        problem, result.state.values(), names, exclude=edited, weighted=True, augmented=True, gram=True
    ):
        if not np.any(blk.used):
            continue
        c = blk.cols
        k = c.size
        G = blk.gram()
        A[blk.name][np.ix_(c, c)] += G[:k, :k]
    return Influence({name: effective_parameters(P, As) for name, As in A.items()}, STATIC_SOURCE, True)


def holdout_rms(problem: Problem, res, masks: Mapping[str, np.ndarray]) -> dict[str, float]:
    """Normalized RMS of the held-out frames of a fit without process noise, each residual
    standardized by its full prediction uncertainty ``sqrt(σ² + (H P Hᵀ)_ii)`` (noise plus
    the uncertainty of the training fit carried to that frame), so 1.0 is the expected
    value for a right model."""
    lins = {l.name: l for l in linearize(problem, res.state.values(), res.solve_for)}
    out = {}
    for name, r in res.residuals.items():
        m = masks.get(name)
        lin = lins.get(name)
        if m is None or lin is None:
            continue
        sel = m & r.valid
        if not np.any(sel):
            continue
        H = lin.H[sel]
        var_pred = np.einsum("kmn,np,kmp->km", H, res.P, H, optimize=True)
        z = r.residual[sel] / np.sqrt(lin.sigma[None, :] ** 2 + var_pred)
        out[name] = float(np.sqrt(np.mean(z**2)))
    return out


def holdout_chi2(problem: Problem, train, sel: Mapping[str, np.ndarray]) -> HoldoutChi2 | None:
    """χ² of the held-out frames ``sel`` (sensor -> (N,) True where held out) under the
    static training fit ``train``: per sensor and all together, each the Woodbury form of
    ``rᵀ (R + H P Hᵀ)⁻¹ r`` (the training fit's errors common to all frames kept)."""
    names = tuple(train.solve_for)
    n = len(names)
    exclude = {sd.name: ~sel.get(sd.name, np.zeros(sd.n, bool)) for sd in problem.sensors}
    acc: dict[str, list] = {}
    for blk in iter_blocks(
        problem,
        train.state.values(),
        names,
        sensors=list(sel),
        exclude=exclude,
        weighted=True,
        augmented=True,
        gram=True,
    ):
        nu = int(np.count_nonzero(blk.used))
        if not nu:
            continue
        a = acc.setdefault(blk.name, [np.zeros((n, n)), np.zeros(n), 0.0, 0])
        c = blk.cols
        k = c.size
        G = blk.gram()
        a[0][np.ix_(c, c)] += G[:k, :k]
        a[1][c] += G[:k, k]
        a[2] += float(G[k, k])
        a[3] += nu * blk.r.shape[1]
    if not acc:
        return None
    L = chol_cov(np.asarray(train.P))
    per = {name: (woodbury_chi2(L, *v[:3]), v[3]) for name, v in acc.items()}
    tot = [sum(v[i] for v in acc.values()) for i in range(4)]
    return HoldoutChi2(per, (woodbury_chi2(L, *tot[:3]), tot[3]))


def chol_cov(P: np.ndarray) -> np.ndarray:
    """A factor ``L`` with ``L Lᵀ = P`` (equilibrated Cholesky; eigen-factor if P is
    only semi-definite)."""
    if P.size == 0:
        return P
    d = np.sqrt(np.clip(np.diag(P), 1e-300, None))
    Ps = P / np.outer(d, d)
    try:
        return d[:, None] * linalg.cholesky(Ps, lower=True, check_finite=False)
    except linalg.LinAlgError:
        w, V = np.linalg.eigh(0.5 * (Ps + Ps.T))
        return d[:, None] * (V * np.sqrt(np.clip(w, 0.0, None)))


def woodbury_chi2(L: np.ndarray, A_h: np.ndarray, g: np.ndarray, c: float) -> float:
    """``c − gᵀ (P⁻¹ + A_h)⁻¹ g`` with ``P = L Lᵀ``: ``(P⁻¹ + A_h)⁻¹ = L (I + Lᵀ A_h L)⁻¹ Lᵀ``,
    whose middle matrix has every eigenvalue ≥ 1 (well conditioned whatever P is)."""
    if L.size == 0:
        return float(c)
    S = np.eye(L.shape[1]) + L.T @ A_h @ L
    u = L.T @ g
    return float(c - u @ linalg.solve(0.5 * (S + S.T), u, assume_a="pos", check_finite=False))


class Elimination(Protocol):
    """Nuisance columns of a fit eliminated from the score tests' normal equations, fed block
    by block as the ranking streams over the data (:class:`NoElimination`,
    :class:`gcs_core.estimators.whole_span.elimination.KnotElimination`)."""

    problem: Problem

    def visit(self, sd) -> None: ...

    def add(self, blk, Hm: np.ndarray, rw: np.ndarray, c: np.ndarray) -> None: ...

    def passed(self, sd, hi: int) -> None: ...

    def finish(self) -> None: ...

    def eliminate(self, N: np.ndarray, g: np.ndarray) -> tuple[np.ndarray, np.ndarray]: ...


class NoElimination:
    """The score tests' nuisance elimination of a static fit: none. Every method leaves the
    normal equations as they are (the whole-span fit's knots:
    :class:`gcs_core.estimators.whole_span.elimination.KnotElimination`)."""

    def __init__(self, problem: Problem):
        self.problem = problem  # linearize the candidates about this problem

    def visit(self, sd) -> None:
        """A sensor's blocks begin."""

    def add(self, blk, Hm: np.ndarray, rw: np.ndarray, c: np.ndarray) -> None:
        """A block's weighted rows over the columns ``c``."""

    def passed(self, sd, hi: int) -> None:
        """The sensor's frames up to ``hi`` are done."""

    def finish(self) -> None:
        """Every block is in."""

    def eliminate(self, N: np.ndarray, g: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """The normal equations ``N``, ``g`` over the state and candidate columns, with the
        nuisance columns eliminated (here, unchanged)."""
        return N, g
