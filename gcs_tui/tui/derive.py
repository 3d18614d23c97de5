"""Small pure functions that turn engine results into what a screen draws.

Arrays in, arrays out; no Textual, no I/O. Shapes are stated per function.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np
from scipy import stats

from gcs_tui.binning import Binned, binned_means  # noqa: F401 — the screens read them here


def argument_of_latitude(r_I: np.ndarray, v_I: np.ndarray) -> np.ndarray:
    """(N,) argument of latitude u [deg, 0..360) from (N, 3) position and velocity.

    ``u`` is the angle in the orbit plane from the ascending node to the position::

        h = r × v,   n = ẑ × h (node line),   u = atan2((ĥ × n̂)·r, n̂·r)

    For an equatorial orbit (n = 0) the x axis stands in for the node.
    """
    r = np.asarray(r_I, dtype=float)
    v = np.asarray(v_I, dtype=float)
    h = np.cross(r, v)
    hn = np.linalg.norm(h, axis=1, keepdims=True)
    h_hat = h / np.where(hn > 0, hn, np.nan)  # no orbit (a ground mission): NaN, silently
    n = np.column_stack([-h[:, 1], h[:, 0], np.zeros(len(h))])
    nn = np.linalg.norm(n, axis=1, keepdims=True)
    n_hat = np.where(
        nn > 1e-12 * np.linalg.norm(h, axis=1, keepdims=True),
        n / np.where(nn > 0, nn, 1.0),
        np.array([[1.0, 0.0, 0.0]]),
    )
    m_hat = np.cross(h_hat, n_hat)
    u = np.degrees(np.arctan2(np.sum(m_hat * r, axis=1), np.sum(n_hat * r, axis=1)))
    return np.mod(u, 360.0)


@dataclass(frozen=True)
class Histogram:
    """Counts of normalized residuals and the counts a unit normal would give.

    Attributes
    ----------
    centers : (B,) bin centres; counts : (B,) observed; expected : (B,) N(0, 1) counts.
    """

    centers: np.ndarray
    counts: np.ndarray
    expected: np.ndarray


def histogram(z: np.ndarray, *, bins: int = 25, limit: float = 5.0) -> Histogram:
    """Histogram of finite ``z`` (N,) on [-limit, limit] with the N(0, 1) expectation."""
    z = np.asarray(z, dtype=float)
    z = z[np.isfinite(z)]
    edges = np.linspace(-limit, limit, bins + 1)
    counts, _ = np.histogram(np.clip(z, -limit, limit), bins=edges)
    expected = z.size * np.diff(stats.norm.cdf(edges))
    return Histogram(0.5 * (edges[1:] + edges[:-1]), counts.astype(float), expected)


def autocorrelation(z: np.ndarray, max_lag: int = 50) -> tuple[np.ndarray, np.ndarray, float]:
    """Sample autocorrelation of finite ``z`` (N,) at lags 0..max_lag (in samples).

    Returns ``(lags, acf, band)``; ``band = 2/√N`` is the ±2σ band of white noise.
    """
    z = np.asarray(z, dtype=float)
    z = z[np.isfinite(z)]
    n = z.size
    max_lag = int(min(max_lag, max(n - 1, 0)))
    if n < 2:
        return np.arange(1), np.ones(1), math.inf
    d = z - z.mean()
    var = float(d @ d)
    if var == 0:
        return np.arange(max_lag + 1), np.zeros(max_lag + 1), 2.0 / math.sqrt(n)
    acf = np.array([float(d[: n - k] @ d[k:]) / var for k in range(max_lag + 1)])
    return np.arange(max_lag + 1), acf, 2.0 / math.sqrt(n)


def segments(t: np.ndarray, *, gap_factor: float = 3.0) -> tuple[list[tuple[float, float]], float]:
    """Contiguous spans of a sorted time series (N,) and its median cadence.

    A gap is a step longer than ``gap_factor`` times the median step. Returns
    ``([(t0, t1), …], cadence)``.
    """
    t = np.asarray(t, dtype=float)
    if t.size == 0:
        return [], math.nan
    if t.size == 1:
        return [(float(t[0]), float(t[0]))], math.nan
    dt = np.diff(t)
    cadence = float(np.median(dt))
    breaks = np.nonzero(dt > gap_factor * cadence)[0]
    starts = np.concatenate([[0], breaks + 1])
    ends = np.concatenate([breaks, [t.size - 1]])
    return [(float(t[a]), float(t[b])) for a, b in zip(starts, ends)], cadence


def chi2_band(dof: int, coverage: float = 0.95) -> tuple[float, float]:
    """Two-sided ``coverage`` band of a χ²(dof) statistic (NIS of one block)."""
    if dof <= 0:
        return math.nan, math.nan
    a = (1.0 - coverage) / 2.0
    return float(stats.chi2.ppf(a, dof)), float(stats.chi2.ppf(1.0 - a, dof))


def thin(n: int, limit: int) -> np.ndarray:
    """Indices 0..n-1 taken with an even stride so that at most ``limit`` remain.

    Used only to keep plot drawing fast; every edited point is drawn regardless.
    """
    if n <= limit:
        return np.arange(n)
    return np.unique(np.linspace(0, n - 1, limit).round().astype(int))


def spread(values: np.ndarray, *, floor: float = 1e-300) -> float:
    """Largest finite |value| (for symmetric plot limits); ``floor`` if none."""
    v = np.asarray(values, dtype=float)
    v = np.abs(v[np.isfinite(v)])
    return float(v.max()) if v.size else floor


def aux_unit(name: str) -> str:
    """The unit of auxiliary channel ``name`` by the ICD's naming ('' when unknown;
    the rule is :func:`gcs_core.display.aux_unit`)."""
    from gcs_core.display import aux_unit as rule

    return rule(name)


def poor_choice(c, alpha: float) -> str:
    """Why adding candidate ``c`` is a poor choice ('' when it is significant and identifiable)."""
    from gcs_core import display as fmt

    reasons = []
    if not c.significant:
        reasons.append(
            f"It is not significant: {fmt.p_text(c.p_adjusted, 'p adj')} is not below the family-wise "
            f"α = {alpha:g}, so its Δχ² = {fmt.sig(c.delta_chi2, 3)} is what noise alone often gives "
            "with this many candidates tried."
        )
    if not c.identifiable:
        with_what = ", ".join(list(c.aliases_state) + [a for a, _ in c.aliases_candidates])
        reasons.append(
            "It is not identifiable: the data cannot tell it apart from "
            + (with_what if with_what else "what is already estimated")
            + ", so its estimate would be set by the a priori and trade off against those."
        )
    return " ".join(reasons)
