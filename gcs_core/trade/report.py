"""Text tables of trade studies: the ranked plans and the error budget of the best ones."""

from __future__ import annotations

import math
from collections.abc import Sequence

from gcs_core.trade.study import ATTITUDE_NAMES, PlanRow, ranked
from gcs_core.units import ARCSEC


def sigma_display(value: float, unit: str) -> tuple[float, str]:
    """A σ in the unit an analyst reads: rad → arcsec, rad/s → deg/h, dimensionless → ppm,
    others as they are."""
    if unit == "rad":
        return value / ARCSEC, "″"
    if unit == "rad/s":
        return value * 180.0 / math.pi * 3600.0, "°/h"
    if unit == "1":
        return value * 1e6, "ppm"
    return value, unit


def _cell(v: float, unit: str, prior: bool = False) -> str:
    if math.isnan(v):
        return "—"
    if math.isinf(v):
        return "undet."
    x, _ = sigma_display(v, unit)
    return f"{x:.3g}" + ("*" if prior else "")


def _short(name: str) -> str:
    return name.replace("attitude.", "att.")


def study_table(rows: Sequence[PlanRow], *, limit: int | None = 20) -> list[str]:
    """The plans ranked best first: score, varied values, σ of every target element."""
    if not rows:
        return ["no plans"]
    r0 = next((r for r in rows if r.status == "ok"), rows[0])
    keys = list(r0.values)
    heads = (
        ["#", "score"] + keys + [f"σ {_short(n)} [{sigma_display(1.0, u)[1]}]" for n, u in zip(r0.elements, r0.units)]
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
                _cell(v, u, bool(r.prior_limited and r.prior_limited[i]))
                for i, (v, u) in enumerate(zip(r.sigma, r.units))
            ]
        )
    widths = [max(len(h), *(len(b[i]) for b in body)) for i, h in enumerate(heads)]
    out = ["  ".join(h.rjust(w) for h, w in zip(heads, widths))]
    out += ["  ".join(c.rjust(w) for c, w in zip(b, widths)) for b in body]
    shown = min(len(rows), limit or len(rows))
    failed = [r for r in rows if r.status != "ok"]
    out.append(
        f"{shown} of {len(rows)} plans shown (score: geometric mean of σ / best σ over the "
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
            _, unit = sigma_display(1.0, u)
            parts = [f"noise {_cell(r.noise_only[i], u)}"]
            parts += [
                f"{c} {_cell(v[i], u)}" for c, v in sorted(r.budget.items(), key=lambda kv: -kv[1][i]) if v[i] > 0
            ]
            out.append(f"  {n:<18} σ {_cell(r.sigma[i], u):>8} {unit:<4} = " + " ⊕ ".join(parts))
        if r.undetermined:
            out.append("  not determined by this plan: " + ", ".join(r.undetermined))
    return out
