"""Which always-on physics the data need, and why (the physics statistics of discovery).

Each always-on physics option (aberration, parallax, the field model, the Earth's
oblateness) is scored like a candidate effect at the current solution, with its signature
``d = h_off − h_on`` (:func:`gcs_core.diagnosis.ranking.rank_candidates`). No refit is made.
"""

from __future__ import annotations

from typing import Any

import numpy as np
from scipy import stats

from gcs_core.diagnosis.ranking import rank_candidates


def physics_needed(problem, result, effects, *, alpha: float, smoothed: bool = False) -> list[dict]:
    """For each physics option in ``effects`` (all switched on), what switching it off would cost.

    With ``c`` the fraction of ``d`` added, ``χ²(c) ≈ χ²₀ − 2cg + c²S`` (``g`` the
    conditional score, ``S`` its information), so switching off (``c = 1``) adds
    ``Δχ² = S − 2g = (1 − 2ĉ)/σ_c²``, ``ĉ = g/S``. The option is *needed* when that increase
    is significant at the family-wise level ``alpha`` on one degree of freedom. Returns one
    report row per option (``id``, ``delta_chi2_if_removed``, ``needed``, ``why``,
    ``physics``), largest cost first.
    """
    crit = float(stats.chi2.isf(alpha, 1))
    out: list[dict[str, Any]] = []
    for c in rank_candidates(problem, result, effects, alpha=alpha, smoothed=smoothed):
        sig = c.sigma.get(c.id, float("inf"))
        c_hat = c.estimate.get(c.id, 0.0)
        cost = (1.0 - 2.0 * c_hat) / sig ** 2 if np.isfinite(sig) and sig > 0 else 0.0
        seen = ", ".join(f"{k} ({100 * v:.0f}%)" for k, v in
                         sorted(c.sensors.items(), key=lambda kv: -kv[1]) if v >= 0.05)
        needed = cost > crit
        why = (f"switching it off would add Δχ² = {cost:.4g} on 1 dof"
               + (f", seen in {seen}" if seen else "")
               + ("; the data need it." if needed else
                  f"; below the {crit:.1f} that α = {alpha:g} needs: "
                  "these data cannot show it, but it is real physics."))
        out.append({"id": c.id, "delta_chi2_if_removed": round(float(cost), 3),
                    "needed": bool(needed), "why": why, "physics": c.effect.explanation})
    out.sort(key=lambda d: -d["delta_chi2_if_removed"])
    return out
