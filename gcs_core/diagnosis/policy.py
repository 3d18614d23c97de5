"""Discovery's choice among candidates the data cannot tell apart."""

from __future__ import annotations

import math

from gcs_core.diagnosis.ranking import Candidate

#: BIC difference below which two aliased candidates count as equally supported
BIC_TIE = 2.0


def parsimonious(top: Candidate, cands: list[Candidate], result, state, alpha: float) -> Candidate:
    """Among candidates the data cannot tell from ``top`` (canonical correlation above
    the alias threshold), prefer the one with the best Bayesian information criterion
    ``Δχ² − dof·ln(n)``: equal fits, fewer parameters (e.g. a Sun-sensor bias against a
    sensor rotation, which differ only at second order). Within ``BIC_TIE`` of the
    best, where the data give no real preference (Kass & Raftery 1995: a difference
    under 2 is "not worth more than a bare mention"), the seed's own calibration
    parameter wins over an extended effect (an Earth-radius bias Δρ over a horizon
    height on a circular orbit), then an always-on physics option over a free parameter
    with the same signature (the WGS-84 flattening over a fitted κ); the report names
    the aliases either way."""
    n = max(2, sum(r.n * len(r.components) for r in result.residuals.values()))
    group = [top] + [c for c in cands if c.id in {a for a, _ in top.aliases_candidates} and c.significant and c.dof > 0]
    bic = {c.id: c.delta_chi2 - c.dof * math.log(n) for c in group}
    best = max(bic.values())
    close = [c for c in group if bic[c.id] >= best - BIC_TIE]

    def seed_effect(c: Candidate) -> bool:
        return bool(c.effect.elements) and all(state[nm].seed for nm in c.effect.elements if nm in state)

    def catalogued(c: Candidate) -> bool:  # a catalogue effect over a generic family of the same form
        return "_vs_" not in c.effect.effect

    # then known physics (no new parameter) over a free one: WGS-84 over a fitted κ
    return max(close, key=lambda c: (seed_effect(c), c.effect.physics, catalogued(c), bic[c.id]))
