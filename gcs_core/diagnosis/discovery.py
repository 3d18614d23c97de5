"""Discovery: fit, rank the candidate effects, add the most significant identifiable one,
refit, until none passes the family-wise level (seed §3.3, the add/refit loop).

The loop drives a session (:class:`gcs_core.session.Analysis`: ``fit``, ``rank``,
``add_effect``, ``goodness``) and records each change as a :class:`Step`; which of a group
of aliased candidates is added is :func:`gcs_core.diagnosis.policy.parsimonious`.
"""

from __future__ import annotations

import logging
import math
from collections.abc import Callable, Mapping
from dataclasses import dataclass, field

from gcs_core.diagnosis import blame, policy
from gcs_core.diagnosis import search as search_session
from gcs_core.display import p_text

log = logging.getLogger(__name__)


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


def discover(analysis, *, max_steps: int = 10, progress: Callable[[str], None] | None = None) -> str:
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
    search = getattr(analysis, "structure", None)
    for _ in range(max_steps):
        cands = analysis.rank()
        report = None
        if search is not None:
            # what the misfit sensors' residuals follow; its families become candidates
            before = analysis.problem
            report = search(offer=True)
            if analysis.problem is not before:
                cands = analysis.rank()
            if not search_session.trusted(analysis):
                report = None  # reported, not acted on (search.trusted)
        ok = [c for c in cands if c.identifiable and c.p_adjusted < alpha]
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
        n_meas = sum(r.n * len(r.components) for r in analysis.result.residuals.values())
        pick = blame.choose(ok, report, n_meas)
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
    if search is not None:
        search()  # what the residuals that remain follow, for the report
    g = analysis.goodness()
    if g is not None:
        # a converged fit of an inadequate model must not read as success
        reason += "; what remains: " + g.verdict
    say(reason)
    return reason
