"""Plot data both faces share (the TUI's screens and the exported HTML): binned means of a
residual against a channel, and a display decimation that keeps the envelope.

Plain numpy; no Textual, no terminal. Decimation is for drawing only: every statistic
(RMS, binned means, χ²) is computed on all the points.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np


@dataclass(frozen=True)
class Binned:
    """Binned means of a residual against a channel.

    Attributes
    ----------
    centers : (B,) the bin's mean x; mean : (B,) mean residual; err : (B,) standard error of
    the mean (the residuals' scatter in the bin / √n; σ/√n when a bin has one point);
    n : (B,) points per bin.
    """

    centers: np.ndarray
    mean: np.ndarray
    err: np.ndarray
    n: np.ndarray


def binned_means(x: np.ndarray, y: np.ndarray, sigma: float, *, bins: int = 24, distinct: int = 24) -> Binned:
    """Mean of ``y`` (N,) in bins of ``x`` (N,) with its standard error.

    A channel with at most ``distinct`` distinct values (a torquer at −60, 0, +60) gets one
    bin per value; otherwise ``bins`` equal-count bins. Non-finite pairs are dropped;
    ``sigma`` is the per-point σ used when a bin's own scatter is undefined.
    """
    x = np.asarray(x, dtype=float)
    y = np.asarray(y, dtype=float)
    ok = np.isfinite(x) & np.isfinite(y)
    x, y = x[ok], y[ok]
    if x.size == 0:
        e = np.zeros(0)
        return Binned(e, e, e, e.astype(int))
    values = np.unique(x)
    if values.size <= distinct:
        idx = np.searchsorted(values, x)
        nb = values.size
    else:
        edges = np.unique(np.quantile(x, np.linspace(0.0, 1.0, bins + 1)))
        idx = np.clip(np.searchsorted(edges, x, side="right") - 1, 0, edges.size - 2)
        nb = edges.size - 1
    n = np.bincount(idx, minlength=nb)
    sx = np.bincount(idx, weights=x, minlength=nb)
    sy = np.bincount(idx, weights=y, minlength=nb)
    syy = np.bincount(idx, weights=y * y, minlength=nb)
    keep = n > 0
    n, sx, sy, syy = n[keep], sx[keep], sy[keep], syy[keep]
    mean = sy / n
    var = np.where(n > 1, np.clip(syy - n * mean**2, 0.0, None) / np.maximum(n - 1, 1), sigma**2)
    return Binned(sx / n, mean, np.sqrt(var / n), n)


#: units of auxiliary channels by name (ICD §6: torquer dipoles in A m², temperatures in °C)


def envelope(n: int, values: np.ndarray, limit: int) -> np.ndarray:
    """Indices of at most ``limit`` of ``n`` points in order, for drawing: the points are cut
    into ``limit // 2`` runs and each run keeps its lowest and highest value, so outliers
    and the envelope stay visible however many points are dropped."""
    if n <= limit:
        return np.arange(n)
    v = np.asarray(values, dtype=float)
    runs = np.array_split(np.arange(n), max(limit // 2, 1))
    keep = []
    for r in runs:
        seg = v[r]
        ok = np.isfinite(seg)
        if not ok.any():
            keep.append(r[0])
            continue
        keep += [r[np.nanargmin(np.where(ok, seg, np.nan))], r[np.nanargmax(np.where(ok, seg, np.nan))]]
    return np.unique(np.asarray(keep, dtype=int))
