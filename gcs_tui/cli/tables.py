"""The plain-text tables of the ``gcs`` command: fit, state, candidates, steps, import,
effects, prediction and what remains.

Numbers are shown with honest precision by the one rule of :mod:`gcs_core.display` (the
unit chosen from σ, σ's two significant digits), the rule the TUI uses too. Every table
is a list of lines, so that the command and the tests print or compare them alike.
"""

from __future__ import annotations

import math
import textwrap
from collections.abc import Iterable
from pathlib import Path

import numpy as np

from gcs_core import display
from gcs_core.noise import correlated as noise_correlation
from gcs_core.reporting import remaining_summary

#: what "unobservable" means, said once under the list
UNOBSERVABLE_NOTE = (
    "(unobservable: the data constrain only the combination named; each element's σ "
    "there comes from its a priori, not from the data)"
)


def fit_table(analysis) -> list[str]:
    """Per sensor: frames used and edited, normalized RMS fitted and held-out, the χ²
    test's p on the fitted and held-out span (:mod:`gcs_core.diagnosis.goodness`), RMS per
    component; then the status and the goodness-of-fit verdict."""
    res = analysis.result
    gof = analysis.goodness() if hasattr(analysis, "goodness") else None
    lines = [
        f"{'sensor':10s} {'n':>7s} {'edited':>6s} {'norm. RMS':>9s} {'held-out':>9s} "
        f"{'p fit':>8s} {'p held':>8s}  RMS per component"
    ]
    for name, r in res.residuals.items():
        rms = np.atleast_1d(np.asarray(r.rms, dtype=float))
        finite = rms[np.isfinite(rms)]  # all NaN (every frame edited): no "All-NaN slice" warning
        shown = display.display_unit(r.unit, float(np.max(finite)) if finite.size else float("nan"))
        comp = ", ".join(
            f"{c} {display.quantity(v, r.unit, shown=shown, with_unit=False)}" for c, v in zip(r.components, rms)
        )
        ho = analysis.holdout_rms.get(name, float("nan"))
        lab = display.unit_label(shown)
        p_fit = _p_cell(gof.sensors.get(name) if gof else None, gof)
        p_ho = _p_cell(gof.holdout_sensors.get(name) if gof else None, gof)
        lines.append(
            f"{name:10s} {r.n:7d} {int(np.count_nonzero(r.edited)):6d} {r.rms_normalized:9.3f} "
            f"{ho:9.3f} {p_fit:>8s} {p_ho:>8s}  {comp}" + (f" [{lab}]" if lab else "")
        )
    lines.append(f"status: {res.message}; χ² {res.chi2:.1f} on {res.dof} dof")
    nw = getattr(analysis, "noise", None)
    if nw is not None and (nw.mode != "correlated" or any(f.factor != 1.0 for f in nw.factors.values())):
        lines.append(nw.summary())  # (correlated and all white: the correlation lines say so)
    carried = getattr(getattr(analysis, "config", None), "filter", None)
    carried = getattr(carried, "noise_weighting", "") == "correlated"
    lines.extend(noise_correlation.lines(getattr(analysis, "correlation", None) or {}, carried))
    if gof is not None:
        lines.append(f"goodness of fit: {gof.verdict}")
        lines.append(
            f"  (p: χ² upper tail on the effective dof, {gof.effective_parameters:.1f} effective "
            f"parameters; ! marks p below the per-test level {gof.level:.2g})"
        )
    for u in res.unobservable:
        lines.append(f"unobservable from the data: {u}")
    if res.unobservable:
        lines.append(UNOBSERVABLE_NOTE)
    if hasattr(analysis, "null_at_prior"):
        listed = set(res.unobservable)
        sigma = res.sigma
        for u in analysis.null_at_prior():
            if u in listed:
                continue
            # an element reached only through a quantity whose a priori is 0 (an unknown
            # field, an amplitude) is null there; say when the fit determined it anyway
            name = u.split(" (no data", 1)[0]
            el = analysis.problem.state[name] if name in sigma else None
            done = el is not None and el.sigma0 > 0 and sigma[name] < 0.5 * el.sigma0
            lines.append(
                f"not determined at the a-priori linearization: {u}" + ("; determined at the solution" if done else "")
            )
    return lines


def _p_cell(test, gof) -> str:
    """A p-value cell: two significant digits, ``!`` where it fails the per-test level."""
    if test is None or not math.isfinite(test.p_value):
        return "-"
    mark = "!" if test.p_value < gof.level else ""
    return (f"{test.p_value:.2g}" if test.p_value >= 1e-99 else "<1e-99") + mark


def state_table(analysis) -> list[str]:
    res = analysis.result
    sig = res.sigma
    loose = analysis.not_determined() if hasattr(analysis, "not_determined") else {}
    prior = analysis.set_by_prior() if hasattr(analysis, "set_by_prior") else {}
    lines = [f"{'element':28s} {'role':10s} estimate"]
    for e in res.state:
        if e.role == "held":
            continue
        note = (
            "   (not determined by the data)"
            if e.name in loose
            else "   (set by the a priori)"
            if e.name in prior
            else ""
        )
        lines.append(f"{e.name:28s} {e.role:10s} {display.estimate(e.value, sig.get(e.name, e.sigma0), e.unit)}{note}")
    for name, why in loose.items():
        lines.append(f"{name}: {why}")
    if prior:
        idx = {n: i for i, n in enumerate(res.solve_for)}
        ratio = {n: math.sqrt(res.P[idx[n], idx[n]]) / res.state[n].sigma0 for n in prior if n in idx}
        shown = [f"{n} {ratio[n]:.2f}" for n in prior if n not in loose and n in ratio]
        if shown:
            lines.append(
                "set by the a priori (the data give less information than the a priori; "
                "posterior σ / a-priori σ): " + ", ".join(shown)
            )
    return lines + sigma_scale_lines(analysis, skip=set(loose) | set(prior))


#: the first words of the correlation-robust σ block
HEADER_SIGMA_SCALE = "σ with the residuals' correlation"
#: what the correlation-robust σ block means, said once under it
SIGMA_SCALE_NOTE = (
    "(the residuals carry less information than the fit's σ assume: correlated within the "
    "windows, or larger than the stated noise; these elements are less certain than their σ "
    "above by the scale shown; not listed: scales up to {limit:.2f}, within their sampling "
    "error of 1, and elements the a priori set)"
)


def sigma_scale_lines(analysis, skip: Iterable[str] = ()) -> list[str]:
    """The elements whose batch-means sandwich σ scale clearly exceeds 1
    (:mod:`gcs_core.diagnosis.honest_sigma`), with the σ that counts the residuals'
    correlation; nothing when none does (white residuals) or the scale was not estimated.
    ``skip``: elements not listed (those the data did not determine: their σ is the a priori's)."""
    from gcs_core.diagnosis.honest_sigma import flagged, frames_per_window, threshold

    sc = analysis.sigma_scale() if hasattr(analysis, "sigma_scale") else None
    big = {n: s for n, s in flagged(sc).items() if n not in set(skip)}
    failed = (
        [f"σ scale not estimable (the sandwich failed numerically, guarded): {', '.join(sc.failed)}"]
        if sc and sc.failed
        else []
    )
    if sc is None or not big:
        return failed
    res = analysis.result
    honest = sc.honest_sigma({n: res.sigma[n] for n in big})
    lines = [f"{HEADER_SIGMA_SCALE} (batch-means sandwich, {sc.block_s:.3g}-s windows, {sc.n_blocks} windows):"]
    # a gyro's elements fitted under its process noise (the whole-span knots): the sandwich
    # does not see that noise, so their scale is indicative (docs/ground.md)
    gyro = getattr(analysis.problem, "gyro_name", None) if res.carries_process_noise else None
    marked = {n for n in big if gyro is not None and res.state[n].sensor == gyro}
    for n, s in big.items():
        e = res.state[n]
        mark = "*" if n in marked else " "
        lines.append(f"  {n:26s} scale {s:5.2f}{mark}  {display.estimate(e.value, honest[n], e.unit)}")
    lines.extend(textwrap.wrap(SIGMA_SCALE_NOTE.format(limit=threshold(sc)), 100))
    if marked:
        lines.append("(* the gyro's, fitted under its process noise, which the sandwich does not see: indicative)")
    sparse = [n for n, v in frames_per_window(sc, res).items() if v < 2.0]
    lines.extend(failed)
    if sparse:
        text = (
            f"({', '.join(sparse)}: fewer than two samples per {sc.block_s:.3g}-s window, so its scales show "
            "residuals larger than the noise, not their correlation; a longer --sigma-window sees that)"
        )
        lines.extend(textwrap.wrap(text, 100))
    return lines


def prediction_table(res) -> list[str]:
    """The predicted 1-σ of every solve-for element at the end of the plan, the attitude
    1-σ and the usable frames per sensor (a :class:`~gcs_core.predictor.PredictionResult`)."""
    names = list(res.names)
    units = list(getattr(res, "units", [""] * len(names)))
    final = res.sigma[-1] if len(res.sigma) else [float("nan")] * len(names)
    lines = []
    plan = getattr(res, "plan", None)
    if plan is not None:
        lines.append(
            f"plan t = {plan.start:g} to {plan.end:g} s, {len(plan.gaps)} gap(s), "
            f"{len(plan.maneuvers)} maneuver(s); method {res.method}"
        )
    budget = dict(getattr(res, "budget", {}) or {})
    noise = getattr(res, "noise_only", None)
    lines.append(
        f"{'element':28s} predicted 1-sigma from the whole plan"
        + ("  (= noise ⊕ each consider element)" if budget else "")
    )
    undetermined = set(getattr(res, "undetermined", ()))
    for i, (n, u, s) in enumerate(zip(names, units, final)):
        note = "   not determined by the plan (the a priori)" if n in undetermined else ""
        if n.startswith("att."):
            note += "   (attitude at the reference epoch)"
        shown = display.display_unit(u, float(s))
        text = display.quantity(float(s), u, shown=shown)
        if budget and noise is not None:
            parts = [f"noise {display.quantity(float(noise[i]), u, shown=shown, with_unit=False)}"]
            parts += [
                f"{c} {display.quantity(float(v[i]), u, shown=shown, with_unit=False)}"
                for c, v in sorted(budget.items(), key=lambda kv: -float(kv[1][i]))
                if float(v[i]) > 0
            ]
            text += " = " + " ⊕ ".join(parts)
        lines.append(f"{n:28s} {text}{note}")
    att = getattr(res, "attitude_sigma", None)
    if att is not None and len(att):
        # three-axis: about the body axes; spinning: of the spin-axis unit vector (≈ angles)
        axes = ("roll", "pitch", "yaw") if "att.roll" in names else ("spin axis x", "spin axis y", "spin axis z")
        shown = display.display_unit("rad", float(np.nanmax(att[-1])))
        when = f" (t = {plan.end:g} s)" if plan is not None else ""
        lines.append(
            f"attitude 1-sigma at the end of the plan{when}: "
            + ", ".join(f"{ax} {display.quantity(float(v), 'rad', shown=shown)}" for ax, v in zip(axes, att[-1]))
        )
    frames = getattr(res, "frames", None)
    if frames:
        avail = getattr(res, "availability", {})
        lines.append(
            "usable frames: "
            + ", ".join(f"{k} {v}" + (f" ({100 * avail[k]:.0f}%)" if k in avail else "") for k, v in frames.items())
        )
    for u in getattr(res, "unobservable", ()):
        lines.append(f"unobservable from the plan: {u}")
    if getattr(res, "unobservable", ()):
        lines.append(UNOBSERVABLE_NOTE.replace("the data constrain", "the plan constrains"))
    return lines


def candidate_table(candidates: Iterable, *, alpha: float, limit: int | None = 10) -> list[str]:
    """Ranked candidate effects: Δχ², dof, p, Bonferroni-adjusted p, identifiable, and
    ``*`` where the adjusted p passes the family-wise level ``alpha`` (the ranking and
    significance rule of :data:`gcs_core.diagnosis.ranking.RULE`)."""
    from gcs_core.diagnosis.ranking import RULE

    cands = list(candidates)
    lines = [f"{'candidate':38s} {'Δχ²':>10s} {'dof':>3s} {'p':>9s} {'p adj':>9s}  identifiable"]
    for c in cands[:limit] if limit else cands:
        mark = " *" if c.passes else ""
        lines.append(
            f"{c.id:38s} {c.delta_chi2:10.1f} {c.dof:3d} {display.pvalue(c.p_value):>9s} "
            f"{display.pvalue(c.p_adjusted):>9s}  {'yes' if c.identifiable else 'no'}{mark}"
        )
    if limit and len(cands) > limit:
        lines.append(f"... {len(cands) - limit} more (all are in the JSON report)")
    n_fam = sum(1 for c in cands if "_vs_" in c.effect.effect)
    m = f"{len(cands) - n_fam}·p" + (f"; drift families counted apart, {n_fam}·p" if n_fam else "")
    lines.append(f"* significant and identifiable at family-wise α = {alpha:g}: p adj = min(1, {m}) < α")
    lines.append(RULE)
    return lines


def steps_table(steps: Iterable, *, min_change: float = 0.005) -> list[str]:
    """One line per effect added or removed: Δχ² and the normalized RMS of the sensors it
    moved by at least ``min_change`` (before → after, held-out after)."""
    lines = []
    for k, s in enumerate((s for s in steps if s.action in ("add", "remove")), start=1):
        moved = {n: (s.rms_before.get(n, float("nan")), v) for n, v in s.rms_after.items()}
        shown = {n: ba for n, ba in moved.items() if abs(ba[1] - ba[0]) >= min_change}
        if not shown and moved:
            n = max(moved, key=lambda n: abs(moved[n][1] - moved[n][0]) if math.isfinite(moved[n][0]) else 0.0)
            shown = {n: moved[n]}
        rms = ", ".join(
            f"{n} {b:.3f} → {a:.3f}" + (f" (held-out {s.holdout_after[n]:.3f})" if n in s.holdout_after else "")
            for n, (b, a) in shown.items()
        )
        verb = "added" if s.action == "add" else "removed"
        lines.append(f"{k:2d}. {verb} {s.effect}: Δχ² {s.delta_chi2:.1f}; normalized RMS {rms}")
    return lines


def import_table(mission) -> list[str]:
    """What an import read: rows kept and dropped per file, unknown keys and repairs
    (an :class:`~gcs_core.io.importer.ImportedMission`)."""
    spec, rep = mission.spec, mission.report
    root = Path(getattr(spec, "root", "."))
    lines = [
        f"mission {spec.name}: {len(spec.sensors)} sensors "
        f"({', '.join(f'{s.name} {s.type}' for s in spec.sensors)}), attitude mode {spec.attitude_mode}",
        "",
        f"{'file':34s} {'role':20s} {'rows kept':>9s} {'NaN dropped':>11s} {'duplicates':>10s}",
    ]
    for fc in rep.files:
        try:
            shown = Path(fc.file).relative_to(root).as_posix()
        except ValueError:
            shown = str(fc.file)
        lines.append(f"{shown:34s} {fc.what:20s} {fc.rows:9d} {fc.dropped_nan:11d} {fc.dropped_duplicates:10d}")
    lines.append(
        f"{'total':34s} {'':20s} {sum(f.rows for f in rep.files):9d} {rep.dropped_nan:11d} {rep.dropped_duplicates:10d}"
    )
    lines.append("")
    lines.append("unknown keys (kept, not used): " + (", ".join(rep.unknown_keys) or "none"))
    lines += [f"repair: {r}" for r in rep.repairs] or ["repairs: none"]
    lines += [f"warning: {w}" for w in getattr(rep, "warnings", ())]
    return lines


def effects_lines(effects: Iterable, in_state: Iterable[str], *, explain: bool = False, width: int = 100) -> list[str]:
    """A mission's catalogue: effect id, family, whether it is in the state, its elements."""
    in_state = set(in_state)
    lines = [f"{'effect id':38s} {'family':18s} {'in state':8s} elements"]
    for e in effects:
        elems = ", ".join(e.elements) if e.elements else "(physics option)"
        lines.append(
            f"{e.id:38s} {e.family:18s} {'yes' if e.id in in_state else 'no':8s} "
            + textwrap.shorten(elems, max(20, width - 67), placeholder=" ...")
        )
        if explain and e.explanation:
            lines += textwrap.wrap(e.explanation, width, initial_indent="    ", subsequent_indent="    ")
    return lines


def generic_effects_lines(rows: Iterable[tuple[str, str, str]], *, width: int = 100) -> list[str]:
    """The catalogue without a mission: ``<SENSOR>.<effect>`` or ``model.<effect>``,
    its family and what it looks like."""
    lines = []
    for name, family, text in rows:
        lines.append(f"model.{name}" if family == "physics" else f"<SENSOR>.{name}")
        lines += textwrap.wrap(f"[{family}] {text}", width, initial_indent="    ", subsequent_indent="    ")
    return lines


def remaining_lines(analysis) -> list[str]:
    """One line per sensor: what remains and whether it is consistent with the noise."""
    lines = []
    for name, d in remaining_summary(analysis).items():
        noise = d["noise"]
        # the unit of the tables (arcsec for a tracker's rad), one rule: gcs_core.display
        shown = display.display_unit(d["unit"], max(abs(d["rms"] or 0.0), abs(noise or 0.0)))
        k, lab = display.scale(d["unit"], shown), display.unit_label(shown)
        what = "estimated from the data" if d["noise_estimated"] else "of the data book"
        src = f" {noise * k:.4g} {lab} noise ({what})" if noise else " noise"
        verdict = (
            "consistent with the noise"
            if d["consistent_with_noise"]
            else f"not consistent with the noise (χ²/n = {d['chi2_per_measurement']:.3g}, "
            f"1 ± {d['consistency_bound']:.2g} expected): something is left unexplained"
        )
        lines.append(
            f"{name}: residual {d['rms'] * k:.4g} {lab} RMS, {d['rms_normalized']:.3g}× "
            f"the{src}, held-out {d['holdout_rms_normalized']:.3g}×; {verdict}"
        )
    return lines
