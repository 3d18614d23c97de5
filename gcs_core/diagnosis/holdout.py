"""The held-out span: which frames a fit leaves out to score its predictions.

The span is cut into blocks of :data:`BLOCK_S` (at least :data:`MIN_BLOCKS`), and block
``b`` is held out when ``frac(b/φ) < fraction`` (φ the golden ratio; never the first or the
last block): about that fraction of the blocks, spread evenly but with no period, so the
held-out frames sample every part of the orbit (slews, eclipses, the Sun's and the stars'
geometry) while the fit interpolates into them rather than extrapolating past the end of
its data. Held-out blocks are single blocks 2, 3 or 5 blocks apart (the three-gap property
of an irrational rotation).

A periodic choice aliases with the orbit: every 4th of 20 equal blocks recurs every 96 min
on an 8 h span, one orbital period, so every held-out block saw one orbital phase (a star
tracker kept 1 of 1663 frames there, 7 of 10 orbital phases were never held out). 5 min is
short against an orbit and long against the knot spacing (≈50 s) and a tracker's 10 s
cadence. The check's calibration against truth: docs/statistics.md.
"""

from __future__ import annotations

from collections.abc import Sequence

import numpy as np

#: held-out block length [s]
BLOCK_S = 300.0
#: ... and at least this many blocks over a span
MIN_BLOCKS = 20
#: 1/φ: the rotation that picks the held-out blocks
GOLDEN_STEP = (np.sqrt(5.0) - 1.0) / 2.0


def holdout_masks(sensors: Sequence, fraction: float) -> dict[str, np.ndarray]:
    """Sensor name -> (N,) True where the frame is held out (module docstring); {} when
    ``fraction`` ≤ 0. ``sensors``: objects with ``name`` and frame times ``t`` [s]."""
    if fraction <= 0 or not sensors:
        return {}
    t_all = np.concatenate([np.asarray(sd.t, float) for sd in sensors])
    if not t_all.size:
        return {}
    t0, t1 = float(t_all.min()), float(t_all.max())
    n_blocks = max(MIN_BLOCKS, round((t1 - t0) / BLOCK_S))
    width = (t1 - t0) / n_blocks or 1.0
    b = np.arange(n_blocks)
    held = (np.mod(b * GOLDEN_STEP, 1.0) < fraction) & (b > 0) & (b < n_blocks - 1)
    out = {}
    for sd in sensors:
        block = np.minimum(((np.asarray(sd.t, float) - t0) / width).astype(int), n_blocks - 1)
        out[sd.name] = held[block]
    return out
