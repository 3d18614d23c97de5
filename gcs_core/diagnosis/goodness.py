"""Goodness of fit: is what the model leaves in the residuals noise?

A fit that converged says nothing about whether its model describes the data. Under a
correct model with the data-book noise (seed §4.3: ``R`` diagonal, the sensors' σ), the
weighted residual sum of squares is χ²-distributed on the *effective* degrees of freedom::

    χ² = Σ rᵀ R⁻¹ r,      ν = m − p_eff,      p = P(χ²_ν ≥ χ²)

``m`` the measurements used (valid frames × components, edited frames excluded) and
``p_eff`` the effective number of parameters, the trace of the influence (hat) matrix
``∂ŷ/∂y``. For the batch with an a priori (Eq 3-1, 3-2) that is::

    p_eff = tr(P A) = Σ_s tr(P A_s) = n − Σ_i (P P̄⁻¹)_ii            (A = Hᵀ R⁻¹ H)

``P A`` the resolution (averaging-kernel) matrix: an element set by its a priori adds
nothing to ``p_eff``, one set by the data adds 1. ``tr(P A_s)`` is the share of sensor
``s`` (its leverage), so each sensor has its own test on ``m_s − tr(P A_s)``. For the
linear Gaussian model with the truth drawn from the a priori, ``E[χ²] = m − tr(P A)``
exactly (Rodgers 2000, §2.4, §12.1). An estimator with process noise (the gyro's random
walks carried as attitude freedom) has more effective parameters than its static
elements: it passes its own ``p_eff`` (its smoother's ``Σ_k tr(H_k P_k|N H_kᵀ R_k⁻¹)``)
and leverages per sensor, and this module uses them. Without them, a covariance that
gives ``tr(P A) > n`` is not the static posterior of these partials (a smoother's
covariance at ``t_ref``, whose attitude freedom is not in ``A``); the static element count
``n`` is used then, an underestimate of ``p_eff``: the dof are too many, so the verdict
leans to "consistent" by the attitude freedom the smoother has (such an estimator should
declare its own).

Held-out span. The frames held out of a training fit are predicted by it; their
residuals ``r_h`` have covariance ``R_h + H_h P Hᵀ_h`` under a correct model, so::

    χ²_h = r_hᵀ (R_h + H_h P H_hᵀ)⁻¹ r_h  ~  χ²_{m_h}
         = r_hᵀ R_h⁻¹ r_h − g_hᵀ (P⁻¹ + A_h)⁻¹ g_h      (Woodbury; g_h = H_hᵀ R_h⁻¹ r_h)

exact for a static-state fit, and formed from the held-out frames' normal equations
(one streaming pass, an n × n solve; no m_h × m_h matrix). Frame by frame
standardizing would ignore that one parameter error moves every held-out frame alike,
which makes the sum far wider than χ²_{m_h} when ``H P Hᵀ`` is not small against ``R``.

Verdict. The tests of one fit form one family: the whole fit and every sensor, on the
fitted span and on the held-out span. Each is read at ``α / K`` (Bonferroni over the
``K`` tests), so a correct model is called inadequate on at most α of fits (α is the
session's family-wise significance, 0.001 by default: the same level at which discovery
adds an effect). With m of order 10⁴–10⁵ the test is sharp: at α = 0.001 over about ten
tests it sees a sensor whose normalized RMS exceeds 1 by about ``3.7/sqrt(2 m_s)`` (5 %
for 3 000 measurements, 1.5 % for 30 000). A model inadequate by that measure has a signature the
diagnosis can look for; a noise level wrong in the data book reads the same, and the
verdict names the sensor so that the analyst can tell which. Residuals *below* the noise
(lower tail at the same level) are reported too: a data-book σ too large makes every σ
and p-value of the fit pessimistic.

References
----------
Rodgers, C. D., *Inverse Methods for Atmospheric Sounding*, World Scientific 2000, §2.4
(averaging kernel, degrees of freedom for signal), §12.1 (χ² test of the retrieval).
Hastie, Tibshirani & Friedman, *The Elements of Statistical Learning*, 2nd ed., §7.6
(effective number of parameters, trace of the smoother matrix).
Tapley, Schutz & Born, *Statistical Orbit Determination*, Elsevier 2004, §4.16.
"""

from __future__ import annotations

import math
from collections.abc import Mapping, Sequence
from dataclasses import dataclass, field

import numpy as np
from scipy import stats

from gcs_core.estimators.static_algebra import STATIC_SOURCE

__all__ = [
    "ChiSquare",
    "GoodnessOfFit",
    "goodness_of_fit",
    "holdout_tests",
    "FAMILY_ALPHA",
]

#: default family-wise level of the verdict (the session passes its ``significance``)
FAMILY_ALPHA = 1e-3


@dataclass(frozen=True)
class ChiSquare:
    """One χ² test of residuals against the noise.

    Attributes
    ----------
    label : "all sensors" or a sensor name.
    chi2 : Σ rᵀ R⁻¹ r over the measurements tested.
    n : measurements (frames × components) tested.
    dof : effective degrees of freedom, ``n − p_eff`` (may be fractional).
    inflation : ``κ₂``, the variance inflation of the χ² sum by the residuals' correlation
        (1: white; :mod:`gcs_core.noise.correlated`). The tails are read on the
        correlation's effective dof, ``χ²/κ₂ ~ χ²_{dof/κ₂}`` (Satterthwaite 1946).
    """

    label: str
    chi2: float
    n: int
    dof: float
    inflation: float = 1.0

    @property
    def p_value(self) -> float:
        """Upper tail ``P(χ²_ν ≥ χ²/κ₂)``, ``ν = dof/κ₂``: small when the residuals exceed the noise."""
        if not (self.dof > 0 and math.isfinite(self.chi2)):
            return float("nan")
        k = self.inflation
        return float(stats.chi2.sf(self.chi2 / k, self.dof / k))

    @property
    def p_lower(self) -> float:
        """Lower tail ``P(χ²_ν ≤ χ²/κ₂)``: small when the residuals are below the noise."""
        if not (self.dof > 0 and math.isfinite(self.chi2)):
            return float("nan")
        k = self.inflation
        return float(stats.chi2.cdf(self.chi2 / k, self.dof / k))

    @property
    def reduced(self) -> float:
        """``chi2 / dof`` (1 for noise)."""
        return self.chi2 / self.dof if self.dof > 0 else float("nan")

    def as_report(self) -> dict:
        out = {
            "chi2": round(float(self.chi2), 3),
            "n": int(self.n),
            "dof": round(float(self.dof), 2),
            "chi2_per_dof": _r(self.reduced, 5),
            "p_value": _p(self.p_value),
            "p_lower": _p(self.p_lower),
        }
        if self.inflation != 1.0:
            out["chi2_inflation"] = _r(self.inflation, 4)
            out["effective_dof"] = _r(self.dof / self.inflation, 2)
        return out


@dataclass(frozen=True)
class GoodnessOfFit:
    """The χ² tests of one fit and their verdict (module docstring).

    Attributes
    ----------
    fit : all sensors on the fitted span; sensors : sensor -> its own test.
    holdout : all sensors on the held-out span (None without one); holdout_sensors : per sensor.
    alpha : family-wise level; effective_parameters : ``p_eff`` of the fit.
    effective_from : how ``p_eff`` was obtained ("trace of P A" or "the estimator").
    """

    fit: ChiSquare
    sensors: Mapping[str, ChiSquare]
    holdout: ChiSquare | None = None
    holdout_sensors: Mapping[str, ChiSquare] = field(default_factory=dict)
    alpha: float = FAMILY_ALPHA
    effective_parameters: float = 0.0
    effective_from: str = "trace of P A"

    @property
    def tests(self) -> list[tuple[str, ChiSquare]]:
        """Every test of the family, as (span, test), span "fitted" or "held-out"."""
        out = [("fitted", self.fit)] + [("fitted", t) for t in self.sensors.values()]
        if self.holdout is not None:
            out += [("held-out", self.holdout)] + [("held-out", t) for t in self.holdout_sensors.values()]
        return [(s, t) for s, t in out if t.dof > 0]

    @property
    def level(self) -> float:
        """The per-test level ``α / K`` (Bonferroni)."""
        return self.alpha / max(1, len(self.tests))

    def failing(self) -> list[tuple[str, ChiSquare]]:
        """Tests whose residuals exceed the noise at the per-test level, worst first."""
        bad = [(s, t) for s, t in self.tests if t.p_value < self.level]
        return sorted(bad, key=lambda st: (st[1].p_value, -st[1].reduced))

    def below_noise(self) -> list[tuple[str, ChiSquare]]:
        """Tests whose residuals are significantly *below* the noise (σ overstated)."""
        return [(s, t) for s, t in self.tests if t.p_lower < self.level]

    @property
    def adequate(self) -> bool:
        """True when no test says the residuals exceed the noise."""
        return not self.failing()

    def worst(self) -> tuple[str, ChiSquare] | None:
        """The sensor test (fitted or held-out) with the smallest upper-tail p."""
        cands = [(s, t) for s, t in self.tests if t.label != ALL]
        return min(cands, key=lambda st: (st[1].p_value, -st[1].reduced)) if cands else None

    @property
    def verdict(self) -> str:
        """One line: "consistent with noise" or "model inadequate: ...", with its numbers."""
        f = self.fit
        head = f"χ² {f.chi2:.1f} on {f.dof:.1f} dof (per dof {f.reduced:.4f}, p {_fmt_p(f.p_value)})"
        bad = self.failing()
        if not bad:
            low = self.below_noise()
            text = f"consistent with noise: {head}"
            if low:
                text += "; residuals significantly below the noise (too good) in " + "; ".join(
                    f"{t.label} ({s}, χ²/dof {t.reduced:.3f}, p lower {_fmt_p(t.p_lower)}): {too_good_cause(t)}"
                    for s, t in low
                )
            return text
        sensors = [(s, t) for s, t in bad if t.label != ALL]
        s, t = (sensors or bad)[0]
        where = t.label + ("" if s == "fitted" else " on the held-out span")
        return (
            f"model inadequate: residuals exceed the noise, p {_fmt_p(t.p_value)}, worst sensor "
            f"{where} (χ²/dof {t.reduced:.3f} on {t.dof:.0f} dof); whole fit {head}; "
            f"family-wise α = {self.alpha:g} over {len(self.tests)} tests"
        )

    def too_good(self) -> list[dict]:
        """The below-noise tests with their likely cause, for the report."""
        return [
            {"sensor": t.label, "span": s, "chi2_per_dof": _r(t.reduced, 4), "p_lower": _p(t.p_lower),
             "cause": too_good_cause(t)}
            for s, t in self.below_noise()
        ]  # fmt: skip

    def sensor_report(self, name: str) -> dict:
        """A sensor's χ² fields for the ICD §7 ``sensors`` entry: ``chi2``, ``dof``,
        ``p_value`` and, with a held-out span, ``holdout_chi2``, ``holdout_dof``,
        ``holdout_p_value``."""
        out: dict[str, float | int] = {}
        for prefix, tests in (("", self.sensors), ("holdout_", self.holdout_sensors)):
            t = tests.get(name)
            if t is not None:
                rep = t.as_report()
                out |= {f"{prefix}{k}": rep[k] for k in ("chi2", "dof", "p_value")}
        return out

    def as_report(self) -> dict:
        worst = self.worst()
        out = {
            "verdict": self.verdict,
            "adequate": self.adequate,
            "alpha": self.alpha,
            "tests": len(self.tests),
            "per_test_level": self.level,
            "effective_parameters": round(float(self.effective_parameters), 3),
            "effective_parameters_from": self.effective_from,
            **self.fit.as_report(),
            "worst_sensor": None
            if worst is None
            else {"sensor": worst[1].label, "span": worst[0], "p_value": _p(worst[1].p_value)},
            "sensors": {k: v.as_report() for k, v in self.sensors.items()},
            "too_good": self.too_good(),
        }
        if self.holdout is not None:
            out["holdout"] = {
                **self.holdout.as_report(),
                "sensors": {k: v.as_report() for k, v in self.holdout_sensors.items()},
            }
        return out


ALL = "all sensors"


def too_good_cause(t: ChiSquare) -> str:
    """The likely cause of residuals significantly below the noise: a correlated sensor
    (``κ₂ > 1``) whose slow error the attitude's freedom absorbed, else a stated σ too large."""
    if t.inflation > 1.0:
        return (
            "correlated noise absorbed by the attitude (the attitude's freedom follows the sensor's slow "
            "error; its σ and the elements it carries are less certain than the fit says)"
        )
    return "the stated σ is likely too large (every σ and p-value of the fit is then pessimistic)"


def _r(v: float, nd: int):
    return round(float(v), nd) if math.isfinite(v) else None


def _p(v: float):
    return float(f"{v:.4g}") if math.isfinite(v) else None


def _fmt_p(p: float) -> str:
    """``= 0.03`` or ``< 1e-300`` (after "p")."""
    return "= nan" if not math.isfinite(p) else (f"= {p:.2g}" if p >= 1e-300 else "< 1e-300")


# ------------------------------------------------------------------------- held-out span
def holdout_tests(problem, train, masks: Mapping[str, np.ndarray]) -> dict[str, ChiSquare]:
    """χ² of the held-out frames under the training fit ``train`` (module docstring),
    per sensor and for all sensors together (key :data:`ALL`); {} without held-out frames.

    ``masks``: sensor -> (N,) True where the frame was held out of ``train``. Every valid
    held-out frame is tested (none was edited: the training fit never saw them). The sums
    are the fit's own (:meth:`~gcs_core.estimators.results.FitResult.holdout_chi2`).
    """
    sel = {k: np.asarray(v, bool) for k, v in masks.items() if np.any(v)}
    if not sel:
        return {}
    sums = train.holdout_chi2(problem, sel)
    if sums is None:
        return {}
    out = {name: ChiSquare(name, chi2, m, float(m)) for name, (chi2, m) in sums.per_sensor.items()}
    out[ALL] = ChiSquare(ALL, sums.total[0], sums.total[1], float(sums.total[1]))
    return out


# ------------------------------------------------------------------------- the verdict
def goodness_of_fit(
    problem,
    result,
    *,
    holdout: Mapping[str, ChiSquare] | None = None,
    alpha: float = FAMILY_ALPHA,
    effective_parameters: float | None = None,
    leverage: Mapping[str, float] | None = None,
    sensors: Sequence[str] | None = None,
    inflation: Mapping[str, float] | None = None,
) -> GoodnessOfFit:
    """The χ² tests of a fit and their verdict (module docstring).

    ``result`` is any estimator's :class:`~gcs_core.estimators.results.FitResult`. The effective
    parameters come from the arguments, else from the result's own influence
    (:meth:`~gcs_core.estimators.results.FitResult.influence`: ``tr(P A_s)`` per sensor for a
    static fit, the influence matrix's trace with the knots for a whole-span fit). Given
    only a total, it is shared among the sensors in proportion to ``tr(P A_s)``. ``holdout`` is
    :func:`holdout_tests` of the training fit. ``inflation``: sensor -> ``κ₂`` of its
    correlated noise (absent: white); the whole fit's is the dof-weighted mean.
    """
    p_eff = effective_parameters
    lev = leverage
    src = "the estimator" if (p_eff is not None or lev is not None) else STATIC_SOURCE
    if lev is None:
        influence = result.influence(problem)
        lev = influence.per_sensor
        if not influence.static:
            src = influence.source
        else:
            n = len(result.solve_for)
            if p_eff is None and sum(lev.values()) > n * (1 + 1e-6):
                # tr(P A) ≤ n for a static fit; above n, P is not the static posterior of these
                # partials (a smoother's covariance at t_ref under process noise, whose freedom
                # is not in A): count the static elements only, an underestimate of p_eff
                p_eff = float(n)
                src = "static elements only (the estimator's process noise not counted)"
            if p_eff is not None:
                tot = sum(lev.values())
                lev = {k: (v / tot * p_eff if tot > 0 else p_eff / max(1, len(lev))) for k, v in lev.items()}
    if p_eff is None:
        p_eff = float(sum(lev.values()))
    per = {}
    for name, r in result.residuals.items():
        if sensors is not None and name not in sensors:
            continue
        m = int(r.n) * len(r.components)
        per[name] = ChiSquare(name, r.chi2, m, m - float(lev.get(name, 0.0)), float((inflation or {}).get(name, 1.0)))
    m_all = sum(t.n for t in per.values())
    chi_all = float(sum(t.chi2 for t in per.values()))
    dof_all = sum(max(t.dof, 0.0) for t in per.values())
    k_all = sum(max(t.dof, 0.0) * t.inflation for t in per.values()) / dof_all if dof_all > 0 else 1.0
    fit = ChiSquare(ALL, chi_all, m_all, m_all - float(p_eff), k_all if inflation else 1.0)
    ho = dict(holdout or {})
    ho_all = ho.pop(ALL, None)
    return GoodnessOfFit(fit, per, ho_all, ho, alpha, float(p_eff), src)
