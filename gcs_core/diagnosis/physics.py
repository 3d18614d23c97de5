"""Which always-on physics the data need (the physics statistics of discovery).

Each always-on physics option (aberration, parallax, the field model, the Earth's
oblateness) is scored like a candidate effect at the current solution, with its signature
``d = h_off − h_on`` (:func:`gcs_core.diagnosis.ranking.rank_candidates`). No refit is made.
The statistics come back as :class:`PhysicsNeed`; the sentence saying why is made where
they are shown (:func:`gcs_core.reporting.physics_why`).
"""

from __future__ import annotations

from collections.abc import Mapping
from dataclasses import dataclass, field

import numpy as np
from scipy import stats

from gcs_core.diagnosis.ranking import rank_candidates


@dataclass(frozen=True)
class PhysicsNeed:
    """What switching one always-on physics option off would cost.

    Attributes
    ----------
    id : the option's effect id (``model.<option>``).
    delta_chi2_if_removed : ``Δχ² = S − 2g`` on 1 dof (:func:`physics_needed`).
    needed : the increase is significant at the family-wise level ``alpha``.
    critical_chi2 : the χ² on 1 dof that ``alpha`` needs; alpha : that level.
    sensors : sensor -> share of the signature's information, largest first.
    explanation : what the physics is (the catalogue's text).
    """

    id: str
    delta_chi2_if_removed: float
    needed: bool
    critical_chi2: float
    alpha: float
    sensors: Mapping[str, float] = field(default_factory=dict)
    explanation: str = ""


def physics_needed(problem, result, effects, *, alpha: float, smoothed: bool = False) -> list[PhysicsNeed]:
    """For each physics option in ``effects`` (all switched on), what switching it off would cost.

    With ``c`` the fraction of ``d`` added, ``χ²(c) ≈ χ²₀ − 2cg + c²S`` (``g`` the
    conditional score, ``S`` its information), so switching off (``c = 1``) adds
    ``Δχ² = S − 2g = (1 − 2ĉ)/σ_c²``, ``ĉ = g/S``. The option is *needed* when that increase
    is significant at the family-wise level ``alpha`` on one degree of freedom. Largest
    cost first.
    """
    crit = float(stats.chi2.isf(alpha, 1))
    out: list[PhysicsNeed] = []
    for c in rank_candidates(problem, result, effects, alpha=alpha, smoothed=smoothed):
        sig = c.sigma.get(c.id, float("inf"))
        c_hat = c.estimate.get(c.id, 0.0)
        cost = (1.0 - 2.0 * c_hat) / sig**2 if np.isfinite(sig) and sig > 0 else 0.0
        shares = dict(sorted(c.sensors.items(), key=lambda kv: -kv[1]))
        out.append(PhysicsNeed(c.id, float(cost), bool(cost > crit), crit, alpha, shares, c.effect.explanation))
    out.sort(key=lambda d: -round(d.delta_chi2_if_removed, 3))
    return out
