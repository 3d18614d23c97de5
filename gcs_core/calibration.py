"""Writing a fitted analysis to the Sensor Calibration Data Set and the Attitude Status File.

The seed's DRIVER "can update two disc data files as a result of the attitude and bias
determination: the Sensor Calibration Data Set which stores the updated sensor
calibration parameter, and the Attitude Status File which stores the attitude
determination results" (§3.2.2). Both are append-only HDF5 histories; every write goes
through :mod:`gcs_core.io.scds` and :mod:`gcs_core.io.asf`, which lock the file and
replace it atomically.

A calibration version holds every element that is not held (solve-for: the estimate and
its 1-σ including consider contributions; consider: the value used and its a-priori σ),
the solve-for covariance (Eq 3-2, with ``S P_c Sᵀ``), and its provenance: the data span,
the model of every sensor, the physics options, the config digest, the mission, the
solution status (and, filled by the SCDS, the GCS version and the UTC time).
"""

from __future__ import annotations

import math
from pathlib import Path

import numpy as np

from gcs_core.errors import EstimationError, InputError
from gcs_core.io import asf, scds
from gcs_core.problem.state import HELD, SOLVE_FOR
from gcs_core.verif.ground import covered, ground_attitude

__all__ = [
    "save_calibration",
    "save_ground_attitude",
    "calibration_provenance",
    "calibration_record",
    "ground_attitude_record",
]


def _result(analysis):
    if analysis.result is None:
        raise EstimationError("the analysis has not been fitted yet: fit before saving a calibration")
    return analysis.result


def _data_span(res) -> tuple[float, float]:
    """(first, last) time of the frames used by the fit [s]."""
    used = [r.t[r.used] for r in res.residuals.values() if np.any(r.used)]
    if not used:
        raise EstimationError("the fit used no frames")
    t = np.concatenate(used)
    return float(t.min()), float(t.max())


def calibration_provenance(analysis, *, note: str = "") -> dict:
    """The provenance facts of a calibration version (module docstring)."""
    res = _result(analysis)
    problem = analysis.problem
    t0, t1 = _data_span(res)
    models = {sd.name: sd.model.type_name for sd in problem.sensors}
    if problem.gyro_name:
        models[problem.gyro_name] = "gyro"
    cfg = analysis.config
    return {
        "note": str(note),
        "data_t0": t0,
        "data_t1": t1,
        "models": models,
        "physics": cfg.physics.as_dict(),
        "config_hash": cfg.digest(),
        "mission": analysis.mission.spec.name,
        "mission_dir": str(analysis.mission.spec.root),
        "epoch_utc": analysis.mission.spec.epoch.strftime("%Y-%m-%dT%H:%M:%SZ"),
        "method": cfg.method,
        "status": res.status,
        "chi2": float(res.chi2) if math.isfinite(res.chi2) else None,
        "dof": int(res.dof),
        "solve_for": list(res.solve_for),
        "consider": list(res.consider),
        "effects_in_state": list(analysis.effects_in_state()),
    }


def calibration_record(analysis, *, note: str = "") -> dict:
    """The keyword arguments :func:`gcs_core.io.scds.append_version` is given for the fitted
    calibration of ``analysis`` (plain data: a worker process can form it and the process
    that owns the SCDS append it, :mod:`gcs_core.fleet`)."""
    res = _result(analysis)
    sigma = res.sigma
    params = {}
    for e in res.state:
        if e.role == HELD:
            continue
        s = sigma[e.name] if e.role == SOLVE_FOR else e.sigma0
        if not math.isfinite(s):
            raise InputError(f"element '{e.name}' has no finite sigma to store", key=f"state.{e.name}")
        params[e.name] = (float(e.value), float(s), e.unit)
    return {
        "sensor_params": params,
        "covariance": np.asarray(res.P_consider),
        "element_names": list(res.solve_for),
        "provenance": calibration_provenance(analysis, note=note),
    }


def save_calibration(analysis, scds_path, *, note: str = "") -> int:
    """Append the fitted calibration of ``analysis`` to the SCDS; return its version number.

    Parameters
    ----------
    analysis : a fitted :class:`gcs_core.session.Analysis`.
    scds_path : the SCDS file (created if absent).
    note : free text kept with the version.

    Raises
    ------
    EstimationError before a fit; DataFileError if the SCDS is locked or corrupt.
    """
    return scds.append_version(scds_path, **calibration_record(analysis, note=note))


def ground_attitude_record(
    analysis, *, step: float | None = None, note: str = "", scds_version: int | None = None
) -> dict:
    """The keyword arguments :func:`gcs_core.io.asf.append_solution` is given for the fitted
    attitude of ``analysis`` (see :func:`save_ground_attitude`)."""
    res = _result(analysis)
    t0, t1 = _data_span(res)
    if step is None:
        t = np.unique(np.concatenate([r.t[r.used] for r in res.residuals.values()]))
    else:
        if not step > 0:
            raise InputError(f"step must be > 0, got {step}", key="asf.step")
        t = np.arange(t0, t1 + 0.5 * step, step)
    t = t[covered(analysis, t)]
    if t.size == 0:
        raise EstimationError("no time of the fitted span is covered by the attitude")
    g = ground_attitude(analysis, t)
    prov = {
        "note": str(note),
        "config_hash": analysis.config.digest(),
        "mission": analysis.mission.spec.name,
        "status": res.status,
        "sigma_axes": "body x, y, z",
    }
    if scds_version is not None:
        prov["scds_version"] = int(scds_version)
    source = analysis.estimator.attitude_source
    return {"t": g.t, "q": g.q, "sigma": g.sigma_body, "source": source, "provenance": prov}


def save_ground_attitude(
    analysis, asf_path, *, step: float | None = None, note: str = "", scds_version: int | None = None
) -> int:
    """Append the fitted attitude with its 1-σ to the ASF; return the solution number.

    Parameters
    ----------
    analysis : a fitted :class:`gcs_core.session.Analysis`.
    asf_path : the ASF file (created if absent).
    step : None — at every sensor frame time used by the fit; else a regular grid of
        this spacing [s] over the fitted span.
    note : free text; scds_version : the SCDS version holding this calibration, if saved.

    The attitude and its body-axis 1-σ come from :func:`gcs_core.verif.ground.ground_attitude`.
    """
    record = ground_attitude_record(analysis, step=step, note=note, scds_version=scds_version)
    return asf.append_solution(Path(asf_path), **record)
