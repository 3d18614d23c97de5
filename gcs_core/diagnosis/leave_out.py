"""Blame by leaving a sensor out: is a candidate significant only through another sensor?

Issue 26, rule 4 of :mod:`gcs_core.diagnosis.blame`. A sensor Y whose residual exceeds its
noise and follows a channel no candidate has the form of (a tracker error following the
star's magnitude) moves the fitted attitude with that error; a sensor X within its noise
then follows it (a Sun sensor "follows time"), and X's drift family passes its score test
though X is perfect. The test that separates the two: refit with Y's weight taken away (its
σ multiplied by :data:`OUT_FACTOR`, the weights of the other sensors held as measured) and
rank again. If X's candidate is no longer significant there, it was significant only through
Y's unexplained error, and it is not added; if it still passes, X's effect is its own.
The session is restored exactly afterwards; the check costs one fit, and runs only when
such a Y exists and the candidate is on another sensor within its noise.
"""

from __future__ import annotations

import logging
import math
from collections.abc import Iterable
from dataclasses import replace
from typing import TYPE_CHECKING

import numpy as np

from gcs_core.diagnosis.alternative import SavedSession, held_fit
from gcs_core.errors import EstimationError
from gcs_core.noise.weighting import NoiseFactor

if TYPE_CHECKING:
    from gcs_core.session import Analysis

log = logging.getLogger(__name__)

#: the factor a left-out sensor's σ is weighted with (its information × 1e-6: out)
OUT_FACTOR = 1e3


def passes_without(analysis: Analysis, sensors: Iterable[str], candidate_id: str) -> bool:
    """Whether ``candidate_id`` still passes (significant and identifiable) when ``sensors``
    are left out of the fit (module docstring). A trial that fails counts as passing (the
    candidate keeps its place)."""
    saved = SavedSession(analysis)
    try:
        factors = dict(analysis._factors)
        for s in sensors:
            f = factors.get(s) or NoiseFactor(s, 0.0, 0, math.nan, math.nan, 1.0)
            factors[s] = replace(f, factor=OUT_FACTOR * max(f.factor, 1.0), note="left out (blame)")
        held_fit(analysis, factors)
        again = next((c for c in analysis.rank() if c.id == candidate_id), None)
        return again is not None and again.passes
    except (EstimationError, np.linalg.LinAlgError) as exc:
        log.info("%s: not checked without %s (%s)", candidate_id, ", ".join(sensors), exc)
        return True
    finally:
        saved.restore(analysis)
