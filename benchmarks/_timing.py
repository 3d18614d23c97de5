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


def interleaved(fns: dict, rounds: int, seed: int | None = 0) -> dict[str, np.ndarray]:
    """name -> (rounds,) wall seconds of each ``fn()``, the functions called in turn round
    after round: a ratio taken within a round sees the same machine state (load, clock,
    caches), which a best-of-each taken minutes apart does not. With ``seed`` the order is
    drawn afresh each round (seeded): a function's time also depends on what ran just
    before it (the pages the previous call freed), and a fixed order would give each
    function the same predecessor every round."""
    rng = None if seed is None else np.random.default_rng(seed)
    names = list(fns)
    out: dict[str, list[float]] = {k: [] for k in fns}
    for _ in range(rounds):
        for k in names if rng is None else [names[i] for i in rng.permutation(len(names))]:
            t0 = time.perf_counter()
            fns[k]()
            out[k].append(time.perf_counter() - t0)
    return {k: np.asarray(v) for k, v in out.items()}
