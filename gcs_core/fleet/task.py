"""What one worker computes for one spacecraft-day, from the data it is handed.

A :class:`Job` carries the imported mission (:class:`~gcs_core.io.importer.ImportedMission`,
read on the submitting machine) and the analysis config; the worker never opens a path
(the paths inside the mission are provenance strings only). :func:`run_job` does what
``gcs batch --scds``, ``gcs verify --asf`` and ``gcs discover`` do on the same inputs, with
the same engine calls (:class:`gcs_core.session.Analysis`,
:func:`gcs_core.calibration.calibration_record`, :func:`gcs_core.verif.analysis.verify_analysis`,
:meth:`~gcs_core.session.Analysis.discover`):

1. fit the configured state (the held-out span scored, as ``gcs batch`` does);
2. form the SCDS record (exactly what ``save_calibration`` appends) and the goodness-of-fit
   verdict;
3. verify the onboard attitudes against the fit (§4.4 flag) and form the ASF record
   (exactly what ``save_ground_attitude`` appends);
4. optionally, stepwise discovery of missing effects on the same analysis (what
   ``gcs discover`` reports; the SCDS keeps the configured state's calibration).

The outcome is plain data: the submitter appends it. A bad input or a failed estimation is
one line in :attr:`Outcome.error`; it stops nothing else.
"""

from __future__ import annotations

import logging
import math
import os
import socket
import time
from dataclasses import dataclass, field
from typing import Any

from gcs_core.errors import GcsError

log = logging.getLogger(__name__)

__all__ = ["Job", "Outcome", "run_job", "one_line", "warm_up"]


@dataclass(frozen=True)
class Job:
    """One spacecraft-day for a worker.

    Attributes
    ----------
    spacecraft, day : names from the manifest.
    input_hash : content hash of the day's input files and config (:mod:`gcs_core.fleet.store`).
    config : the spacecraft's analysis config.
    mission : the imported mission, in memory.
    discover, max_steps : run discovery, with at most this many additions.
    note : the note stored with the calibration.
    """

    spacecraft: str
    day: str
    input_hash: str
    config: Any
    mission: Any
    discover: bool = True
    max_steps: int = 3
    note: str = ""


@dataclass
class Outcome:
    """What a worker hands back for one spacecraft-day.

    Attributes
    ----------
    calibration : keyword arguments of :func:`gcs_core.io.scds.append_version` (None on error).
    attitude : keyword arguments of :func:`gcs_core.io.asf.append_solution` (None when the fit
        covers no time or on error).
    summary : fit status, goodness-of-fit verdict (``adequate``, ``verdict``), verification
        (``flag``, ``flag_reason``), discovery (``discovered``, ``stop_reason``).
    error : one line when the spacecraft-day failed, else None.
    worker : host:pid that computed it; seconds : its wall time; cpu_s : the CPU time
    [s] of the worker process while computing it.
    """

    spacecraft: str
    day: str
    input_hash: str
    calibration: dict | None = None
    attitude: dict | None = None
    summary: dict = field(default_factory=dict)
    error: str | None = None
    worker: str = ""
    seconds: float = 0.0
    cpu_s: float = 0.0


def one_line(text: object) -> str:
    return " ".join(str(text).split())


def _plain(value):
    """``value`` with every non-finite float as None (the SCDS provenance is strict JSON)."""
    if isinstance(value, dict):
        return {k: _plain(v) for k, v in value.items()}
    if isinstance(value, (list, tuple)):
        return [_plain(v) for v in value]
    if isinstance(value, float) and not math.isfinite(value):
        return None
    return value


def _verification(a) -> dict:
    from gcs_core.verif.analysis import verify_analysis

    if a.mission.onboard is None or len(a.mission.onboard) == 0:
        return {"flag": None, "flag_reason": "no onboard attitude to verify (ICD §6)"}
    v = verify_analysis(a)
    rep = v.as_report()
    return {"flag": bool(v.flag), "flag_reason": one_line(v.reason), "verification": rep}


def _analyse(job: Job) -> tuple[dict, dict | None, dict]:
    from gcs_core.calibration import calibration_record, ground_attitude_record
    from gcs_core.session import Analysis

    a = Analysis(job.config, mission=job.mission)
    a.fit()
    res = a.result
    assert res is not None  # fit() sets it
    if res.status == "diverged":
        raise GcsError(f"estimation failed: {one_line(res.message)}")
    cal = calibration_record(a, note=job.note)
    g = a.goodness()
    summary: dict = {
        "status": res.status,
        "adequate": bool(g.adequate) if g is not None else None,
        "verdict": one_line(g.verdict) if g is not None else "",
        "warnings": [one_line(w) for w in a.warnings],
        "effects_in_state": list(a.effects_in_state()),
    }
    summary.update(_verification(a))
    att = ground_attitude_record(a, note=job.note)
    if job.discover:
        a.discover(max_steps=job.max_steps)
        summary["discovered"] = [s.effect for s in a.steps if s.action == "add" and s.effect]
        summary["stop_reason"] = one_line(a.stop_reason)
    return cal, att, _plain(summary)


def warm_up() -> float:
    """Import what :func:`run_job` uses (run on each worker as the cluster starts); return
    the CPU seconds it took. A worker's first task would otherwise pay it: 1.2 to 1.4 s,
    four times a 15-minute spacecraft-day's fit, once per worker process."""
    c0 = time.process_time()
    import gcs_core.calibration
    import gcs_core.io.importer
    import gcs_core.session
    import gcs_core.verif.analysis  # noqa: F401 — imported for the side effect of loading them

    return time.process_time() - c0


def run_job(job: Job) -> Outcome:
    """Compute one spacecraft-day (module docstring); never raises for bad data."""
    t0, c0 = time.perf_counter(), time.process_time()
    out = Outcome(job.spacecraft, job.day, job.input_hash, worker=f"{socket.gethostname()}:{os.getpid()}")
    try:
        out.calibration, out.attitude, out.summary = _analyse(job)
    except GcsError as err:
        out.error = one_line(err)
    except Exception as err:
        if type(err).__name__ == "LinAlgError" or isinstance(err, FloatingPointError):
            out.error = one_line(f"estimation failed: {type(err).__name__}: {err}")
        else:
            log.debug("internal error on %s %s", job.spacecraft, job.day, exc_info=True)
            out.error = one_line(f"internal error: {type(err).__name__}: {err}")
    out.seconds, out.cpu_s = time.perf_counter() - t0, time.process_time() - c0
    return out
