"""Text tables of trade studies: the ranked plans and the error budget of the best ones."""

from __future__ import annotations

import math
from collections.abc import Sequence

from gcs_core import display
from gcs_core.trade.study import ATTITUDE_NAMES, PlanRow, ranked


def element_unit(unit: str, sigma: float) -> tuple[str, str]:
    """(display unit, its label) of an element of internal ``unit`` whose σ is ``sigma``:
    :func:`gcs_core.display.display_unit` (the one display rule), so ``gcs predict``,
    ``trade`` and ``montecarlo`` show one element alike (a dimensionless one with no unit)."""
    shown = display.display_unit(unit, sigma)
    return shown, display.unit_label(shown)


def in_unit(value: float, unit: str, shown: str) -> float:
    """``value`` (internal ``unit``) in the display unit ``shown``."""
    return display.to_display(value, unit, shown)


def sigma_display(value: float, unit: str) -> tuple[float, str]:
    """A σ in the small display unit of the one rule (rad → arcsec, rad/s → deg/h, rad/s2 →
    deg/h², dimensionless and others as they are) and its label; for a fixed axis label
    (plots, the TUI's columns) where no σ chooses the unit."""
    shown = display.display_unit(unit, 0.0)
    return in_unit(value, unit, shown), display.unit_label(shown)


def _cell(v: float, unit: str, prior: bool = False, shown: str | None = None) -> str:
    if math.isnan(v):
        return "—"
    if math.isinf(v):
        return "undet."
    x = in_unit(v, unit, shown) if shown is not None else sigma_display(v, unit)[0]
    return f"{x:.3g}" + ("*" if prior else "")


def _column_units(rows: Sequence[PlanRow], r0: PlanRow) -> list[str]:
    """One display unit per target column: the rule's unit for the column's largest σ."""
    return [
        display.common_unit(u, [r.sigma[i] for r in rows if r.status == "ok" and i < len(r.sigma)])
        for i, u in enumerate(r0.units)
    ]


def _short(name: str) -> str:
    return name.replace("attitude.", "att.")


def study_table(rows: Sequence[PlanRow], *, limit: int | None = 20) -> list[str]:
    """The plans ranked best first: score, varied values, σ of every target element."""
    if not rows:
        return ["no plans"]
    r0 = next((r for r in rows if r.status == "ok"), rows[0])
    keys = list(r0.values)
    shown = _column_units(rows, r0)
    heads = (
        ["#", "score"]
        + keys
        + [
            f"σ {_short(n)}" + (f" [{display.unit_label(sh)}]" if display.unit_label(sh) else "")
            for n, sh in zip(r0.elements, shown)
        ]
    )
    body = []
    for rank, (sc, r) in enumerate(ranked(rows), start=1):
        if limit is not None and rank > limit:
            break
        score = "failed" if r.status != "ok" else ("∞" if math.isinf(sc) else f"{sc:.3g}")
        body.append(
            [str(rank), score]
            + [str(r.values.get(k)) for k in keys]
            + [
                _cell(v, u, bool(r.prior_limited and r.prior_limited[i]), shown[i] if i < len(shown) else None)
                for i, (v, u) in enumerate(zip(r.sigma, r.units))
            ]
        )
    widths = [max(len(h), *(len(b[i]) for b in body)) for i, h in enumerate(heads)]
    out = ["  ".join(h.rjust(w) for h, w in zip(heads, widths))]
    out += ["  ".join(c.rjust(w) for c, w in zip(b, widths)) for b in body]
    n_shown = min(len(rows), limit or len(rows))
    failed = [r for r in rows if r.status != "ok"]
    out.append(
        f"{n_shown} of {len(rows)} plans shown (score: geometric mean of σ / best σ over the "
        "targets; 1 = best at every target; * = set by the a priori: the data alone cannot "
        "separate the element; '—' = not in the plan's state)"
    )
    if failed:
        out.append(f"{len(failed)} plans could not be predicted, e.g. {failed[0].plan_id}: {failed[0].status}")
    return out


def budget_lines(rows: Sequence[PlanRow], top: int = 3) -> list[str]:
    """The error budget (noise only and each consider element) of the ``top`` best plans."""
    out = []
    for rank, (_, r) in enumerate(ranked(rows)[:top], start=1):
        if r.status != "ok":
            break
        out.append(f"plan {rank}: {r.plan_id}")
        for i, (n, u) in enumerate(zip(r.elements, r.units)):
            if n in ATTITUDE_NAMES:
                continue
            shown, unit = element_unit(u, r.sigma[i])
            parts = [f"noise {_cell(r.noise_only[i], u, shown=shown)}"]
            parts += [
                f"{c} {_cell(v[i], u, shown=shown)}"
                for c, v in sorted(r.budget.items(), key=lambda kv: -kv[1][i])
                if v[i] > 0
            ]
            out.append(f"  {n:<18} σ {_cell(r.sigma[i], u, shown=shown):>8} {unit:<4} = " + " ⊕ ".join(parts))
        if r.undetermined:
            out.append("  not determined by this plan: " + ", ".join(r.undetermined))
    return out
