"""The correlation-robust σ of a finished fit, as the headless runs report it.

:func:`gcs_core.noise.correlation.sigma_scale` gives each solve-for element the
batch-means sandwich scale ``s_i`` (``Cov = A⁻¹ B A⁻¹``; Newey & West 1987, Conway 1963;
read that module's docstring: the scale is conditional on the attitude, and below 1 it is
the method's blind spot, so a σ is never scaled down). This module runs it once after the
final fit of ``gcs batch`` and ``gcs discover`` (the window: given, or chosen by
:func:`auto_window`), skips it quietly (one log line) when it cannot be estimated, and
says which elements the residuals' correlation makes
clearly less certain than the fit's σ claim:

    flagged ⇔  s_i > FLAG_SCALE  and  s_i > 1 + FLAG_SIGMAS / sqrt(2 n_b)

(``n_b`` windows; ``1/sqrt(2 n_b)`` is the sampling error of ``s`` on white residuals).
The two conditions keep white data silent: a scale of 1.3 on a correct model is within
what the σ of a σ allows on a few dozen windows, and below :data:`FLAG_SCALE` the
correction does not change how an analyst reads a σ.

The fit is weighted by the problem's σ (with ``[filter] noise_weighting = "long_run"`` the
stated σ times each sensor's factor); the session's result carries residuals against the
stated σ, so the residuals are put back on the fit's weights before the sandwich: the
scale is then what remains beyond the weighting the fit already used.
"""

from __future__ import annotations

import logging
import math
from collections.abc import Mapping
from typing import Any

import numpy as np

from gcs_core.errors import InputError
from gcs_core.noise.correlation import BLOCK_S, MIN_BLOCKS, SigmaScale, sigma_scale
from gcs_core.noise.weighting import MIN_SAMPLES, stated_residuals

log = logging.getLogger(__name__)

#: default window of the headless runs: None = :func:`auto_window` (a number [s]: that
#: window; 0 = off)
SIGMA_WINDOW: float | None = None
#: a scale is reported beside the σ only above this ...
FLAG_SCALE = 1.5
#: ... and above 1 by this many of its sampling errors 1/sqrt(2 n_b)
FLAG_SIGMAS = 3.0


def auto_window(result) -> float | None:
    """The default window [s]: :data:`~gcs_core.noise.correlation.BLOCK_S` (several
    times the hand motions' time scale), lengthened to hold :data:`~gcs_core.noise.weighting.MIN_SAMPLES`
    samples of the sparsest sensor (a window of one sample sees no correlation, only
    residuals above the noise), shortened to leave ``MIN_BLOCKS + 1`` windows in a short
    span (correlation longer than the window is then not seen: logged); None when the
    span cannot hold that many windows of that many samples."""
    lo, hi, dt = np.inf, -np.inf, 0.0
    for r in result.residuals.values():
        t = np.asarray(r.t, float)[np.asarray(r.used, bool)]
        if t.size < 2:
            continue
        lo, hi = min(lo, t[0]), max(hi, t[-1])
        dt = max(dt, float(np.median(np.diff(t))))
    if not dt:
        return None
    floor = MIN_SAMPLES * dt
    window = max(BLOCK_S, floor)
    span = hi - lo
    if span / window < MIN_BLOCKS + 1:
        window = span / (MIN_BLOCKS + 1)
        if window < floor:
            log.info("no correlation-robust σ: a %.3g-s span holds too few windows of %d samples", span, MIN_SAMPLES)
            return None
        log.info("correlation-robust σ over %.3g-s windows (a short span); longer correlation is not seen", window)
    return window


def fit_sigma_scale(
    problem, result, weights: Mapping[str, float], window: float | None = SIGMA_WINDOW
) -> SigmaScale | None:
    """The sandwich σ scale of a finished fit, or None (logged) when off or not estimable.

    Parameters
    ----------
    problem : the fitted problem; result : its result with residuals against the stated σ.
    weights : sensor -> the factor the fit weighted its stated σ with (absent: 1).
    window : window [s]; 0 turns it off; None chooses it (:func:`auto_window`).
    """
    if window == 0:
        return None
    if window is None:
        window = auto_window(result)
        if window is None:
            return None
    res = stated_residuals(result, {n: 1.0 / k for n, k in weights.items()}) if weights else result
    try:
        return sigma_scale(problem, res, block_s=window)
    except InputError as exc:
        log.info("no correlation-robust σ: %s", exc)
    except (np.linalg.LinAlgError, ValueError, FloatingPointError) as exc:
        log.info("no correlation-robust σ (numerical: %s)", exc)
    return None


def threshold(sc: SigmaScale) -> float:
    """The scale above which an element is flagged (module docstring)."""
    return max(FLAG_SCALE, 1.0 + FLAG_SIGMAS / math.sqrt(2.0 * max(sc.n_blocks, 1)))


def flagged(sc: SigmaScale | None) -> dict[str, float]:
    """Elements whose scale clearly exceeds 1 (module docstring) -> their scale."""
    if sc is None:
        return {}
    lim = threshold(sc)
    return {n: s for n, s in sc.scale.items() if s > lim}


def frames_per_window(sc: SigmaScale, result) -> dict[str, float]:
    """Sensor -> used frames per window. Below 2 a window holds about one sample: the scale
    then measures residuals larger than the stated noise (the heteroskedastic sandwich),
    not their correlation, which needs a window longer than the sampling interval."""
    return {
        n: float(np.count_nonzero(result.residuals[n].used)) / max(sc.n_blocks, 1)
        for n in sc.sensors
        if n in result.residuals
    }


def sigma_scale_report(sc: SigmaScale, sigma: Mapping[str, float], result=None) -> dict[str, Any]:
    """The report's ``sigma_scale`` field: window, windows, used frames per window (with
    ``result``), threshold and per element the scale and the σ with it (``σ × max(1, s)``),
    in the element's unit."""
    honest = sc.honest_sigma({n: sigma[n] for n in sc.scale if n in sigma})
    per = frames_per_window(sc, result) if result is not None else {}
    return {
        "method": "batch-means sandwich, conditional on the attitude",
        "window_s": sc.block_s,
        "n_windows": sc.n_blocks,
        "sensors": list(sc.sensors),
        "frames_per_window": {n: round(v, 2) for n, v in per.items()},
        "flag_above": round(threshold(sc), 4),
        "not_estimable": list(sc.failed),
        "elements": {
            n: {"scale": round(s, 4), "sigma": float(sigma[n]), "sigma_with_correlation": honest[n]}
            for n, s in sc.scale.items()
            if n in honest
        },
    }
