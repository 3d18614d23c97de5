"""Held repeats and interpolated samples: a sensor read by a bus faster than it updates.

A sample equal to the one before *exactly on every axis* is, for a noisy sensor, almost
never chance: with white noise σ per sample and a quantization step q ≪ σ, two samples
fall on the same step with probability ≈ q / (2 √π σ) per axis (the density of their
difference at zero, times q; the difference has σ√2), the product over the axes for all
of them. Far more repeats than that, at rest and in motion alike, are the bus reading the
last value again: the *earlier* measurement under a later time stamp, and one noise draw
counted twice. Likewise a sample equal to the mean of its two neighbours on every axis
(second difference zero to rounding; by chance ≈ q / (σ √(12π)) per axis, the second
difference having σ√6) was interpolated onto the bus's clock: no new measurement, its
noise the average of its neighbours'. Converters write them with ``flag =``
:data:`FLAG_HELD` and :data:`FLAG_INTERPOLATED` (kept in the file, not used: the import
leaves flagged rows out and counts them); :data:`FLAG_TRANSIENT` marks a start-up
transient. A channel is flagged only where these samples outnumber the chance count of
its quantization :data:`EXCESS` times and make at least :data:`MIN_FRACTION` of it
(:func:`bus_check`): otherwise its exact repeats are quantization and stay in.
"""

from __future__ import annotations

import numpy as np

__all__ = [
    "FLAG_TRANSIENT",
    "FLAG_HELD",
    "FLAG_INTERPOLATED",
    "FLAG_NOTE",
    "held_repeats",
    "interpolated",
    "hold_runs",
    "bus_check",
]

#: ``flag`` of a start-up transient (kept, not used)
FLAG_TRANSIENT = 1
#: ``flag`` of a held repeat: equal to the sample before on every axis (kept, not used)
FLAG_HELD = 2
#: ``flag`` of an interpolated sample: the mean of its two neighbours (kept, not used)
FLAG_INTERPOLATED = 3
#: flagged when more frequent than chance this many times and at least this fraction
EXCESS = 10.0
MIN_FRACTION = 0.01
#: the relative rounding below which a repeat or a second difference counts as exact
EXACT = 1e-12
FLAG_NOTE = (
    f"flag {FLAG_HELD} = held repeat (the sample before read again), flag {FLAG_INTERPOLATED} = "
    "interpolated (the mean of its neighbours): kept, not used"
)


def held_repeats(y: np.ndarray) -> np.ndarray:
    """(N,) True where sample k equals sample k−1 exactly in every component (``y`` (N, m)):
    a held value, not a new measurement. Sample 0 is never held."""
    y = np.asarray(y)
    out = np.zeros(y.shape[0], dtype=bool)
    if y.shape[0] > 1:
        out[1:] = np.all(y[1:] == y[:-1], axis=1)
    return out


def hold_runs(held: np.ndarray) -> dict[int, int]:
    """How often each value was read: ``{n: count}`` over the runs of ``n`` identical samples
    (1: read once; 3: the value and two held repeats), from :func:`held_repeats`'s mask."""
    held = np.asarray(held, dtype=bool)
    if held.size == 0:
        return {}
    starts = np.flatnonzero(~held)
    if held[0]:
        starts = np.concatenate([[0], starts])
    lengths = np.diff(np.concatenate([starts, [held.size]]))
    n, c = np.unique(lengths, return_counts=True)
    return {int(a): int(b) for a, b in zip(n, c)}


def interpolated(y: np.ndarray, held: np.ndarray) -> np.ndarray:
    """(N,) True where sample k (not held) is the mean of samples k−1 and k+1 on every
    component, to rounding (:data:`EXACT` of the values' scale)."""
    y = np.asarray(y, dtype=float)
    out = np.zeros(y.shape[0], dtype=bool)
    if y.shape[0] > 2:
        tol = EXACT * (1.0 + np.max(np.abs(y)))
        dd = y[2:] - 2.0 * y[1:-1] + y[:-2]
        out[1:-1] = np.all(np.abs(dd) <= tol, axis=1)
    return out & ~np.asarray(held, dtype=bool)


def _steps(y: np.ndarray) -> np.ndarray:
    """(m,) the smallest non-zero change of each component: its quantization step."""
    out = []
    tol = EXACT * (1.0 + float(np.max(np.abs(y))))
    for k in range(y.shape[1]):
        d = np.abs(np.diff(y[:, k]))
        d = d[d > tol]
        out.append(float(d.min()) if d.size else np.nan)
    return np.array(out)


def bus_check(label: str, y: np.ndarray, moving: np.ndarray, dt: float) -> tuple[np.ndarray, list[str]]:
    """``(flag (N,) int, report lines)`` for one channel (N, m) read every ``dt`` [s]:
    held repeats (:data:`FLAG_HELD`) and interpolated samples (:data:`FLAG_INTERPOLATED`),
    each flagged only when far above the chance count of the channel's quantization
    (module docstring). The noise σ behind the chance counts is that of the first
    differences of the remaining samples at rest (``~moving``), a lower bound when they
    are correlated, so the chance counts are upper bounds.
    """
    y = np.asarray(y, dtype=float)
    moving = np.asarray(moving, dtype=bool)
    n = y.shape[0]
    rep = held_repeats(y)
    mid = interpolated(y, rep)
    own = ~rep & ~mid
    d = np.diff(y[own & ~moving] if (own & ~moving).sum() > 10 else y[own], axis=0)
    sigma = 1.4826 * np.median(np.abs(d - np.median(d, axis=0)), axis=0) / np.sqrt(2.0)
    q = _steps(y)
    s = np.maximum(sigma, 1e-300)
    p_rep = float(np.prod(np.minimum(1.0, q / (2.0 * np.sqrt(np.pi) * s))))
    p_mid = float(np.prod(np.minimum(1.0, q / (np.sqrt(12.0 * np.pi) * s))))
    flag = np.zeros(n, dtype=int)
    lines = []
    why = f"quantization step {np.array2string(q, precision=4)} against a noise ≥ {np.array2string(sigma, precision=4)}"
    for what, mask, p, value in (
        ("repeat the sample before", rep, p_rep, FLAG_HELD),
        ("are the mean of their neighbours", mid, p_mid, FLAG_INTERPOLATED),
    ):
        found = int(mask.sum())
        chance = p * max(n - 2, 0)
        at = (
            f"{found} of {n} samples ({100.0 * found / max(n, 1):.1f} %; at rest "
            f"{100.0 * mask[~moving].mean() if (~moving).any() else 0.0:.1f} %, in motion "
            f"{100.0 * mask[moving].mean() if moving.any() else 0.0:.1f} %) {what} exactly on every axis"
        )
        if found >= MIN_FRACTION * n and found > EXCESS * max(chance, 1.0):
            flag[mask] = value
            lines.append(f"{label}: {at}, ≤ {chance:.3g} by chance ({why}): flagged (flag = {value}), kept, not used")
        else:
            lines.append(f"{label}: {at}; ≤ {chance:.3g} by chance ({why}): quantization, kept")
    if flag.any():
        runs = hold_runs(rep)
        ages = sum(c * m * (m - 1) / 2 for m, c in runs.items())  # ticks of age over the repeats
        used = np.flatnonzero(flag == 0)
        gaps = np.diff(used)
        g, c = np.unique(gaps, return_counts=True)
        lines.append(
            f"{label}: values read n times (n× count): "
            + ", ".join(f"{m}× {k}" for m, k in sorted(runs.items()))
            + f"; mean age of a held repeat {1e3 * dt * ages / max(int(rep.sum()), 1):.2f} ms; the samples used "
            f"({used.size}, {used.size / (n * dt):.1f} Hz on a {1.0 / dt:.1f} Hz bus) follow each other after "
            + ", ".join(f"{int(a)} ({int(b)}×)" for a, b in zip(g, c))
            + " bus intervals"
        )
    return flag, lines
