"""Timing helper shared by the benchmark scripts (imported from the scripts' own folder)."""

from __future__ import annotations

import time

import numpy as np


def best_of(fn, repeats: int) -> float:
    """Wall seconds of the fastest of ``repeats`` calls of ``fn()`` (the machine may be shared)."""
    best = float("inf")
    for _ in range(repeats):
        t0 = time.perf_counter()
        fn()
        best = min(best, time.perf_counter() - t0)
    return best


def interleaved(fns: dict, rounds: int) -> dict[str, np.ndarray]:
    """name -> (rounds,) wall seconds of each ``fn()``, the functions called in turn round
    after round: a ratio taken within a round sees the same machine state (load, clock,
    caches), which a best-of-each taken minutes apart does not."""
    out: dict[str, list[float]] = {k: [] for k in fns}
    for _ in range(rounds):
        for k, fn in fns.items():
            t0 = time.perf_counter()
            fn()
            out[k].append(time.perf_counter() - t0)
    return {k: np.asarray(v) for k, v in out.items()}
