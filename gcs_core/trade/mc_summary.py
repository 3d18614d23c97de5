"""The Monte-Carlo verdict: scatter against the predicted σ, with its own sampling error.

The statistics of :mod:`gcs_core.trade.montecarlo` (its module docstring): per element the
ratio of the sample σ of the runs' errors to the predicted σ, accepted inside the χ² band
of a sample σ widened by :data:`MATCH_FRACTION`; the NEES over the determined elements in
its 95 % χ² band (Bar-Shalom, Li & Kirubarajan 2001, §5.4.2).
"""

from __future__ import annotations

import math
from collections.abc import Mapping, Sequence
from dataclasses import dataclass

import numpy as np

from gcs_core.errors import InputError
from gcs_core.predictor.information import prior_information

#: the acceptance band of predicted against Monte-Carlo σ, beyond the sampling error
MATCH_FRACTION = 0.15
#: family-wise false-alarm rate of the per-element sampling bands (Bonferroni over elements)
ALPHA = 0.05
#: statuses of a run that counts
CONVERGED = ("converged", "max_passes")


@dataclass(frozen=True)
class MonteCarloResult:
    """Scatter against prediction (module docstring); arrays over ``names``.

    ``band`` (lo, hi): the range of ``scatter / predicted`` that agrees within
    :data:`MATCH_FRACTION` once the sampling error of N runs is allowed for."""

    runs: int
    failed: int
    names: tuple[str, ...]
    units: tuple[str, ...]
    predicted: np.ndarray
    scatter: np.ndarray
    ratio: np.ndarray
    mean_z: np.ndarray
    fit_sigma: np.ndarray
    determined: np.ndarray
    nees: float
    nees_band: tuple[float, float]
    nees_dof: int
    band: tuple[float, float] = (1.0 - MATCH_FRACTION, 1.0 + MATCH_FRACTION)

    @property
    def inside(self) -> np.ndarray:
        """(n,) True where the ratio is inside its band (undetermined elements: True)."""
        lo, hi = self.band
        return ~self.determined | ((self.ratio >= lo) & (self.ratio <= hi))

    @property
    def nees_inside(self) -> bool:
        lo, hi = self.nees_band
        return self.nees_dof == 0 or lo <= self.nees <= hi

    @property
    def consistent(self) -> bool:
        return bool(np.all(self.inside) and self.nees_inside)


def ratio_band(runs: int, elements: int, alpha: float = ALPHA, match: float = MATCH_FRACTION) -> tuple[float, float]:
    """Band of ``s / σ`` accepted with ``runs`` runs and ``elements`` compared (module
    docstring): the χ² sampling band of a sample σ at the Bonferroni level
    ``alpha / elements``, widened by ``match`` each way."""
    from scipy import stats

    dof = max(runs - 1, 1)
    a = alpha / max(elements, 1)
    lo = math.sqrt(stats.chi2.ppf(0.5 * a, dof) / dof)
    hi = math.sqrt(stats.chi2.ppf(1.0 - 0.5 * a, dof) / dof)
    return (1.0 - match) * lo, (1.0 + match) * hi


def drawn_sigma(pred, draw: Mapping[str, float] | None) -> np.ndarray:
    """(n,) the predicted total σ of ``pred``'s elements for a priori drawn at ``draw``
    (element -> σ of its draw; the others at their a priori σ̄): :func:`prior_as_drawn`.
    An element drawn narrower than its a priori lowers its own share and, through the
    correlations of ``P``, the others' (the cap of
    :func:`~gcs_core.trade.montecarlo.draw_sigmas`; without this the tracker scales of a
    τ = 60 s Monte Carlo read 4–17 % conservative, docs/benchmarks.md)."""
    total = np.asarray(pred.sigma[-1], float) ** 2
    if not draw or pred.P is None or pred.prior is None:
        return np.sqrt(total)
    s0 = np.asarray(pred.prior, float)
    sd = np.array([draw.get(n, s) for n, s in zip(pred.names, s0)], float)
    return prior_as_drawn(total, np.asarray(pred.P, float), s0, sd)


def prior_as_drawn(total: np.ndarray, P: np.ndarray, sigma0: np.ndarray, sigma_d: np.ndarray) -> np.ndarray:
    """(n,) the σ of an estimate whose error variance is ``total`` when its a priori (σ̄
    ``sigma0``) was drawn at ``sigma_d`` instead (0: the a priori at the truth). The a priori
    is an observation with influence ``P P₀⁻¹``: of each variance ``(P P₀⁻¹ P)_ii`` is its
    error's share, which draws at ``σ_d`` make ``(P P₀⁻¹ D P₀⁻¹ P)_ii``, ``D = diag(σ_d²)``."""
    info0 = prior_information(sigma0)
    sd = np.where(np.isfinite(sigma_d), sigma_d, 0.0)
    share = np.einsum("ij,j,ji->i", P, info0, P)
    drawn = np.einsum("ij,j,ji->i", P, info0**2 * sd**2, P)
    return np.sqrt(np.maximum(total - share + drawn, 0.0))


def summarize(pred, records: Sequence[dict], draw: Mapping[str, float] | None = None) -> MonteCarloResult:
    """The verdict of the runs ``records`` against ``pred``, the a priori drawn at ``draw``
    (:func:`drawn_sigma`; None: at every σ̄)."""
    from scipy import stats

    ok = [r for r in records if r.get("status") in CONVERGED]
    if not ok:
        raise InputError("no run converged", key="montecarlo")
    names = tuple(ok[0]["names"])
    E = np.array([r["error"] for r in ok])
    Ps = np.array([r["P"] for r in ok])
    pi = [pred.names.index(n) if n in pred.names else None for n in names]
    # the total σ: the runs draw the consider elements too (module docstring), each
    # element's a priori as it was drawn
    sig_all = drawn_sigma(pred, draw)
    psig = np.array([sig_all[i] if i is not None else np.nan for i in pi])
    und = set(pred.undetermined)
    det = np.array([n not in und and np.isfinite(s) for n, s in zip(names, psig)])
    scat = np.std(E, axis=0, ddof=1) if len(ok) > 1 else np.full(len(names), np.nan)
    units = tuple(pred.units[i] if i is not None else "" for i in pi)
    idx = np.flatnonzero(det)
    nees = float(sum(e[idx] @ np.linalg.solve(P[np.ix_(idx, idx)], e[idx]) for e, P in zip(E, Ps)))
    dof = len(ok) * idx.size
    band = (float(stats.chi2.ppf(0.025, dof)), float(stats.chi2.ppf(0.975, dof))) if dof else (0.0, 0.0)
    return MonteCarloResult(
        len(ok),
        len(records) - len(ok),
        names,
        units,
        psig,
        scat,
        scat / psig,
        np.mean(E, axis=0) / psig,
        np.sqrt(np.mean(np.einsum("kii->ki", Ps), axis=0)),
        det,
        nees,
        band,
        dof,
        ratio_band(len(ok), int(idx.size)),
    )


def summary_lines(res: MonteCarloResult) -> list[str]:
    from gcs_core.trade.report import element_unit, in_unit

    lo, hi = res.band
    out = [
        f"{res.runs} runs fitted"
        + (f", {res.failed} failed" if res.failed else "")
        + f"; predicted σ (noise and consider elements, the a priori as drawn) against the Monte-Carlo "
        "scatter: ratio band "
        f"[{lo:.3f}, {hi:.3f}] = ±{100 * MATCH_FRACTION:g} % widened by the χ² sampling error of "
        f"{res.runs} runs (family-wise α = {ALPHA:g})",
        f"{'element':<16}{'predicted σ':>13}{'MC σ':>11}{'ratio':>8}{'fit σ':>11}{'mean/σ':>8}  unit",
    ]
    for k, n in enumerate(res.names):
        shown, label = element_unit(res.units[k], res.predicted[k])
        p = in_unit(res.predicted[k], res.units[k], shown)
        s = in_unit(res.scatter[k], res.units[k], shown)
        f = in_unit(res.fit_sigma[k], res.units[k], shown)
        flag = "" if res.determined[k] else "  (not determined by the plan)"
        if not res.inside[k]:
            flag = "  OUTSIDE its band"
        out.append(f"{n:<16}{p:>13.4g}{s:>11.4g}{res.ratio[k]:>8.3f}{f:>11.4g}{res.mean_z[k]:>+8.2f}  {label}{flag}")
    nlo, nhi = res.nees_band
    out.append(
        f"NEES over the determined elements: {res.nees:.1f} on {res.nees_dof} dof, 95 % band "
        f"[{nlo:.1f}, {nhi:.1f}] — {'inside' if res.nees_inside else 'OUTSIDE'}"
    )
    out.append(
        "predicted σ "
        + ("match" if res.consistent else "do NOT match")
        + f" the scatter: every determined element within {100 * MATCH_FRACTION:g} % once the sampling "
        "error is allowed for, and the NEES in its band" + ("" if res.consistent else " (see OUTSIDE above)")
    )
    return out
