"""The residual-structure search on the gyro carrying the attitude: does its bias follow a switch?

A gyro carrying the attitude has no residuals of its own. Its bias stepping when a heater
switches (``b(t) = b + ḃ τ + k x(t)``, x ∈ {0, 1}) turns the carried attitude by
``∫ k x dt``. The batch shows that in every sensor's residual as a dependence on the time
integral of the switch (the channel ``int:<name>``, :mod:`gcs_core.diagnosis.channels`).
The whole-span fit (the default) does not: its knots model the gyro's angle and rate
random walks, and they follow the step's attitude error (0.05 °/h over a 300 s heater
cycle is 15″, against the attitude's own wander of about 1″ there, but spread over
hundreds of knots it costs the process term less than leaving it in the residuals), so
the post-fit residuals are white and the knots' corrections, a smoothed estimate whose
samples are correlated over many knots, have too few independent values for a binned test.

What does see it is the score test of the gyro's bias following the channel, formed with
the whole-span fit's own elimination of the knots (:func:`gcs_core.diagnosis.ranking.rank_candidates`):
the exact test of this one form, χ² on 3 degrees of freedom under the null. So the search
on the gyro is that test, one per switch (an aux channel of values 0 and 1: a heater, a
valve, a power state; :func:`gcs_core.diagnosis.channels.switch_channels`); its p-value
is counted in the search's family-wise correction like every binned test, and a finding
offers the family ``<GYRO>.bias_vs_<channel>`` (:mod:`gcs_core.models.gyro_steps`). On a
mission without a switch nothing is tested and nothing changes. Not under the batch
method (its findings are not acted on, :func:`gcs_core.diagnosis.search.trusted`) nor when
the attitude is not gyro-carried.
"""

from __future__ import annotations

import logging
from dataclasses import replace

import numpy as np

from gcs_core.diagnosis.channels import aux_unit, switch_channels
from gcs_core.diagnosis.structure import Dependency
from gcs_core.problem.state import HELD

log = logging.getLogger(__name__)
AXES = "xyz"


def _scored(analysis, gyro: str, tag: str):
    """The score test of ``<gyro>.bias_vs_<tag>`` at the current fit (a Candidate), on the
    problem with the family held; None when it cannot be formed."""
    from gcs_core.diagnosis.catalogue import mission_catalogue
    from gcs_core.diagnosis.ranking import rank_candidates

    fam = f"bias_vs_{tag}"
    have = analysis.offered.get(gyro, ())
    problem = analysis.problem
    res = analysis.result
    if fam not in have:
        analysis.offered[gyro] = (*have, fam)
        try:
            problem = analysis._build()
        finally:
            if have:
                analysis.offered[gyro] = have
            else:
                del analysis.offered[gyro]
        values = res.state.values()
        res = replace(res, state=problem.state.with_values({k: v for k, v in values.items() if k in problem.state}))
    effect = next((e for e in mission_catalogue(problem, analysis.physics) if e.id == f"{gyro}.{fam}"), None)
    if effect is None or any(problem.state[n].role != HELD for n in effect.elements):
        return None
    cands = rank_candidates(
        problem, res, [effect], alpha=analysis.config.diagnosis.significance, smoothed=res.scores_own_residuals
    )
    return cands[0] if cands else None


def gyro_dependencies(analysis) -> list[Dependency]:
    """One test per switched aux channel of the gyro carrying the attitude (module
    docstring), as dependencies of the gyro on ``aux:<channel>`` (unadjusted p). Asked only
    where the search is trusted (:func:`gcs_core.diagnosis.search.run`)."""
    from gcs_core.problem.gyro_attitude import GyroAttitude

    prob = analysis.problem
    gyro = prob.gyro_name
    if gyro is None or not isinstance(prob.attitude, GyroAttitude):
        return []
    out = []
    for tag in switch_channels(analysis.mission.aux):
        c = _scored(analysis, gyro, tag)
        if c is None:
            continue
        out.append(_dependency(gyro, tag, c, analysis))
    return out


def _dependency(gyro: str, tag: str, c, analysis) -> Dependency:
    """The score test as a finding: the bias axis the estimate is most sure of, its two
    levels' predicted bias about the mean (rad/s)."""
    names = [f"{gyro}.bias_{a}_vs_{tag}" for a in AXES]
    z = [abs(c.estimate.get(n, 0.0)) / max(c.sigma.get(n, np.inf), 1e-300) for n in names]
    i = int(np.argmax(z))
    k = float(c.estimate.get(f"{gyro}.bias_{AXES[i]}_vs_{tag}", 0.0))
    x = np.asarray(analysis.mission.aux.columns[tag], dtype=float)
    levels = np.unique(x)
    counts = np.array([np.count_nonzero(x == v) for v in levels])
    mean = float(np.sum(levels * counts) / counts.sum())
    return Dependency(
        gyro,
        f"b{AXES[i]}",
        "rad/s",
        f"aux:{tag}",
        tag,
        "aux",
        aux_unit(tag),
        levels,
        k * (levels - mean),
        counts,
        float(c.delta_chi2 / max(c.dof, 1)),
        (float(c.dof), float("inf")),
        1.0,
        float(c.p_value),
        share=float("nan"),
    )
