"""Weighting a sensor by the noise it really shows: the long-run noise factor in the fit.

One mechanism, two measures of the same long-run variance ratio. The session weights a
sensor by ``σ × k`` (:class:`NoiseFactor`, its ``_reweight`` loop, :func:`stated_residuals`)
whichever way ``k`` was found: ``noise_weighting = "correlated"`` (the default) takes
``k = √κ`` of the sensor's first-order Gauss–Markov correlation, declared in mission.toml
or measured where significant (:mod:`gcs_core.noise.correlated`); ``"long_run"``
takes the model-free batch-means ratio ``s`` below, over a configured window.

A fit weights each sensor as white noise of its stated σ (seed §4.3: ``R`` diagonal). When
a sensor's errors are correlated over a time ``τ`` longer than its sample interval (an
optical reference interpolated between its camera frames, a magnetometer that repeats
samples), ``n`` consecutive samples carry the information of fewer independent ones and
the white-noise weight counts it too often: the σ come out optimistic, and a gyro-carried
attitude (whose knots may move within ``τ``) follows the sensor's error instead of
averaging it. ``[filter] noise_weighting = "long_run"`` weights each such sensor by its
*effective* white noise on time scales longer than ``τ``::

    σ_eff = σ_stated · k,    k = max(1, s)  where s is significant,
    s² = Σ_b ‖Σ_{j ∈ b} r_j / σ_j‖² / Σ_j ‖r_j / σ_j‖²          (windows b of L seconds)

``s`` is the batch-means ratio of the long-run to the short-run variance of the sensor's
own post-fit residuals (``1 + 2 Σ_j ρ_j`` for a stationary error; Conway, Operations
Research 11(1), 1963; :func:`gcs_core.noise.correlation.noise_scale`). Each draw held
over ``n`` samples gives ``s = √n``; white residuals ``s ≈ 1``. The sequence, per fit:

1. fit with the current weights (at the first fit: the stated σ);
2. measure ``s`` of every measurement sensor over windows of ``L`` = ``noise_window``
   seconds (at least :data:`MIN_SAMPLES` sample intervals, and
   :data:`~gcs_core.noise.correlation.MIN_BLOCKS` windows in the span, else the sensor
   keeps its stated σ and says why);
3. refit with ``σ · k``; ``noise_passes`` = 2 measures again on the refit (its knots no
   longer follow the sensor's error, which the first fit's residuals hid) and refits.

``s`` is a ratio, so it does not depend on the σ the residuals were weighted with: each pass
measures the factor against the stated σ afresh.

Why ``k ≥ 1`` only, and only where significant. On white residuals ``s`` scatters about 1
by ``≈ 1/sqrt(2 n_b)`` (``n_b`` windows) and sits slightly below it (the fit's parameters
absorb a share of each window's sum); a factor below 1 would claim the sensor is better
than its per-sample noise, which no correlation can make it. So ``k = s`` only where
``s`` exceeds 1 by more than :data:`SIGNIFICANCE` times its sampling error, else
``k = 1``: a white-noise sensor keeps its stated σ exactly, and the fit is the stated one.

What ``s`` cannot see. It is measured on the fit's own residuals: what the fit's freedom
(the knots, the time offsets) absorbed is not in them, so ``s`` is a lower bound, and a
systematic model error that is slow against ``L`` raises it like correlated noise does
(an effect missing from the model is weighted down, not found: run discovery with the
stated weighting first, or with ``L`` shorter than the effects' time scales).

Normalized RMS and the verdicts. The residuals a weighted fit reports are normalized by the
*stated* σ (the per-sample noise the goodness-of-fit tests are about: "consistent with the
noise" keeps its meaning, and a correlated error still shows as inadequacy there), while the
estimates, their σ and the discovery's score tests use ``σ · k``.
:func:`stated_residuals` converts a weighted fit's residuals back.
"""

from __future__ import annotations

import math
from collections.abc import Mapping, Sequence
from dataclasses import dataclass, replace

import numpy as np

from gcs_core.noise.correlation import MIN_BLOCKS, noise_scale

#: a window spans at least this many of the sensor's sample intervals (a window of one
#: sample measures nothing)
MIN_SAMPLES = 10
#: a factor is applied only when ``s − 1`` exceeds this many of its sampling errors
SIGNIFICANCE = 3.0


@dataclass(frozen=True)
class NoiseFactor:
    """One sensor's long-run noise factor.

    Attributes
    ----------
    sensor : its name; window_s : the window used [s]; n_windows : windows with used frames.
    measured : ``s`` (NaN when not measured); sampling_error : its 1σ scatter on white noise,
        ``s / sqrt(2 n_b)``.
    factor : ``k`` the stated σ is multiplied by (1 unless ``s`` is significantly above 1).
    note : why the factor is 1 when it is (empty otherwise).
    """

    sensor: str
    window_s: float
    n_windows: int
    measured: float
    sampling_error: float
    factor: float
    note: str = ""

    def as_report(self) -> dict:
        out: dict = {
            "factor": round(self.factor, 4),
            "measured": round(self.measured, 4) if math.isfinite(self.measured) else None,
            "sampling_error": round(self.sampling_error, 4) if math.isfinite(self.sampling_error) else None,
            "window_s": self.window_s,
            "n_windows": self.n_windows,
        }
        if self.note:
            out["note"] = self.note
        return out


@dataclass(frozen=True)
class NoiseWeighting:
    """What a ``long_run`` fit weighted its sensors with (module docstring).

    Attributes
    ----------
    window_s : the configured window [s] (NaN for ``correlated``); passes : refits run with
        new factors (0: the measured factors agreed with the weights the fit had).
    factors : sensor -> :class:`NoiseFactor` of the last pass (the weights of the fit).
    mode : ``long_run`` (batch-means ratio) or ``correlated`` (``√κ`` of the sensor's
        Gauss–Markov correlation, :mod:`gcs_core.noise.correlated`): one
        mechanism, two measures of the same long-run variance ratio.
    """

    window_s: float
    passes: int
    factors: Mapping[str, NoiseFactor]
    mode: str = "long_run"

    def as_report(self) -> dict:
        """The ``noise_weighting`` field of the ICD §7 report (docs/icd_extensions.md)."""
        return {
            "mode": self.mode,
            "window_s": self.window_s if math.isfinite(self.window_s) else None,
            "passes": self.passes,
            "normalized_against": "stated sigma",
            "weights": "stated sigma x factor",
            "sensors": {n: f.as_report() for n, f in self.factors.items()},
        }

    def summary(self) -> str:
        """One line for a fit summary."""
        parts = []
        for n, f in self.factors.items():
            if math.isfinite(f.measured) and not math.isfinite(f.window_s):  # correlated: √κ
                parts.append(f"{n} × {f.factor:.2f} (√κ {f.measured:.2f} ± {f.sampling_error:.2g})")
            elif math.isfinite(f.measured):
                parts.append(f"{n} × {f.factor:.2f} (s {f.measured:.2f} ± {f.sampling_error:.2f}, {f.window_s:g} s)")
            else:
                parts.append(f"{n} × 1 ({f.note})")
        return (
            f"noise weighting {self.mode} ({self.passes} refit{'' if self.passes == 1 else 's'}): σ × "
            + "; ".join(parts)
            + "; normalized RMS and χ² tests against the stated σ"
        )


def measure(result, sensors: Sequence[str], window_s: float, only: Sequence[str] = ()) -> dict[str, NoiseFactor]:
    """The long-run factor of each measurement sensor named in ``sensors`` from ``result``'s
    residuals, over windows of ``window_s`` (at least :data:`MIN_SAMPLES` sample intervals);
    ``only``: the sensors to weight (empty: all)."""
    out = {}
    for name in sensors:
        if name not in result.residuals or (only and name not in only):
            continue
        res = result.residuals[name]
        t = np.asarray(res.t, float)
        dt = float(np.median(np.diff(t))) if t.size > 1 else math.inf
        window = float(max(float(window_s), MIN_SAMPLES * dt))
        used = np.asarray(res.used, bool)
        n_b = int(np.unique(np.floor((t[used] - t[0]) / window)).size) if used.any() else 0
        if n_b < MIN_BLOCKS:
            note = f"{n_b} windows of {window:g} s; {MIN_BLOCKS} needed"
            out[name] = NoiseFactor(name, window, n_b, math.nan, math.nan, 1.0, note)
            continue
        s = noise_scale(result, name, block_s=window)
        err = s / math.sqrt(2.0 * n_b)
        k = s if s - 1.0 > SIGNIFICANCE * err else 1.0
        note = "" if k > 1.0 else "not significantly above 1"
        out[name] = NoiseFactor(name, window, n_b, s, err, float(k), note)
    return out


def weighted_sensors(sensors: Sequence, scale: Mapping[str, float]) -> list:
    """The prepared sensors with each σ multiplied by its factor (others unchanged)."""
    return [replace(sd, sigma=sd.sigma * scale[sd.name]) if sd.name in scale else sd for sd in sensors]


def stated_residuals(result, scale: Mapping[str, float]):
    """A weighted fit's result with its residuals normalized by the stated σ (``σ / k``):
    what the normalized RMS, the χ² tests and the reports read."""
    if not scale:
        return result
    res = {
        n: (replace(r, sigma=r.sigma / scale[n], normalized_=_times(r.normalized_, scale[n])) if n in scale else r)
        for n, r in result.residuals.items()
    }
    return replace(result, residuals=res)


def _times(a, k: float):
    """``a × k``, None kept (a residual normalized by its marginal σ, readout.py, or formed when read)."""
    return None if a is None else a * k


def same_factors(new: Mapping[str, NoiseFactor], old: Mapping[str, NoiseFactor]) -> bool:
    """Whether newly measured factors agree with the ones a fit was weighted with (missing:
    1) within their sampling errors: then no refit is needed."""
    for n in set(new) | set(old):
        a, b = new.get(n), old.get(n)
        fa, fb = (a.factor if a else 1.0), (b.factor if b else 1.0)
        errs = [f.sampling_error for f in (a, b) if f is not None and math.isfinite(f.sampling_error)]
        if abs(fa - fb) > max(errs, default=0.0):
            return False
    return True
