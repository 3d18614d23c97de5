"""Blame the right sensor: which candidate discovery adds when several pass.

One sensor's unexplained error moves the fitted attitude, and the other sensors'
residuals then follow it: a perfect magnetometer's residual follows a temperature because
a bending tracker tilts the attitude with it. A candidate on the magnetometer may then be
significant, though the cause is the tracker. Two rules, applied to the candidates that
pass the family-wise level (:func:`choose`):

1. **The sensor whose own residual follows a channel goes first.** When the
   residual-structure search found sensor Y's residual following a channel, Y's
   candidates of that form (a family on that channel, or a catalogue effect with that
   form) are chosen before anyone else's.
2. **A candidate is not added on sensor X when its Δχ² comes mostly from another sensor
   Y's residuals** (the score's share, ``Candidate.sensors``, below :data:`OWN_SHARE`
   in X's own) while Y has a passing candidate whose Δχ² comes from Y itself: Y's
   explanation is the stronger one. Effects of sensors without residuals of their own
   (the gyro carrying the attitude) and physics effects are exempt.

:func:`blame_text` says for each candidate where its Δχ² comes from.
"""

from __future__ import annotations

from collections.abc import Sequence

from gcs_core.diagnosis.families import channel_of
from gcs_core.diagnosis.ranking import Candidate
from gcs_core.diagnosis.structure import StructureReport

#: share of a candidate's Δχ² its own sensor's residuals must give for it to stand alone
OWN_SHARE = 0.5


def own_share(c: Candidate) -> float | None:
    """Share of ``c``'s Δχ² from its own sensor's residuals; None when that sensor has none
    (a gyro, a physics option)."""
    s = c.effect.sensor
    if s is None or s not in c.sensors:  # a sensor with residuals scores its own effects
        return None
    return float(c.sensors[s])


def matches(c: Candidate, report: StructureReport | None) -> bool:
    """``c`` is a candidate on a sensor whose residual the search found following a channel,
    of that channel's form (a family on it, or a catalogue effect of its form)."""
    if report is None or c.effect.sensor is None:
        return False
    deps = report.for_sensor(c.effect.sensor)
    if not deps:
        return False
    ch = channel_of(c.effect.effect)
    for d in deps:
        chans = {d.channel, *d.aliases}
        if ch is not None and (ch in chans or (ch == "orbit_phase" and chans & {"sun_angle", "eclipse"})):
            return True
        if c.id in d.catalogue:
            return True
    return False


def choose(ok: Sequence[Candidate], report: StructureReport | None) -> Candidate:
    """The candidate to add among ``ok`` (passing, identifiable, most significant first):
    rules 1 and 2 of the module docstring, else the most significant."""
    first = [c for c in ok if matches(c, report)]
    if first:
        return first[0]
    for c in ok:
        own = own_share(c)
        if own is None or own >= OWN_SHARE:
            return c
        source = max(c.sensors.items(), key=lambda kv: kv[1])[0]
        theirs = [o for o in ok if o.effect.sensor == source and (own_share(o) or 0.0) >= OWN_SHARE]
        if not theirs:
            return c
    return ok[0]


def blame_text(c: Candidate) -> str:
    """``Δχ² from FHST2 (93%), TAM1 (5%)``: where a candidate's Δχ² comes from."""
    parts = [f"{s} ({100 * v:.0f}%)" for s, v in sorted(c.sensors.items(), key=lambda kv: -kv[1]) if v >= 0.01]
    return "Δχ² from " + (", ".join(parts) if parts else "no sensor's residuals")
