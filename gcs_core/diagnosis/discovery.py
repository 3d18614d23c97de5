"""Discovery's record: each change of the add/refit loop (seed §3.3) as a :class:`Step`.

The loop itself drives a session and lives beside it (:mod:`gcs_core.stepwise`); which of a
group of aliased candidates it adds is :func:`gcs_core.diagnosis.policy.parsimonious`.
"""

from __future__ import annotations

import math
from collections.abc import Mapping
from dataclasses import dataclass, field


@dataclass(frozen=True)
class Step:
    """One entry of the add/refit history.

    Attributes
    ----------
    action : "fit", "add" or "remove"; effect : the effect id (None for the first fit).
    rms_before, rms_after : sensor -> normalized RMS on the fitted span.
    holdout_after : sensor -> normalized RMS on the held-out span (empty if none).
    delta_chi2 : χ² removed by the change (fit χ² before − after).
    estimates : element -> value after the step, for the elements of ``effect``.
    """

    action: str
    effect: str | None
    rms_before: Mapping[str, float]
    rms_after: Mapping[str, float]
    holdout_after: Mapping[str, float]
    delta_chi2: float
    chi2_after: float
    estimates: Mapping[str, float] = field(default_factory=dict)

    def as_report(self) -> dict:
        return {
            "action": self.action,
            "added" if self.action != "remove" else "removed": self.effect,
            "rms_normalized_before": rounded(self.rms_before),
            "rms_normalized_after": rounded(self.rms_after),
            "holdout_rms_normalized_after": rounded(self.holdout_after),
            "delta_chi2": round(self.delta_chi2, 3),
            "estimates": dict(self.estimates),
        }


def rounded(d: Mapping[str, float]) -> dict:
    """Normalized RMS values for a report: 4 decimals, None where not finite."""
    return {k: (round(v, 4) if math.isfinite(v) else None) for k, v in d.items()}
