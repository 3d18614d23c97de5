"""The cheapest data plan that meets σ targets within a budget (seed §1.1 (1), (4), (5)).

Targets are ``ELEMENT<SIGMA`` with a unit: ``TAM1.alignment<0.01deg`` (every element of
the effect), ``FHST1.align_1<10arcsec``, ``TAM1.bias_x<1nT``, ``IRU.G_11<20ppm``,
``attitude<5arcsec``. The budget bounds the plan space: at most ``slew_min`` minutes of
slewing, at most ``hours`` of data, maneuvers only about the allowed ``axes`` at the
allowed ``rates``.

Plan space. Spans from :data:`SPANS_H` up to the budget; no maneuver, or a sequence of
one maneuver per allowed axis (one axis, or two, in the order given), each
:data:`SLEW_MINUTES` long at an allowed rate, flown back to back and centred in the span;
the same data split into ``passes`` passes (2 or more, budget ``passes``) separated by
:data:`SEPARATIONS_MIN`; and, where the operator controls it (budget ``starts``), the
start phase in the orbit [min from the plan's start]. What the search did not control
(the start phase when ``starts`` is not given) is reported afterwards
(:mod:`gcs_core.trade.robustness`): the chosen plan's σ over the orbit.
A plan meets a target when its predicted σ is below the limit by the margin
(:data:`MARGIN`, the accuracy the predictor is held to against Monte Carlo), so the
flown plan still meets it if the true σ is that much above the prediction. Cost is
lexicographic: the fewest minutes of slewing first (the operationally expensive
part, seed §2.1.2: "performing slew maneuvers during the early phase of the mission may
not be permissible"), then the fewest hours of data. The plans are predicted cheapest
first (serially, stopping at the first that meets every target; on Dask all at once).

Why it works. For the chosen plan each target element's σ is recomputed with one source
of data taken away at a time: each observing sensor switched off, each maneuver left out.
The factor by which σ grows says which data determine which element.
"""

from __future__ import annotations

import itertools
import math
import re
from collections.abc import Callable, Mapping, Sequence
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

from gcs_core.config_checks import AXES
from gcs_core.config_schema import AnalysisConfig, Maneuver
from gcs_core.errors import InputError
from gcs_core.trade import engine, space
from gcs_core.trade.report import element_unit, in_unit
from gcs_core.trade.study import PlanRow, StudyDefinition, evaluate_plans, target_elements
from gcs_core.units import ARCSEC, DEG

SPANS_H = (0.25, 0.5, 0.75, 1.0, 1.5, 2.0, 3.0, 4.0, 6.0)
#: gaps between passes of a split plan [min]
SEPARATIONS_MIN = (15.0, 30.0, 45.0)
SLEW_MINUTES = (1.0, 2.0, 3.0, 5.0, 7.5, 10.0, 15.0, 20.0, 30.0)
DEFAULT_RATES = (0.05, 0.1, 0.2)
#: a target is met when σ·(1 + MARGIN) is below its limit
MARGIN = 0.15
#: unit suffix -> factor to the internal unit
UNITS = {
    "deg": DEG,
    "°": DEG,
    "arcsec": ARCSEC,
    "″": ARCSEC,
    "rad": 1.0,
    "nT": 1.0,
    "ppm": 1e-6,
    "deg/h": DEG / 3600.0,
    "": 1.0,
    "1": 1.0,
}
_TARGET = re.compile(r"^\s*([A-Za-z][\w.\-]*)\s*<\s*([0-9.eE+\-]+)\s*([^\s]*)\s*$")


@dataclass(frozen=True)
class Target:
    """``σ(element) < limit`` (internal units) for every element of ``name``."""

    name: str
    limit: float
    text: str


def parse_target(text: str) -> Target:
    m = _TARGET.match(str(text))
    if not m:
        raise InputError(
            f"a target is ELEMENT<SIGMA[unit], e.g. TAM1.alignment<0.01deg, not {text!r}", key="trade.optimize.targets"
        )
    unit = m.group(3)
    if unit not in UNITS:
        raise InputError(
            f"unknown unit {unit!r} (known: {', '.join(u for u in UNITS if u)})", key="trade.optimize.targets"
        )
    value = float(m.group(2))
    if not value > 0:
        raise InputError(f"a σ limit must be > 0, not {value}", key="trade.optimize.targets")
    return Target(m.group(1), value * UNITS[unit], text.strip())


@dataclass(frozen=True)
class Budget:
    """The plan space allowed (module docstring)."""

    slew_min: float = 0.0
    hours: float = 2.0
    axes: tuple[str, ...] = AXES
    rates: tuple[float, ...] = DEFAULT_RATES
    #: start phases the operator can choose [min from the plan's start]; () = not controlled
    starts: tuple[float, ...] = ()
    #: numbers of passes the data may be split into (1 = one continuous pass)
    passes: tuple[int, ...] = (1,)
    #: sensor -> the most minutes of data it may deliver (a per-sensor window, placed at
    #: the start, the middle or the end of the plan by the search)
    windows: Mapping[str, float] = field(default_factory=dict)

    @classmethod
    def from_mapping(
        cls,
        d: Mapping[str, Any],
        *,
        slew_min=None,
        hours=None,
        axes=None,
        rates=None,
        starts=None,
        passes=None,
        windows=None,
    ) -> Budget:
        b = cls()
        d = dict(d)
        if windows is not None:  # "FHST2=10,FSS1=20" from the command line
            pairs = [w.split("=", 1) for w in windows.split(",")] if isinstance(windows, str) else windows.items()
            if any(len(p) != 2 for p in pairs):
                raise InputError("--windows takes SENSOR=MINUTES[,SENSOR=MINUTES]", key="trade.optimize.budget.windows")
            d["windows"] = {str(k).strip(): v for k, v in pairs}
        for key, v in (("starts", starts), ("passes", passes)):
            if v is not None:
                d[key] = v.split(",") if isinstance(v, str) else v
        sm = slew_min if slew_min is not None else d.get("slew_min", b.slew_min)
        hr = hours if hours is not None else d.get("hours", b.hours)
        ax = axes if axes is not None else d.get("axes", b.axes)
        rt = rates if rates is not None else d.get("rates", b.rates)
        ax = tuple(a.strip() for a in (ax.split(",") if isinstance(ax, str) else ax) if str(a).strip())
        try:
            rt = tuple(float(r) for r in (rt.split(",") if isinstance(rt, str) else rt))
        except ValueError:
            raise InputError(f"rates must be numbers [deg/s], not {rt!r}", key="trade.optimize.budget.rates") from None
        if any(a not in AXES for a in ax):
            raise InputError(f"axes must be among {', '.join(AXES)}, not {ax!r}", key="trade.optimize.budget.axes")
        if not (float(sm) >= 0 and float(hr) > 0) or any(r == 0 for r in rt):
            raise InputError("slew_min ≥ 0, hours > 0 and rates ≠ 0 are needed", key="trade.optimize.budget")
        try:
            st = tuple(float(x) for x in d.get("starts", ()))
            ps = tuple(int(x) for x in d.get("passes", (1,)))
            wn = {str(k): float(v) for k, v in dict(d.get("windows", {})).items()}
        except (TypeError, ValueError):
            raise InputError(
                "starts [min], passes and windows {SENSOR = minutes} must be numbers", key="trade.optimize.budget"
            ) from None
        if any(p < 1 for p in ps) or any(x < 0 for x in st) or any(not w > 0 for w in wn.values()):
            raise InputError("passes ≥ 1, starts ≥ 0 and windows > 0 are needed", key="trade.optimize.budget")
        return cls(float(sm), float(hr), ax, rt, st, ps or (1,), wn)


def candidates(budget: Budget) -> list[dict[str, Any]]:
    """Every plan of the space (module docstring), cheapest first."""
    spans = [h for h in SPANS_H if h <= budget.hours + 1e-9] or [budget.hours]
    seqs: list[tuple[float, str]] = [(0.0, "none")]
    if budget.slew_min > 0:
        for k in (1, 2):
            for axes in itertools.permutations(budget.axes, k):
                for rate in budget.rates:
                    for minutes in SLEW_MINUTES:
                        total = k * minutes
                        if total <= budget.slew_min + 1e-9:
                            seqs.append((total, ",".join(f"{a}:{rate:g}:{minutes:g}" for a in axes)))
    out = []
    for (slew, seq), h in itertools.product(seqs, spans):
        if slew > 60.0 * h:
            continue
        for n in budget.passes:
            if n == 1:
                shapes: list[dict[str, Any]] = [{"span_min": 60.0 * h}]
            else:
                pass_min = 60.0 * h / n
                if slew > pass_min:  # the slews fly inside one pass
                    continue
                shapes = [{"passes": n, "pass_min": pass_min, "separation_min": sep} for sep in SEPARATIONS_MIN]
            for shape in shapes:
                for start in budget.starts or (None,):
                    c = {**shape, "maneuvers": seq}
                    if start is not None:
                        c["start_min"] = start
                    out.extend(_windowed(c, budget.windows))
    out.sort(key=lambda c: (_slew(c), _data_min(c), c.get("passes", 1), c["maneuvers"], c.get("start_min", 0.0)))
    return out


#: where a sensor's window goes in the plan: at its start, its middle, its end
WINDOW_PLACES = (0.0, 0.5, 1.0)


def _windowed(c: dict[str, Any], windows: Mapping[str, float]) -> list[dict[str, Any]]:
    """``c`` with every placement of each windowed sensor's data (budget ``windows``)."""
    out = [c]
    span = _data_min(c) if "span_min" in c else c["passes"] * c["pass_min"] + (c["passes"] - 1) * c["separation_min"]
    for name, minutes in windows.items():
        if minutes >= span:
            continue
        placed = []
        for x in out:
            for f in WINDOW_PLACES:
                a = f * (span - minutes)
                placed.append({**x, f"{name}.window_min": f"{a:g}:{a + minutes:g}"})
        out = placed
    return out


def _data_min(c) -> float:
    return c["span_min"] if "span_min" in c else c["passes"] * c["pass_min"]


def _slew(c) -> float:
    return sum(m for _, _, m in space.parse_maneuvers(c["maneuvers"]))


@dataclass
class OptimizeResult:
    """The cheapest plan meeting the targets (None if none within the budget)."""

    targets: list[Target]
    budget: Budget
    searched: int
    margin: float
    best: PlanRow | None
    config: AnalysisConfig | None
    closest: PlanRow | None = None
    why: list[str] = field(default_factory=list)
    elements: dict[str, list[str]] = field(default_factory=dict)

    def lines(self) -> list[str]:
        out = [
            "targets: " + ", ".join(t.text for t in self.targets),
            f"budget: ≤ {self.budget.slew_min:g} min of slewing, ≤ {self.budget.hours:g} h of data, "
            f"axes {','.join(self.budget.axes)}, rates {','.join(f'{r:g}' for r in self.budget.rates)} deg/s, "
            f"passes {','.join(str(p) for p in self.budget.passes)}, start "
            + (f"{','.join(f'{x:g}' for x in self.budget.starts)} min" if self.budget.starts else "not controlled")
            + "".join(f", {k} ≤ {v:g} min of data" for k, v in self.budget.windows.items()),
            f"{self.searched} plans predicted",
        ]
        row = self.best
        if row is None:
            out.append("no plan within the budget meets every target")
            row = self.closest
            if row is None:
                return out
            out.append(f"closest: {row.plan_id}")
        else:
            out.append(f"cheapest plan: {row.slew_min():g} min of slewing, {row.data_h():g} h of data ({row.plan_id})")
            for m in row.description.get("maneuvers", ()):
                out.append(
                    f"  maneuver: {m['axis']} at {m['rate_deg_s']:g} deg/s from t = {m['start']:g} s "
                    f"for {m['duration']:g} s ({m['rate_deg_s'] * m['duration']:+g}°)"
                )
        for t in self.targets:
            for n in self.elements.get(t.name, []):
                i = row.elements.index(n)
                shown, u = element_unit(row.units[i], row.sigma[i])
                s, lim = in_unit(row.sigma[i], row.units[i], shown), in_unit(t.limit, row.units[i], shown)
                ok = row.sigma[i] * (1.0 + self.margin) < t.limit
                out.append(
                    f"  σ {n:<16} {s:10.4g} {u:<3} (target < {lim:g} with a "
                    f"{100 * self.margin:g} % margin) {'met' if ok else 'NOT met'}"
                )
        out += self.why
        return out


def _meets(row: PlanRow, targets: Sequence[Target], elements: Mapping[str, list[str]], margin: float = MARGIN) -> bool:
    if row.status != "ok":
        return False
    for t in targets:
        for n in elements[t.name]:
            s = row.sigma_of(n)
            if not (math.isfinite(s) and s * (1.0 + margin) < t.limit):
                return False
    return True


def _shortfall(row: PlanRow, targets, elements) -> float:
    if row.status != "ok":
        return math.inf
    worst = 0.0
    for t in targets:
        for n in elements[t.name]:
            s = row.sigma_of(n)
            worst = max(worst, s / t.limit if math.isfinite(s) else math.inf)
    return worst


def optimize(
    cfg: AnalysisConfig,
    targets: Sequence[Target],
    budget: Budget,
    *,
    method: str | None = None,
    margin: float = MARGIN,
    workers: int | None = None,
    scheduler: str | None = None,
    progress: Callable[[int, int], None] | None = None,
) -> OptimizeResult:
    """Search the plan space (module docstring)."""
    from gcs_core.predictor.source import load_source

    if cfg.path is None:
        raise InputError("the optimizer needs its analysis config on disk", key="trade")
    src = load_source(cfg, method=method)  # read once here, shipped to any worker
    spec = src.spec
    elements = {t.name: list(target_elements([t.name], spec)[0]) for t in targets}
    names = tuple(dict.fromkeys(n for t in targets for n in elements[t.name]))
    cands = candidates(budget)
    defn = StudyDefinition(
        str(Path(cfg.path).resolve()),
        {"span_min": (), "maneuvers": ()},
        names,
        cfg.trade.get("orbit"),
        method,
        source=src,
    )
    items = list(enumerate(cands))
    rows: list[PlanRow] = []
    if workers or scheduler:
        engine.run_jobs(
            evaluate_plans, defn, items, on_batch=rows.extend, workers=workers, scheduler=scheduler, progress=progress
        )
        rows.sort(key=lambda r: r.index)
    else:
        for k, item in enumerate(items):
            rows.extend(evaluate_plans(defn, [item]))
            if progress:
                progress(k + 1, len(items))
            if _meets(rows[-1], targets, elements, margin):
                break
    best = next((r for r in rows if _meets(r, targets, elements, margin)), None)
    ok = [r for r in rows if r.status == "ok"]
    if not ok and rows:
        raise InputError(f"no plan could be predicted: {rows[0].status}", key="trade.optimize")
    closest = None if best is not None else min(ok, key=lambda r: _shortfall(r, targets, elements), default=None)
    res = OptimizeResult(list(targets), budget, len(rows), margin, best, None, closest, elements=elements)
    chosen = best or closest
    if chosen is not None:
        res.config = plan_config(cfg, chosen)
        res.why = why_lines(defn, chosen, spec)
        if not budget.starts:
            from gcs_core.trade.robustness import start_phase_lines

            res.why += start_phase_lines(defn, chosen, targets, elements, margin)
    return res


def plan_config(cfg: AnalysisConfig, row: PlanRow) -> AnalysisConfig:
    """The analysis config flying ``row``'s plan (``[prediction]`` span and maneuvers)."""
    d = row.description
    mans = tuple(Maneuver(m["start"], m["duration"], m["axis"], m["rate_deg_s"]) for m in d.get("maneuvers", ()))
    return cfg.with_changes(
        prediction={
            "start": d["start"],
            "end": d["end"],
            "gaps": tuple(tuple(g) for g in d.get("gaps", ())),
            "maneuvers": mans,
        },
        name=f"optimized plan: {row.plan_id}",
    )


def why_lines(defn: StudyDefinition, row: PlanRow, spec) -> list[str]:
    """Which data determine which target (module docstring: leave one source out)."""
    combo = dict(row.values)
    variants: list[tuple[str, dict]] = []
    on = [s for s, v in row.description.get("sensors", {}).items() if v.get("on") and v.get("type") != "gyro"]
    for s in on:
        variants.append((f"without {s}", {**combo, f"models.{s}": "off"}))
    seq = space.parse_maneuvers(combo.get("maneuvers", "none"))
    for k in range(len(seq)):
        rest = [m for j, m in enumerate(seq) if j != k]
        variants.append(
            (
                f"without the {seq[k][0]} maneuver",
                {**combo, "maneuvers": ",".join(f"{a}:{r:g}:{m:g}" for a, r, m in rest) or "none"},
            )
        )
    if not variants:
        return []
    rows = evaluate_plans(defn, list(enumerate(c for _, c in variants)))
    out = ["why it works (σ with one source of data taken away, × the plan's σ):"]
    for n, base in zip(row.elements, row.sigma):
        parts = []
        for (label, _), r in zip(variants, rows):
            s = r.sigma_of(n) if r.status == "ok" else math.nan
            if math.isnan(s):
                continue  # its own sensor: nothing to say
            limited = bool(r.prior_limited) and r.prior_limited[r.elements.index(n)]
            if math.isinf(s) or limited:
                parts.append(f"{label}: not determined (σ = a priori)")
            else:
                parts.append(f"{label}: ×{s / base:.3g}")
        out.append(f"  {n:<16} " + "; ".join(parts))
    return out
