"""Sizes bounded before anything is allocated.

One key or flag must not exhaust the memory: ``prediction.step = 1e-6`` asked for 7.2 GB,
``gcs montecarlo --runs 1000000000000`` for 3.7 GB. Each bound here is checked where the
value is read, before the arrays it sizes exist, and a breach is one line naming the key
and the limit (``InputError``, exit 2). The bounds sit far above any real use: a week of
data at 10 Hz is 6e6 frames.
"""

from __future__ import annotations

#: output times of a prediction ((end − start) / prediction.step + 1)
MAX_OUTPUT_TIMES = 1_000_000
#: frames of one sensor over a data plan (span / cadence + 1)
MAX_PLAN_FRAMES = 20_000_000
#: length of a planned span [min] (a trade study's span_min, a pass plan's total): one year
MAX_SPAN_MIN = 366 * 24 * 60.0
#: knots of a whole-span fit (span / knot spacing; the spacing is at least the gyro's
#: sample interval, so real data stay far below)
MAX_KNOTS = 2_000_000
#: runs of one Monte Carlo study
MAX_MONTECARLO_RUNS = 100_000
