"""Each sensor's noise correlation: measured from its residuals, or declared in mission.toml.

The fit weights every sensor as white noise of its stated σ (seed §4.3: ``R`` diagonal).
Real sensor errors are correlated in time (a star tracker's low-frequency errors, a
magnetometer's wander). The model taken here is the first-order Gauss–Markov process
(Gelb, *Applied Optimal Estimation*, 1974, §3.8): a share ``a`` of the variance
(``a = σ_c² / σ²``, ``σ_c`` the correlated part, 1 when all of it is) with autocorrelation
``exp(−|Δt|/τ)``, the rest white. At the sample interval ``Δt`` the lag-1 autocorrelation
of the normalized noise is ``ρ₁ = a φ``, ``φ = exp(−Δt/τ)``, and what it does to the
statistics of a fit is two numbers (sums over a stationary sequence; Priestley, *Spectral
Analysis and Time Series*, 1981, §5.3; Bayley & Hammersley, JRSS Suppl. 8, 1946):

    κ  = 1 + 2a φ/(1 − φ)        long-run / per-sample variance of Σ r_k / σ (AR(1): (1+φ)/(1−φ))
    κ₂ = 1 + 2a² φ²/(1 − φ²)     Var(Σ r_k²/σ²) / (2 n): the χ² sum's variance inflation

``κ`` is the variance-inflation factor of everything the data determine on time scales
longer than ``τ`` (biases, alignments, the score of a slow candidate such as a time offset
on a slowly turning spacecraft): weighting the sensor with ``σ √κ`` (the fit's
:mod:`~gcs_core.noise.weighting` mechanism, ``noise_weighting = "correlated"``) makes
its elements' σ and its candidates' Δχ² honest on those scales. ``κ₂`` turns the χ² test of
the sensor's residuals into one on its *effective* dof (Satterthwaite 1946:
``χ²/κ₂ ~ χ²_{ν/κ₂}``), both tails: residuals below their noise on those dof are as much a
misfit as residuals above it (:mod:`gcs_core.diagnosis.goodness`).

Measured (no declaration): the pooled lag-1 autocorrelation of the sensor's used residuals
normalized by their σ, over consecutive frames one sample interval apart (gaps break the
pairs), with ``a = 1``::

    ρ̂₁ = Σ x_k·x_{k−1} / sqrt(Σ x_k² Σ x_{k−1}²),    se(ρ̂₁) = sqrt((1 − ρ̂₁²)/n_pairs)

(the AR(1) estimator's large-sample error; Box & Jenkins, *Time Series Analysis*, §6.3),
``τ̂ = −Δt/ln ρ̂₁``, ``κ̂``, ``κ̂₂`` and their errors by the delta method. It is *significant*
when ``ρ̂₁ > SIGNIFICANCE·se`` and ``ρ̂₁ > RHO_MIN`` and neighbours' differences are
smaller than the stated noise's: ``d = mean((x_k − x_{k−1})²)/2`` (against the stated σ)
is ``1 − φ`` for Gauss–Markov noise at its stated σ and ``≈ 1`` for white noise plus a slow
model error, which raises ``ρ̂₁`` but not the differences; so ``1 − d`` must exceed
``max(RHO_MIN, SIGNIFICANCE·sqrt(2/n))`` too. A sensor whose correlation is not
significant is treated as white and nothing about it changes (a missing effect is left to
discovery, which the stated weights serve best). Residuals are the fit's own:
what the fit's freedom absorbed (the whole-span knots soak up a slow tracker error) is not
in them, so ``ρ̂₁`` is a lower bound at the first fit; the weighting measures again on its
refit. A slow model error raises ``ρ̂₁`` like correlated noise does, but only by its share
of the residual variance: an effect removing Δχ² = D from m measurements gives
``κ ≈ 1 + 2D/m``, so its score after weighting is still ``≈ min(D, m/2)``, found.

The batch-means ratio over several windows (:func:`~gcs_core.noise.correlation.noise_scale`,
``s(L)² → κ`` for ``L ≫ τ``) is reported beside it as a model-free check of the AR(1) form.

Declared (``noise_correlation_s`` = τ, optionally ``noise_correlated`` = σ_c, in a sensor's
table of mission.toml; docs/icd_extensions.md): ``φ = exp(−Δt/τ)`` at the sensor's median
sample interval and ``a = σ_c²/σ²``; used as is, and the measurement is reported beside it.
"""

from __future__ import annotations

import math
import textwrap
from collections.abc import Mapping, Sequence
from dataclasses import dataclass, field, replace

import numpy as np

from gcs_core.noise import weighting
from gcs_core.noise.correlation import noise_scale
from gcs_core.noise.weighting import MIN_SAMPLES, NoiseFactor

#: a measured lag-1 autocorrelation is significant above this many of its standard errors ...
SIGNIFICANCE = 4.0
#: ... and above this value (κ ≈ 1.1: below it the weights would change by under 5 %)
RHO_MIN = 0.05
#: pairs needed to measure at all
MIN_PAIRS = 50
#: windows of the batch-means check, in sample intervals
CHECK_WINDOWS = (10, 30, 100)
#: a window of the batch-means check needs this many windows in the span
CHECK_MIN_WINDOWS = 20


@dataclass(frozen=True)
class Declared:
    """A sensor's noise correlation as mission.toml declares it: τ [s] and the share ``a``
    of the stated variance that is correlated."""

    tau_s: float
    share: float = 1.0


@dataclass(frozen=True)
class SensorCorrelation:
    """One sensor's noise correlation (module docstring).

    Attributes
    ----------
    sensor : name; source : "measured" or "declared"; dt_s : median sample interval [s].
    n_pairs : residual pairs one interval apart (× components); rho : measured ``ρ̂₁``;
        rho_sigma : its standard error.
    tau_s, tau_sigma : correlation time [s] and its error (NaN when ``ρ ≤ 0``).
    inflation, inflation_sigma : ``κ`` and its error; chi2_inflation : ``κ₂``.
    significant : measured and significant, or declared: the fit and its tests use it.
    batch_means : window [s] -> measured ``s(L)`` (the long-run check).
    share : the correlated share ``a`` of the variance (1 when measured).
    """

    sensor: str
    source: str
    dt_s: float
    n_pairs: int
    rho: float
    rho_sigma: float
    tau_s: float
    tau_sigma: float
    inflation: float
    inflation_sigma: float
    chi2_inflation: float
    significant: bool
    batch_means: Mapping[float, float] = field(default_factory=dict)
    note: str = ""
    share: float = 1.0

    @property
    def applied_inflation(self) -> float:
        """``κ`` the fit and its tests use: 1 unless significant or declared."""
        return self.inflation if self.significant else 1.0

    @property
    def applied_chi2_inflation(self) -> float:
        return self.chi2_inflation if self.significant else 1.0

    def factor(self, window_s: float = math.nan) -> NoiseFactor:
        """The weighting's factor ``√κ`` (:class:`~gcs_core.noise.weighting.NoiseFactor`)."""
        k = math.sqrt(self.inflation) if math.isfinite(self.inflation) else math.nan
        err = self.inflation_sigma / (2.0 * k) if k and math.isfinite(k) else math.nan
        note = "" if self.significant else (self.note or "correlation not significant")
        return NoiseFactor(self.sensor, window_s, self.n_pairs, k, err, math.sqrt(self.applied_inflation), note)

    def as_report(self) -> dict:
        def num(v: float, nd: int = 4):
            return round(float(v), nd) if math.isfinite(v) else None

        out = {
            "source": self.source,
            "significant": self.significant,
            "sample_interval_s": num(self.dt_s, 6),
            "pairs": self.n_pairs,
            "lag1_autocorrelation": num(self.rho),
            "lag1_sigma": num(self.rho_sigma),
            "correlation_time_s": num(self.tau_s, 3),
            "correlation_time_sigma_s": num(self.tau_sigma, 3),
            "variance_inflation": num(self.inflation),
            "variance_inflation_sigma": num(self.inflation_sigma),
            "chi2_inflation": num(self.chi2_inflation),
            "applied_inflation": num(self.applied_inflation),
            "batch_means": {f"{w:g}": num(s) for w, s in self.batch_means.items()},
        }
        if self.note:
            out["note"] = self.note
        return out

    def line(self, applied: bool = True) -> str:
        """One line for the CLI and the TUI (``applied``: the fit carries the correlation)."""
        if not math.isfinite(self.rho):
            return f"{self.sensor}: not measured ({self.note})"
        tau = f"τ {self.tau_s:.3g} ± {self.tau_sigma:.2g} s" if math.isfinite(self.tau_s) else "τ –"
        if self.source == "declared":
            tau = f"τ {self.tau_s:.3g} s and κ {self.inflation:.3g} as declared; residuals' ρ₁ {self.rho:.3f}"
            return f"{self.sensor}: {tau} ± {self.rho_sigma:.3f} at {self.dt_s:.3g} s; " + (
                f"σ × {math.sqrt(self.inflation):.2f} in the fit" if applied else "not carried"
            )
        if not self.significant:
            use = "white (not significant)"
        elif applied:
            use = f"σ × {math.sqrt(self.inflation):.2f} in the fit"
        else:
            use = "significant; not carried (noise_weighting is not 'correlated')"
        return (
            f"{self.sensor}: {self.source} ρ₁ {self.rho:.3f} ± {self.rho_sigma:.3f} at {self.dt_s:.3g} s, "
            f"{tau}, κ {self.inflation:.3g} ± {self.inflation_sigma:.2g}; {use}"
        )


def inflations(phi: float, share: float = 1.0) -> tuple[float, float]:
    """``(κ, κ₂)`` of a Gauss–Markov share ``share`` with lag-1 coefficient ``phi`` (module docstring)."""
    phi = min(max(phi, 0.0), 1.0 - 1e-12)
    return 1.0 + 2.0 * share * phi / (1.0 - phi), 1.0 + 2.0 * share**2 * phi**2 / (1.0 - phi**2)


def _pairs(res) -> tuple[float, np.ndarray, np.ndarray]:
    """Median used interval [s] and the normalized residual pairs ``(x_{k−1}, x_k)`` one
    interval apart (flattened over components)."""
    t = np.asarray(res.t, float)
    used = np.asarray(res.used, bool)
    tu = t[used]
    if tu.size < 3:
        return math.nan, np.zeros(0), np.zeros(0)
    dt = float(np.median(np.diff(tu)))
    x = np.asarray(res.residual, float)[used] / np.broadcast_to(np.asarray(res.sigma, float), res.residual.shape)[used]
    gap = np.diff(tu)
    ok = (gap > 0.5 * dt) & (gap < 1.5 * dt) & np.all(np.isfinite(x[1:]), axis=1) & np.all(np.isfinite(x[:-1]), axis=1)
    return dt, x[:-1][ok].reshape(-1), x[1:][ok].reshape(-1)


def _batch_means(result, name: str, dt: float) -> dict[float, float]:
    """Window [s] -> batch-means ratio ``s(L)`` for the :data:`CHECK_WINDOWS` the span holds."""
    res = result.residuals[name]
    t = np.asarray(res.t, float)[np.asarray(res.used, bool)]
    out = {}
    for n in CHECK_WINDOWS:
        w = float(max(n, MIN_SAMPLES) * dt)
        if t.size < 2 or (t[-1] - t[0]) / w < CHECK_MIN_WINDOWS:
            continue
        out[w] = noise_scale(result, name, block_s=w)
    return out


def measure_sensor(result, name: str, declared: Declared | None = None, weight: float = 1.0) -> SensorCorrelation:
    """The noise correlation of one sensor's residuals in ``result`` (module docstring);
    ``weight``: the factor its σ in ``result`` carries over the stated σ."""
    res = result.residuals[name]
    dt, a, b = _pairs(res)
    n = int(a.size)
    smooth = 1.0 - float(np.mean((b - a) ** 2)) * weight**2 / 2.0 if n else 0.0  # 1 − d, stated σ
    if n < MIN_PAIRS or not math.isfinite(dt):
        rho = se = math.nan
        note = f"{n} residual pairs one sample interval apart; {MIN_PAIRS} needed"
    else:
        den = math.sqrt(float(np.sum(a * a)) * float(np.sum(b * b)))
        rho = float(np.sum(a * b)) / den if den > 0 else 0.0
        se = math.sqrt(max(1.0 - rho * rho, 1e-12) / n)
        note = ""
    bm = _batch_means(result, name, dt) if math.isfinite(dt) else {}
    if declared is not None:
        phi = math.exp(-dt / declared.tau_s) if math.isfinite(dt) else 0.0
        k, k2 = inflations(phi, declared.share)
        return SensorCorrelation(
            name, "declared", dt, n, rho, se, declared.tau_s, 0.0, k, 0.0, k2, True, bm,
            "declared in mission.toml" + (f"; measured ρ₁ {rho:.3f} ± {se:.3f}" if math.isfinite(rho) else ""),
            declared.share,
        )  # fmt: skip
    if not math.isfinite(rho):
        return SensorCorrelation(
            name, "measured", dt, n, rho, se, math.nan, math.nan, 1.0, math.nan, 1.0, False, bm, note
        )
    # correlated noise also makes neighbours' differences smaller than the stated noise's;
    # a slow model error does not (module docstring)
    sig = rho > SIGNIFICANCE * se and rho > RHO_MIN and smooth > max(RHO_MIN, SIGNIFICANCE * math.sqrt(2.0 / n))
    if rho > SIGNIFICANCE * se and rho > RHO_MIN and not sig:
        note = f"neighbours' differences at the stated noise (1 − d = {smooth:.3f}): a slow residual, not noise"
    k, k2 = inflations(rho)
    if 0.0 < rho < 1.0:
        tau = -dt / math.log(rho)
        tau_se = dt / (rho * math.log(rho) ** 2) * se
    else:
        tau, tau_se = math.nan, math.nan
    k_se = 2.0 / (1.0 - min(max(rho, 0.0), 1.0 - 1e-12)) ** 2 * se
    return SensorCorrelation(name, "measured", dt, n, rho, se, tau, tau_se, k, k_se, k2, bool(sig), bm, note)


def measure(
    result,
    sensors: Sequence[str],
    declared: Mapping[str, Declared] | None = None,
    weights: Mapping[str, float] | None = None,
) -> dict[str, SensorCorrelation]:
    """:func:`measure_sensor` for every named sensor with residuals (``weights``: sensor ->
    the factor its σ in ``result`` carries over the stated σ)."""
    declared, weights = declared or {}, weights or {}
    return {
        n: measure_sensor(result, n, declared.get(n), weights.get(n, 1.0)) for n in sensors if n in result.residuals
    }


def declared_correlation(spec) -> dict[str, Declared]:
    """Sensor -> :class:`Declared` from a mission spec's data-book keys ``noise_correlation_s``
    and ``noise_correlated`` (docs/icd_extensions.md); sensors without them are absent."""
    out = {}
    for s in spec.sensors:
        tau = s.book.get("noise_correlation_s")
        if tau is None or s.noise is None:
            continue
        sig_c = s.book.get("noise_correlated")
        share = 1.0 if sig_c is None else min(1.0, (float(sig_c) / float(s.noise)) ** 2)
        out[s.name] = Declared(float(tau), share)
    return out


def chi2_inflations(corr: Mapping[str, SensorCorrelation] | None) -> dict[str, float]:
    """Sensor -> ``κ₂`` the χ² tests use (only sensors whose correlation is applied)."""
    return {n: c.chi2_inflation for n, c in (corr or {}).items() if c.significant and c.chi2_inflation > 1.0}


def report(corr: Mapping[str, SensorCorrelation], applied: bool = True) -> dict:
    """The ICD §7 report's ``noise_correlation`` field (docs/icd_extensions.md); ``applied``:
    the fit carries it (``noise_weighting = "correlated"``)."""
    return {
        "model": "first-order Gauss-Markov (AR(1) at the sample interval)",
        "carried_by_the_fit": applied,
        "significance": {"sigmas": SIGNIFICANCE, "rho_min": RHO_MIN},
        "sensors": {n: c.as_report() for n, c in corr.items()},
    }


def inflated_tests(tests: Mapping, infl: Mapping[str, float]) -> dict:
    """χ² tests (label -> :class:`~gcs_core.diagnosis.goodness.ChiSquare`, "all sensors"
    among them) read on the correlated sensors' effective dof: each sensor's ``κ₂``, the
    whole's the dof-weighted mean."""
    if not infl:
        return dict(tests)
    out = {k: replace(t, inflation=float(infl.get(k, 1.0))) for k, t in tests.items()}
    parts = [t for k, t in out.items() if k in infl or k not in ("all sensors",)]
    parts = [t for t in parts if t.label != "all sensors" and t.dof > 0]
    dof = sum(t.dof for t in parts)
    if "all sensors" in out and dof > 0:
        out["all sensors"] = replace(out["all sensors"], inflation=sum(t.dof * t.inflation for t in parts) / dof)
    return out


def lines(corr: Mapping[str, SensorCorrelation], applied: bool = True) -> list[str]:
    """The CLI's and the TUI's lines: one per sensor whose correlation is significant or
    declared, one naming the sensors found white. ``applied``: the fit carries it."""
    if not corr:
        return []
    out = ["noise correlation (first-order Gauss–Markov; ρ₁ lag-1 autocorrelation, κ variance inflation):"]
    out += ["  " + c.line(applied) for c in corr.values() if c.significant or not math.isfinite(c.rho)]
    white = [
        f"{c.sensor} (ρ₁ {c.rho:+.3f} ± {c.rho_sigma:.3f})"
        for c in corr.values()
        if not c.significant and math.isfinite(c.rho)
    ]
    if white:
        out += textwrap.wrap(
            "white within the test: " + ", ".join(white), 100, initial_indent="  ", subsequent_indent="    "
        )
    return out


def factors(
    result, sensors: Sequence[str], fl, declared: Mapping[str, Declared], scale: Mapping[str, float]
) -> tuple[dict[str, NoiseFactor], dict[str, SensorCorrelation]]:
    """The weighting's factors by ``fl.noise_weighting`` (``fl`` the ``[filter]`` table):
    ``correlated``, ``√κ`` of each sensor's correlation (returned too); ``long_run``, the
    batch-means ratio (:func:`gcs_core.noise.weighting.measure`; no correlation).
    ``scale``: the factors ``result`` was weighted with."""
    if fl.noise_weighting == "correlated":
        corr = measure(result, sensors, declared, scale)
        return {n: c.factor() for n, c in corr.items()}, corr
    return weighting.measure(result, sensors, fl.noise_window, fl.noise_sensors), {}
