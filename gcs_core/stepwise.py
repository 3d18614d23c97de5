"""Stepwise discovery: fit, rank the candidate effects, add the most significant
identifiable one, refit, until none passes the family-wise level (seed §3.3, the add/refit
loop).

The loop drives a session (:class:`gcs_core.session.Analysis`: ``fit``, ``rank``,
``add_effect``, ``goodness``) from the session's own level: the diagnosis below it scores
and judges the candidates (each :class:`~gcs_core.diagnosis.ranking.Candidate` carries its
verdict, ``passes``), and each change is recorded as a
:class:`~gcs_core.diagnosis.discovery.Step`. Which of a group of aliased candidates is added
is :func:`gcs_core.diagnosis.policy.parsimonious`.
"""

from __future__ import annotations

import logging
from collections.abc import Callable
from typing import TYPE_CHECKING

from gcs_core.diagnosis import alternative, blame, leave_out, policy
from gcs_core.diagnosis import search as search_session
from gcs_core.display import p_text

if TYPE_CHECKING:  # the session calls this loop; the loop only reads the session
    from gcs_core.diagnosis.structure import StructureReport
    from gcs_core.session import Analysis

log = logging.getLogger(__name__)


def discover(analysis: Analysis, *, max_steps: int = 10, progress: Callable[[str], None] | None = None) -> str:
    """Stepwise: add the most significant identifiable candidate while one passes the
    Bonferroni-corrected level ``diagnosis.significance``; returns why it stopped (with
    the goodness-of-fit verdict of what remains). ``analysis.steps`` gets one
    :class:`Step` per effect added."""
    say = progress or (lambda msg: log.info(msg))
    alpha = analysis.config.diagnosis.significance
    if analysis.result is None:
        analysis.fit()
    if not analysis.steps:
        analysis.first_step()
    search = analysis.structure
    for _ in range(max_steps):
        cands = analysis.rank()
        # what the misfit sensors' residuals follow; its families become candidates
        before = analysis.problem
        report: StructureReport | None = search(offer=True)
        if analysis.problem is not before:
            cands = analysis.rank()
        if not search_session.trusted(analysis):
            report = None  # reported, not acted on (search.trusted)
        # the most significant candidate absorbed at weights its own misfit set (diagnosis/alternative.py)
        again = alternative.recheck(analysis, cands)
        if again is not None:
            cands = again
        ok = [c for c in cands if c.passes]
        if not ok:
            best = cands[0] if cands else None
            reason = f"no candidate is significant at family-wise α = {alpha:g}" + (
                f" (best: {best.id}, {p_text(best.p_adjusted, 'p adj')}"
                + ("" if best.identifiable else ", not identifiable")
                + ")"
                if best
                else ""
            )
            break
        fitted = analysis.result
        assert fitted is not None  # rank() fitted
        n_meas = sum(int(r.n) * len(r.components) for r in fitted.residuals.values())
        pick, suspects = _choose_checked(analysis, ok, report, n_meas, say)
        if pick is None:
            reason = (
                "no candidate is significant but through the unexplained misfit of "
                + ", ".join(sorted(suspects))
                + f" (family-wise α = {alpha:g})"
            )
            break
        top = policy.parsimonious(pick, cands, analysis.result, analysis.problem.state, alpha)
        top = blame.prefer_misfit(top, cands, report, alpha)
        say(
            f"adding {top.id} (Δχ² = {top.delta_chi2:.1f}, dof {top.dof}, {p_text(top.p_value)}, "
            f"{p_text(top.p_adjusted, 'p adj')}; {blame.blame_text(top)})"
        )
        analysis.add_effect(top.id)
    else:
        reason = f"stopped after {max_steps} steps"
    analysis.rank()
    search()  # what the residuals that remain follow, for the report
    g = analysis.goodness()
    if g is not None:
        # a converged fit of an inadequate model must not read as success
        reason += "; what remains: " + g.verdict
    say(reason)
    return reason


def _choose_checked(analysis: Analysis, ok: list, report, n_meas: int, say) -> tuple:
    """``(candidate to add or None, suspects)``: :func:`blame.choose`, then rule 4 of
    :mod:`gcs_core.diagnosis.blame`: a candidate on a sensor within its noise, while a
    misfit no candidate explains is in the data, must still pass with that sensor left out
    (:func:`gcs_core.diagnosis.leave_out.passes_without`), else the next is chosen."""
    pick = blame.choose(ok, report, n_meas)
    suspects = blame.unexplained_misfits(report, ok) - {pick.effect.sensor}
    while suspects and blame.within_noise(pick, report):
        if leave_out.passes_without(analysis, suspects, pick.id):
            break
        say(f"not adding {pick.id}: significant only through {', '.join(sorted(suspects))} (left out, it is not)")
        ok = [c for c in ok if c.id != pick.id]
        if not ok:
            return None, suspects
        pick = blame.choose(ok, report, n_meas)
        suspects = blame.unexplained_misfits(report, ok) - {pick.effect.sensor}
    return pick, suspects
