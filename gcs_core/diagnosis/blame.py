"""Blame the right sensor: which candidate discovery adds when several pass.

One sensor's unexplained error moves the fitted attitude, and the other sensors'
residuals then follow it: a perfect magnetometer's residual follows a temperature because
a bending tracker tilts the attitude with it. A candidate on the magnetometer may then be
significant, though the cause is the tracker. Two rules, applied to the candidates that
pass the family-wise level (:func:`choose`):

1. **Candidates on the channels the search found go first.** When the search found
   sensor Y's residual following a channel, Y's candidates of that form (its families on
   that channel or its aliases, or a catalogue effect of that form, a physics option
   included) are chosen before any other; among them, the one that explains most for its
   elements (:func:`choose`). A sensor's residual following the time integral of a
   switched aux channel is the form of the gyro's bias following the switch (the gyro
   carries the attitude and has no residuals of its own). Unless a sensor's own candidate (its Δχ² from its own
   residuals) explains clearly more than all of them: that sensor's error is then what
   moves the attitude the others follow.
2. **A candidate is not added on sensor X when its Δχ² comes mostly from another sensor
   Y's residuals** (the score's share, ``Candidate.sensors``, below :data:`OWN_SHARE`
   in X's own) while Y has a passing candidate whose Δχ² comes from Y itself: Y's
   explanation is the stronger one. Effects of sensors without residuals of their own
   (the gyro carrying the attitude) and physics effects are exempt.
3. **An unexplained misfit's own candidates first.** When a sensor exceeds its noise and its
   residual's strongest dependency has the form of no passing candidate (or the search found
   none), and no sensor exceeding its noise is explained, rule 1 chooses only
   among that sensor's candidates of the search's forms (and the gyro's and physics options,
   which have no residuals of their own), else among its own passing candidates (its
   alignment), when it has any: a tracker with an error no family holds (one
   following the star's magnitude) tilts the attitude slowly, and a Sun sensor within its
   noise then "follows time" too; the tracker's own drift family goes first, and the search
   runs again after it. A sensor merely exceeding its noise is not enough, nor a weaker
   dependency without a form (a Sun sensor whose held-out χ² exceeds, following the orbit
   through the attitude of a tracker tilting over the orbit, and weakly the angle turned).
4. **Left out, is it still there?** A candidate on a sensor within its noise, chosen while an
   unexplained misfit (rule 3) is in the data, is checked with that misfit's sensor left out
   of the fit (:mod:`gcs_core.diagnosis.leave_out`); if it no longer passes, it was
   significant only through that sensor's error, and it is not added (the loop chooses
   again without it). Run by :func:`gcs_core.stepwise.discover`.

:func:`blame_text` says for each candidate where its Δχ² comes from.
"""

from __future__ import annotations

import math
from collections.abc import Sequence

from gcs_core.diagnosis.families import channel_of
from gcs_core.diagnosis.policy import BIC_TIE
from gcs_core.diagnosis.ranking import Candidate, is_family
from gcs_core.diagnosis.structure import Dependency, StructureReport

#: share of a candidate's Δχ² its own sensor's residuals must give for it to stand alone
OWN_SHARE = 0.5
#: share of a family's Δχ² a catalogue effect of the same sensor must explain to go first
CATALOGUE_SHARE = 0.5


def own_share(c: Candidate) -> float | None:
    """Share of ``c``'s Δχ² from its own sensor's residuals; None when that sensor has none
    (a gyro, a physics option)."""
    s = c.effect.sensor
    if s is None or s not in c.sensors:  # a sensor with residuals scores its own effects
        return None
    return float(c.sensors[s])


def matches(c: Candidate, d: Dependency) -> bool:
    """``c`` has the form of dependency ``d``: a family on ``d``'s sensor made on its channel
    or one of its aliases, or a catalogue effect (a physics option included) of that form."""
    if c.id in d.catalogue:
        return True
    ch = channel_of(c.effect.effect)
    if ch is not None and d.kind == "aux_integral":
        # the integral of a switch in any sensor's residual: the gyro's bias following the
        # switch (a sensor without residuals of its own, carrying the attitude)
        return own_share(c) is None and d.channel == "int:" + ch.removeprefix("aux:")
    if ch is None or c.effect.sensor != d.sensor:
        return False
    chans = {d.channel, *d.aliases}
    return ch in chans or (ch == "orbit_phase" and bool(chans & {"sun_angle", "eclipse"}))


def choose(ok: Sequence[Candidate], report: StructureReport | None, n_meas: int = 2) -> Candidate:
    """The candidate to add among ``ok`` (passing, identifiable, most significant first):
    rules 1 and 2 of the module docstring, else the most significant. Rule 1 takes, among
    the passing candidates of the form of some finding of the search (each on its own
    sensor), the one with the best Bayesian information criterion ``Δχ² − dof·ln n``
    (``n`` measurements; Schwarz 1978): a Sun sensor's drifting offset that moves the
    attitude explains more than the trackers' families on the same channel, and a family of
    nine elements on a tracker whose residual follows the orbit does not win over a physics
    option of one element that explains it through the attitude. Within
    :data:`~gcs_core.diagnosis.policy.BIC_TIE` of the best, a catalogue effect wins."""
    log_n = math.log(max(n_meas, 2))
    found = report.found if report is not None else ()
    first = [c for c in ok if any(matches(c, d) for d in found)]
    misfit = unexplained_misfits(report, ok)
    if misfit:
        # rule 3: a sensor within its noise whose residual follows a channel only because a
        # misfit sensor's error moves the attitude comes after that sensor's own candidates
        on_misfit = [c for c in first if c.effect.sensor in misfit or own_share(c) is None]
        theirs = [c for c in ok if c.effect.sensor in misfit and (own_share(c) or 0.0) >= OWN_SHARE]
        first = on_misfit or theirs or first
    if first:
        bic = {c.id: c.delta_chi2 - c.dof * log_n for c in ok}
        best = max(bic[c.id] for c in first)
        # a sensor's own explanation that explains clearly more than anything of the search's
        # forms comes first: its error moves the attitude, and the other sensors' residuals
        # follow the orbit only through it (a Sun sensor's harmonic against the trackers'
        # orbit families)
        # (and a catalogue effect of its own that ties with them: known physics first)
        theirs_own = [
            c
            for c in ok
            if c not in first and (own_share(c) or 0.0) >= OWN_SHARE and (not misfit or c.effect.sensor in misfit)
        ]
        stronger = [
            c
            for c in theirs_own
            if bic[c.id] > best + BIC_TIE or (not is_family(c.effect) and bic[c.id] >= best - BIC_TIE)
        ]
        if stronger:
            return max(stronger, key=lambda c: bic[c.id])
        # within BIC_TIE the data give no preference: the catalogue's effect (known physics)
        pick = max(first, key=lambda c: (bic[c.id] >= best - BIC_TIE and not is_family(c.effect), bic[c.id]))
        return _catalogue_first(pick, ok, bic)
    for c in ok:
        own = own_share(c)
        if own is None or own >= OWN_SHARE:
            return c
        source = max(c.sensors.items(), key=lambda kv: kv[1])[0]
        theirs = [o for o in ok if o.effect.sensor == source and (own_share(o) or 0.0) >= OWN_SHARE]
        if not theirs:
            return c
    return ok[0]


def within_noise(c: Candidate, report: StructureReport | None) -> bool:
    """``c`` is on a sensor with residuals that the search found within its noise."""
    s = c.effect.sensor
    return report is not None and s is not None and "exceed" not in report.searched.get(s, "exceed")


def unexplained_misfits(report: StructureReport | None, ok: Sequence[Candidate]) -> set[str]:
    """Sensors exceeding their noise (fitted or held-out) whose strongest dependency (the
    largest share of its residual's variance) no passing candidate has the form of (a
    tracker error following the star's magnitude), or with no dependency found at all: an
    error left unexplained there moves the attitude the others follow. Empty while any
    sensor exceeding its noise has an explanation (its misfit may be what moves the rest)."""
    if report is None:
        return set()
    exceeding = {s for s, why in report.searched.items() if "exceed" in why}
    strongest: dict[str, Dependency] = {}
    for d in report.found:
        if d.sensor in exceeding and (d.sensor not in strongest or d.share > strongest[d.sensor].share):
            strongest[d.sensor] = d
    found_none = exceeding - set(strongest)  # a misfit whose residual follows nothing searched
    out = found_none | {s for s, d in strongest.items() if not any(matches(c, d) for c in ok)}
    # only while no misfit has an explanation: an explained misfit (a magnetometer's matrix)
    # moves the attitude too, and the others' unexplained excess may be its doing
    return out if out == exceeding else set()


def _catalogue_first(pick: Candidate, ok: Sequence[Candidate], bic: dict[str, float]) -> Candidate:
    """A generic family is added only for what the catalogue cannot explain: when a passing
    catalogue effect of the family's sensor, scored on that sensor's own residuals, explains
    at least :data:`CATALOGUE_SHARE` of the family's Δχ², that effect goes first (a
    magnetometer's scale and non-orthogonality before a bias following the orbit's second
    harmonic, which a matrix error also makes); the search runs again after it, and the
    family comes back if a dependence remains."""
    if not is_family(pick.effect):
        return pick
    known = [
        c
        for c in ok
        if not is_family(c.effect)
        and c.effect.sensor == pick.effect.sensor
        and (own_share(c) or 0.0) >= OWN_SHARE
        and c.delta_chi2 >= CATALOGUE_SHARE * pick.delta_chi2
    ]
    return max(known, key=lambda c: bic[c.id]) if known else pick


def prefer_misfit(
    top: Candidate, cands: Sequence[Candidate], report: StructureReport | None, alpha: float
) -> Candidate:
    """Among ``top``'s aliases (candidates the data cannot tell from it), the one on the
    sensor whose own residual the search found structured, when ``top``'s sensor shows none:
    a relative alignment between two trackers is either's, and the one whose residual
    follows something is to blame (a tracker whose error follows the star's magnitude).
    Not when ``top``'s Δχ² comes from no residual of its own sensor (the gyro's, which reach
    the data only through the attitude): "its residual shows no structure" says nothing
    there, and the other sensors' structure is its own signature (issue 27: a gyro scale
    error read as FHST2.alignment_vs_time under τ = 60 s noise)."""
    if report is None or top.effect.sensor is None or report.for_sensor(top.effect.sensor):
        return top
    if top.sensors and top.effect.sensor not in top.sensors:
        return top
    by_id = {c.id: c for c in cands}
    for alias, _ in top.aliases_candidates:
        c = by_id.get(alias)
        if c is not None and c.effect.sensor and report.for_sensor(c.effect.sensor) and c.p_adjusted < alpha:
            return c
    return top


def blame_text(c: Candidate) -> str:
    """``Δχ² from FHST2 (93%), TAM1 (5%)``: where a candidate's Δχ² comes from."""
    parts = [f"{s} ({100 * v:.0f}%)" for s, v in sorted(c.sensors.items(), key=lambda kv: -kv[1]) if v >= 0.01]
    return "Δχ² from " + (", ".join(parts) if parts else "no sensor's residuals")
