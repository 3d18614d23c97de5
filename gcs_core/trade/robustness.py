"""How much an optimized plan depends on what the search did not control.

The optimizer (:mod:`gcs_core.trade.optimize`) picks the cheapest plan; the σ of some
targets depends strongly on where in the orbit the plan starts (the TAM bias varies
2.6-fold with the start of a 20-minute pass, seed §2.1.2, Figure 2-1), which an operator
may not choose. :func:`start_phase_lines` recomputes the chosen plan at
:data:`PHASES_MIN` starts over an orbit and reports, per target element, the range of σ
as a multiple of the chosen plan's and at how many starts the target is still met.
"""

from __future__ import annotations

import math
from collections.abc import Mapping, Sequence

#: start phases tried [min from the plan's start]: an orbit of a low satellite (~95 min)
PHASES_MIN = (0.0, 15.0, 30.0, 45.0, 60.0, 75.0, 90.0)


def start_phase_lines(defn, row, targets: Sequence, elements: Mapping[str, list[str]], margin: float) -> list[str]:
    """Lines: the chosen plan's σ over the start phase (module docstring)."""
    from gcs_core.trade.report import element_unit, in_unit
    from gcs_core.trade.study import evaluate_plans

    base = dict(row.values)
    offset = float(base.get("start_min", 0.0))
    combos = [{**base, "start_min": offset + p} for p in PHASES_MIN]
    rows = [r for r in evaluate_plans(defn, list(enumerate(combos))) if r.status == "ok"]
    if not rows:
        return []
    out = [f"not controlled, the start in the orbit ({len(rows)} starts over {PHASES_MIN[-1]:g} min):"]
    for t in targets:
        for n in elements.get(t.name, []):
            s = [r.sigma_of(n) for r in rows]
            finite = [x for x in s if math.isfinite(x)]
            if not finite:
                continue
            mine = row.sigma_of(n)
            met = sum(1 for x in s if math.isfinite(x) and x * (1.0 + margin) < t.limit)
            shown, label = element_unit(row.units[row.elements.index(n)], mine)
            u = row.units[row.elements.index(n)]
            lo, hi = in_unit(min(finite), u, shown), in_unit(max(finite), u, shown)
            out.append(
                f"  {n:<16} σ {lo:.3g} to {hi:.3g} {label}".rstrip()
                + f" (× {min(finite) / mine:.2f} to {max(finite) / mine:.2f} the chosen start's); "
                f"target met at {met} of {len(rows)} starts"
            )
    return out
