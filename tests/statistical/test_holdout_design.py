"""The held-out design (:mod:`gcs_core.diagnosis.holdout`, :meth:`Analysis.holdout_masks`).

The held-out frames must sample every part of the orbit, at every span: blocks of 5 min
held out by the golden-ratio rotation. The periodic design it replaces (every 4th of 20
equal blocks) recurs every 96 min on an 8 h span, one orbital period, so its held-out
frames all saw one orbital phase (a star tracker kept 1 of 1663 frames there). Checked
without a fit: the shares of held-out frames overall and in each tenth of the orbit.
"""

from __future__ import annotations

from types import SimpleNamespace

import numpy as np
import pytest

from gcs_core.diagnosis.holdout import holdout_masks

#: a LEO period [s]
orbit_s = 95.0 * 60.0
#: held-out share overall: the configured fraction within this (block granularity)
share_tolerance = 0.04
#: ... and in each tenth of the orbit at least this (the periodic design gave 0)
phase_share_min = 0.10


def _masks(hours: float, fraction: float = 0.25, cadence: float = 10.0):
    t = np.arange(0.0, hours * 3600.0, cadence)
    return t, holdout_masks([SimpleNamespace(name="FHST1", t=t)], fraction).get("FHST1")


@pytest.mark.parametrize("hours", [1.0, 3.0, 4.0, 8.0, 24.0])
def test_held_out_frames_sample_every_orbital_phase(hours):
    t, held = _masks(hours)
    assert abs(held.mean() - 0.25) < share_tolerance
    if hours >= 8.0:  # five orbits and more: every phase recurs
        phase = ((t % orbit_s) / orbit_s * 10).astype(int)
        shares = [held[phase == k].mean() for k in range(10)]
        assert min(shares) > phase_share_min, shares


def test_the_ends_are_never_held_out_and_no_fraction_holds_nothing():
    t, held = _masks(8.0)
    assert not held[t < 300.0].any() and not held[t > t[-1] - 300.0].any()
    assert _masks(4.0, fraction=0.0)[1] is None
