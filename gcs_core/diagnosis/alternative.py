"""Noise weights measured under the alternative, for a candidate the null's weights hide.

The default fit weights each sensor by ``σ √κ`` with ``κ`` measured on the fit's own
residuals (:mod:`gcs_core.noise.correlated`). A candidate effect is scored at the null (the
current model), so when it is really there its signature is in the residuals the weights
were measured on: a misfit that changes from sample to sample (a star tracker's
misalignment, each frame another star) raises the sensor's residual variance and *lowers*
its lag-1 autocorrelation, so its Gauss–Markov noise goes unseen and the sensor is weighted
as white; the attitude then follows it, another sensor takes the misfit as a slow residual
(its ``τ`` overestimated), and the effect reads as absorbed by the state. Issue 27, FHST1
roll 0.1° under τ = 60 s noise on both trackers and the magnetometer (4 h Sun-pointing):
FHST1 × 1, FHST2 × 4.8, TAM1 × 10.9, Δχ² 3559 but 99.957 % absorbed (limit 99.9 %); with
the true κ declared (FHST1 and FHST2 × 3.47, TAM1 × 10.95) the same candidate is 99.27 %
absorbed, Δχ² 316, and found.

The weights are a nuisance estimate, consistent only under the model that is true. A
score test takes them from the null, which is right when the null holds (the false-alarm
rate, issue 27's alarms sweep, is untouched: this path runs only when a candidate is
already significant). When the most significant candidate is unidentifiable by
absorption (``absorbed ≥`` :data:`~gcs_core.diagnosis.ranking.ABSORB_TOL`), the weights
are measured again on the fit with it added (:func:`weights_under`), the current model is
refitted with those weights held, and the candidates ranked there (:func:`recheck`): the
same tests, the same limit, with the nuisance evaluated where the test's own evidence says
the data are (as a likelihood-ratio test re-estimates its nuisance under the alternative;
Cox & Hinkley, *Theoretical Statistics*, 1974, §9.3). If the candidate passes there it is
offered to discovery, which adds it and re-measures the weights as every step does; if
not, the session is restored exactly and nothing changes. It runs only while some sensor
is carried (weighted by ``√κ > 1``): on white noise nothing runs and nothing changes.
"""

from __future__ import annotations

import logging
from collections.abc import Sequence
from typing import TYPE_CHECKING

import numpy as np

from gcs_core.diagnosis.ranking import ABSORB_TOL, Candidate
from gcs_core.errors import EstimationError
from gcs_core.noise.weighting import same_factors

if TYPE_CHECKING:
    from gcs_core.session import Analysis

log = logging.getLogger(__name__)


class SavedSession:
    """What a trial changes in a session, to put back."""

    def __init__(self, analysis: Analysis):
        self.parts = (analysis.config, analysis.problem, dict(analysis._factors), analysis.record, analysis.candidates)

    def restore(self, analysis: Analysis) -> None:
        analysis.config, analysis.problem, factors, analysis.record, analysis.candidates = self.parts
        analysis._factors = dict(factors)


def weights_under(analysis: Analysis, effect_id: str) -> dict:
    """The noise factors measured on the fit with ``effect_id`` added (the session is left as
    it was)."""
    saved = SavedSession(analysis)
    prev = analysis.result
    assert prev is not None
    try:
        analysis._set_effect(effect_id, True)
        warm = {k: v for k, v in prev.state.values().items() if k in analysis.problem.state}
        analysis.fit(holdout=False, initial=warm)
        return dict(analysis._factors)
    finally:
        saved.restore(analysis)


def held_fit(analysis: Analysis, factors: dict) -> None:
    """Refit the current model with ``factors`` held (measured, not refitted)."""
    prev = analysis.result
    assert prev is not None
    analysis._factors = dict(factors)
    analysis.problem = analysis._build()
    analysis.hold_factors = True
    try:
        analysis.fit(initial=prev.state.values())
    finally:
        analysis.hold_factors = False


def recheck(analysis: Analysis, cands: Sequence[Candidate]) -> list[Candidate] | None:
    """The candidates ranked at the weights measured under the most significant one (of
    ``cands``, most significant first) when it is unidentifiable by absorption (module
    docstring) and passes there; None (the session unchanged) otherwise."""
    if analysis.config.filter.noise_weighting != "correlated" or analysis.result is None or not analysis._scale():
        return None  # white noise: no sensor carried, nothing runs
    best = next((c for c in cands if c.significant and c.dof > 0), None)
    if best is None or best.absorbed < ABSORB_TOL:
        return None
    saved = SavedSession(analysis)
    try:
        alt = weights_under(analysis, best.id)
        if same_factors(alt, analysis._factors):
            return None
        held_fit(analysis, alt)
        new = analysis.rank()
    except (EstimationError, np.linalg.LinAlgError) as exc:  # a trial that fails changes nothing
        log.info("%s: weights under it not measured (%s)", best.id, exc)
        saved.restore(analysis)
        return None
    again = next((c for c in new if c.id == best.id), None)
    if again is not None and again.passes:
        log.info(
            "%s: %.2f%% absorbed at the weights measured under it (%.3f%% at the current ones); offered",
            best.id,
            100 * again.absorbed,
            100 * best.absorbed,
        )
        return new
    saved.restore(analysis)
    return None
