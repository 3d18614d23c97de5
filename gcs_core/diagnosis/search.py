"""The residual-structure search run on an analysis session (its hooks into discovery).

:func:`exceeding` names the sensors whose residuals exceed the noise, on the fitted span
(``Σz²`` against χ² on the frames' count, the fit's few parameters left out: conservative)
or the held-out span (the session's held-out χ² tests), each at the family-wise level over
all these tests; :func:`run` searches them, any sensor asked for and the others, with
:func:`gcs_core.diagnosis.structure.search`; :func:`offer` makes the generic families of
what was found candidates of the session (:mod:`gcs_core.diagnosis.families`), except
under the batch method with a gyro, whose attitude wander looks like any slow drift.
"""

from __future__ import annotations

import logging
from collections.abc import Iterable
from dataclasses import replace

import numpy as np
from scipy import stats

from gcs_core.diagnosis.channels import Channel, sensor_channels
from gcs_core.diagnosis.families import families_from
from gcs_core.diagnosis.gyro_search import gyro_dependencies
from gcs_core.diagnosis.structure import StructureReport, search

log = logging.getLogger(__name__)


def exceeding(analysis) -> dict[str, str]:
    """sensor -> why it is searched ("fitted residuals exceed the noise", "held-out ...")."""
    res = analysis.result
    if res is None:
        return {}
    tests: list[tuple[str, str, float]] = []
    for name, r in res.residuals.items():
        z = np.asarray(r.residual, float)[np.asarray(r.used, bool)] / np.asarray(r.sigma, float)
        z = z[np.isfinite(z)]
        if z.size:
            tests.append((name, "fitted residuals exceed the noise", float(stats.chi2.sf(np.sum(z**2), z.size))))
    for name, t in analysis.holdout_chi2.items():
        if name in res.residuals:
            tests.append((name, "held-out residuals exceed the noise", t.p_value))
    m = max(len(tests), 1)
    alpha = analysis.config.diagnosis.significance
    out: dict[str, str] = {}
    for name, why, p in tests:
        if np.isfinite(p) and p * m < alpha and name not in out:
            out[name] = why
    return out


def channels_of(analysis, sensor: str) -> list[Channel]:
    """The channels at a sensor's frames, formed once per problem."""
    prob = analysis.problem
    cache = prob.__dict__.setdefault("_channel_cache", {})
    if sensor not in cache:
        sd = prob.sensor(sensor)
        r = analysis.result.residuals.get(sensor)
        y_fov = (
            np.asarray(r.y, float) - np.asarray(r.residual, float)
            if r is not None and r.y.shape == sd.y.shape
            else None
        )
        cache[sensor] = sensor_channels(
            sd, builder=prob.builder, telemetry=analysis.mission.telemetry, gyro=prob.gyro_name, y_fov=y_fov
        )
    return cache[sensor]


def run(analysis, sensors: Iterable[str] = ()) -> StructureReport:
    """Search every sensor with residuals: those exceeding the noise, those in ``sensors``
    (on request) and the rest (a drift the fit's attitude half absorbs may leave a sensor
    within its noise while its residual still follows the channel); the search's family-wise
    level covers them all."""
    why = exceeding(analysis)
    for s in sensors:
        why.setdefault(s, "on request")
    res = analysis.result
    for s in res.residuals:
        why.setdefault(s, "within the noise")
    known = {sd.name for sd in analysis.problem.sensors}
    why = {k: v for k, v in why.items() if k in known and k in res.residuals}
    chans = {s: channels_of(analysis, s) for s in why}
    ids = [e.id for e in analysis.candidate_effects()]
    # its bias against switched aux channels (none without; not where the search is untrusted)
    gyro = gyro_dependencies(analysis) if trusted(analysis) else []
    if gyro:
        why[gyro[0].sensor] = "its bias against the switched aux channels (score test)"
    return search(
        res.residuals, chans, alpha=analysis.config.diagnosis.significance, why=why, catalogue_ids=ids, extra=gyro
    )


def trusted(analysis) -> bool:
    """Whether the search's findings may make candidates and blame: not under the batch
    method with a gyro, which holds the gyro-carried attitude exact, so that the attitude's
    wander shows in every sensor as a slow dependence (on time, the orbit, a temperature
    following it) its score tests cannot tell from a drift (``Analysis._method_warnings``)."""
    return analysis.estimator.gyro_process_noise or analysis.problem.gyro_name is None


def offer(analysis, report: StructureReport) -> bool:
    """Make the families of ``report``'s findings candidates; True when any is new. The
    problem is rebuilt with them (held, so the fit is unchanged) and the latest result's
    state gains them at zero."""
    if not trusted(analysis):
        return False
    models = {sd.name: sd.model for sd in analysis.problem.sensors}
    new = families_from(report.found, models, gyro=analysis.problem.gyro_name)
    changed = False
    for s, fams in new.items():
        have = analysis.offered.get(s, ())
        add = tuple(f for f in fams if f not in have)
        if add:
            analysis.offered[s] = have + add
            changed = True
    if not changed:
        return False
    record = analysis.record
    analysis.problem = analysis._build()
    if record is not None:
        old = record.result
        values = old.state.values()
        merged = analysis.problem.state.with_values({k: v for k, v in values.items() if k in analysis.problem.state})
        analysis.record = replace(record, result=replace(old, state=merged))
    log.info("offered families: %s", ", ".join(f"{s}.{f}" for s, fs in new.items() for f in fs))
    return True
