"""The JSON report of the headless runs (ICD §7) and what remains after a fit.

The report of ``gcs batch`` and ``gcs discover`` is :func:`analysis_report`, built here
once from a fitted :class:`~gcs_core.session.Analysis`; the fields ICD §7 requires are
checked by :func:`icd_report_problems`. The text tables of the command are in the face
(:mod:`gcs_tui.cli.tables`); nothing here writes to a terminal.
"""

from __future__ import annotations

import json
import math
from collections.abc import Mapping
from pathlib import Path
from typing import Any

import numpy as np

from gcs_core.diagnosis.honest_sigma import sigma_scale_report
from gcs_core.fileperm import write_atomic
from gcs_core.json_values import json_default
from gcs_core.noise import correlated as noise_correlation
from gcs_core.problem.state import HELD, SOLVE_FOR
from gcs_core.toml_values import is_number


# ---------------------------------------------------------------------------- JSON (ICD §7)
def analysis_report(analysis, *, command: str | None = None) -> dict[str, Any]:
    """The ICD §7 report of a :class:`~gcs_core.session.Analysis`: what ``gcs batch`` and
    ``gcs discover`` write (``command`` names which).

    ``sensors[name].rms`` is one number as in ICD §7, the RMS over the components
    ``sqrt(mean_j rms_j²)`` in the sensor's unit; the per-component values are in
    ``rms_components``. ``state`` lists every element that is not held, with whether the
    data determined it; ``physics_needed`` the always-on physics and what switching each
    off would cost; ``remaining`` what is left per sensor against its stated noise;
    ``noise_weighting`` (only with ``[filter] noise_weighting = "long_run"``) each sensor's
    long-run noise factor and window (:mod:`gcs_core.noise.weighting`): the fit weighted
    σ × factor, while normalized RMS, χ² and verdicts stay against the stated σ;
    ``sigma_scale`` the batch-means sandwich σ scale of each solve-for element and its σ with
    the residuals' correlation (:mod:`gcs_core.diagnosis.honest_sigma`), null when off or
    not estimable (too few windows); ``noise_correlation`` each sensor's first-order
    Gauss–Markov correlation, measured or declared (:mod:`gcs_core.noise.correlated`).
    """
    res = analysis.result
    gof = analysis.goodness()
    out: dict[str, Any] = {"mission": analysis.mission.spec.name}
    if command:
        out["command"] = command
    out.update(
        {
            "method": analysis.config.method,
            "status": res.status if res else "not run",
            "sensors": _sensor_rows(analysis, gof) if res is not None else {},
            "state": _state_rows(analysis) if res is not None else [],
            "candidates": [c.as_report() for c in analysis.candidates],
            "steps": [s.as_report() for s in analysis.steps if s.action != "fit"],
            "effects_in_state": analysis.effects_in_state(),
            "physics": analysis.config.physics.as_dict(),
            "physics_needed": [physics_row(p) for p in analysis.physics_needed()] if res is not None else [],
            "unobservable": list(res.unobservable) if res else [],
            "aliases": [al.as_report() for al in analysis.aliases()],
            "unobservable_at_prior": analysis.null_at_prior() if res else [],
            "goodness_of_fit": gof.as_report() if gof is not None else None,
            "verdict": gof.verdict if gof is not None else "not run",
            "warnings": list(analysis.warnings),
            "stop_reason": analysis.stop_reason,
            "residual_structure": _structure(analysis),
            "config_digest": analysis.config.digest(),
        }
    )
    if res is not None:
        out["remaining"] = remaining_summary(analysis)
        sc = analysis.sigma_scale() if hasattr(analysis, "sigma_scale") else None
        out["sigma_scale"] = sigma_scale_report(sc, res.sigma, res) if sc is not None else None
    if getattr(analysis, "noise", None) is not None:  # [filter] noise_weighting = "long_run" / "correlated"
        out["noise_weighting"] = analysis.noise.as_report()
    if getattr(analysis, "correlation", None):  # each sensor's noise correlation (docs/icd_extensions.md)
        carried = analysis.config.filter.noise_weighting == "correlated"
        out["noise_correlation"] = noise_correlation.report(analysis.correlation, carried)
    return out


def _structure(analysis) -> dict[str, Any] | None:
    """The latest residual-structure search (docs/residual_structure.md), with the families
    it offered; None when none ran."""
    rep = getattr(analysis, "structure_report", None)
    if rep is None:
        return None
    out = rep.as_report()
    out["families_offered"] = {k: list(v) for k, v in getattr(analysis, "offered", {}).items()}
    return out


def _sensor_rows(analysis, gof) -> dict[str, dict[str, Any]]:
    """Per sensor: frames used and edited, RMS (one number and per component), normalized
    RMS fitted and held-out, the goodness-of-fit tests."""
    rows = {}
    for name, r in analysis.result.residuals.items():
        comp = np.atleast_1d(np.asarray(r.rms, dtype=float))
        held = analysis.holdout_rms.get(name, float("nan"))
        rows[name] = {
            "n": r.n,
            "rms": float(np.sqrt(np.mean(comp**2))) if comp.size else float("nan"),
            "rms_normalized": round(r.rms_normalized, 4),
            "edited": int(np.count_nonzero(r.edited)),
            "holdout_rms_normalized": round(held, 4) if math.isfinite(held) else None,
            "unit": r.unit,
            "components": list(r.components),
        }
        rows[name].update(gof.sensor_report(name) if gof is not None else {})
        rows[name]["rms_components"] = {c: float(v) for c, v in zip(r.components, comp)}
    return rows


def _state_rows(analysis) -> list[dict[str, Any]]:
    """Every element not held: estimate, σ, unit, role; for solve-for elements whether the
    data determined it, whether the a priori set it, its prior share and why."""
    from gcs_core.diagnosis.determination import prior_shares

    res = analysis.result
    sig = res.sigma
    loose = analysis.not_determined()
    by_prior = analysis.set_by_prior()
    shares = prior_shares(res.solve_for, res.P, [res.state[n].sigma0 for n in res.solve_for])
    rows = []
    for e in res.state:
        if e.role == HELD:
            continue
        row = {"name": e.name, "estimate": e.value, "sigma": sig.get(e.name, e.sigma0), "unit": e.unit, "role": e.role}
        if e.role == SOLVE_FOR:
            row["determined"] = e.name not in loose
            if e.name in loose:
                row["note"] = loose[e.name]
            row["set_by_prior"] = e.name in by_prior
            if e.name in shares:
                row["prior_share"] = round(shares[e.name], 4)
            if e.name in by_prior and e.name not in loose:
                row["note"] = by_prior[e.name]
        rows.append(row)
    return rows


def physics_why(p) -> str:
    """Why an always-on physics option is or is not shown needed (a
    :class:`~gcs_core.diagnosis.physics.PhysicsNeed`), in one sentence."""
    seen = ", ".join(f"{k} ({100 * v:.0f}%)" for k, v in p.sensors.items() if v >= 0.05)
    return (
        f"switching it off would add Δχ² = {p.delta_chi2_if_removed:.4g} on 1 dof"
        + (f", seen in {seen}" if seen else "")
        + (
            "; the data need it."
            if p.needed
            else f"; below the {p.critical_chi2:.1f} that α = {p.alpha:g} needs: "
            "these data cannot show it, but it is real physics."
        )
    )


def physics_row(p) -> dict[str, Any]:
    """The report row of a :class:`~gcs_core.diagnosis.physics.PhysicsNeed`."""
    return {
        "id": p.id,
        "delta_chi2_if_removed": round(p.delta_chi2_if_removed, 3),
        "needed": p.needed,
        "why": physics_why(p),
        "physics": p.explanation,
    }


#: χ²/n within this many standard deviations (√(2/n)) of 1 is "consistent with the noise"
NOISE_CONSISTENCY_SIGMAS = 3.0


def remaining_summary(analysis) -> dict[str, dict[str, Any]]:
    """What remains after the fit, per sensor, against the noise the data book states.

    With white noise of the stated σ, ``χ²/n = rms_normalized²`` has mean 1 and standard
    deviation ``√(2/n)`` (n measurements); the residual is called consistent with the
    noise when ``|χ²/n − 1| ≤ 3 √(2/n)``. ``noise_estimated`` is true when the mission
    says its noise was estimated from the data (a converter's note).
    """
    res = analysis.result
    if res is None:
        return {}
    out: dict[str, dict[str, Any]] = {}
    spec = analysis.mission.spec
    for name, r in res.residuals.items():
        comp = np.atleast_1d(np.asarray(r.rms, dtype=float))
        n = int(np.count_nonzero(r.used)) * len(r.components) if hasattr(r, "used") else r.n
        ratio = float(r.rms_normalized) ** 2
        bound = NOISE_CONSISTENCY_SIGMAS * float(np.sqrt(2.0 / max(n, 1)))
        try:
            sensor = spec.sensor(name)
        except KeyError:
            sensor = None
        noise = getattr(sensor, "noise", None)
        estimated = _noise_estimated(spec, name)
        held = analysis.holdout_rms.get(name, float("nan"))
        out[name] = {
            "rms": float(np.sqrt(np.mean(comp**2))) if comp.size else float("nan"),
            "rms_normalized": float(r.rms_normalized),
            "holdout_rms_normalized": float(held),
            "noise": noise,
            "unit": r.unit,
            "noise_estimated": estimated,
            "chi2_per_measurement": ratio,
            "consistency_bound": bound,
            "consistent_with_noise": bool(abs(ratio - 1.0) <= bound),
        }
    return out


def _noise_estimated(spec, name: str) -> bool:
    """True when mission.toml marks the sensor's noise as estimated from the data (the
    converters' one marker, :func:`gcs_core.noise.measured.noise_estimated`)."""
    from gcs_core.noise.measured import noise_estimated

    try:
        text = (spec.root / "mission.toml").read_text(encoding="utf-8")
    except OSError:
        return False
    return noise_estimated(text, name)


def _is_num(v, *, none_ok: bool = False) -> bool:
    return none_ok if v is None else is_number(v)


def icd_report_problems(rep: Mapping[str, Any]) -> list[str]:
    """What an ICD §7 report lacks (empty when every required field is there and typed).

    Required: ``mission``; ``sensors{name: {n, rms, rms_normalized}}``;
    ``state[{name, estimate, sigma, unit}]``; ``candidates[{id, sensor, effect,
    delta_chi2, dof, p_value, identifiable}]``; ``steps[{added, rms_normalized_before,
    rms_normalized_after}]`` (a removal names ``removed`` instead). A number that was not
    finite is ``null`` in JSON and accepted where a σ or p may be undefined.
    """
    out = []
    if not isinstance(rep.get("mission"), str):
        out.append("mission: must be a string")
    sensors = rep.get("sensors")
    if not isinstance(sensors, Mapping):
        out.append("sensors: must be an object")
        sensors = {}
    for name, s in sensors.items():
        if not isinstance(s, Mapping):
            out.append(f"sensors.{name}: must be an object")
            continue
        if not isinstance(s.get("n"), int) or isinstance(s.get("n"), bool):
            out.append(f"sensors.{name}.n: must be an integer")
        for k in ("rms", "rms_normalized"):
            if k not in s or not _is_num(s[k], none_ok=True):
                out.append(f"sensors.{name}.{k}: must be a number")
    for key, fields in (
        ("state", {"name": str, "estimate": float, "sigma": float, "unit": str}),
        (
            "candidates",
            {
                "id": str,
                "sensor": str,
                "effect": str,
                "delta_chi2": float,
                "dof": int,
                "p_value": float,
                "identifiable": bool,
            },
        ),
        ("steps", {"rms_normalized_before": dict, "rms_normalized_after": dict}),
    ):
        rows = rep.get(key)
        if not isinstance(rows, list):
            out.append(f"{key}: must be a list")
            continue
        for i, row in enumerate(rows):
            if not isinstance(row, Mapping):
                out.append(f"{key}[{i}]: must be an object")
                continue
            for f, typ in fields.items():
                v = row.get(f)
                ok = f in row and (
                    _is_num(v, none_ok=f in ("sigma", "p_value"))
                    if typ is float
                    else isinstance(v, int) and not isinstance(v, bool)
                    if typ is int
                    else isinstance(v, typ)
                )
                if not ok:
                    out.append(f"{key}[{i}].{f}: must be {typ.__name__}")
            if key == "steps" and not isinstance(row.get("added", row.get("removed")), str):
                out.append(f"steps[{i}].added: must name the effect")
    return out


def _clean(o):
    if isinstance(o, float) and not math.isfinite(o):
        return None
    if isinstance(o, dict):
        return {k: _clean(v) for k, v in o.items()}
    if isinstance(o, (list, tuple)):
        return [_clean(v) for v in o]
    return o


def write_json_atomic(path: Path, data: dict) -> Path:
    """Write JSON (NaN/inf as null) atomically (:func:`gcs_core.fileperm.write_atomic`);
    a file of a kind GCS recognises (an SCDS, an SDF, a mission directory) is never replaced."""
    from gcs_core.io.outputs import refuse_other_kind

    refuse_other_kind(path, "text", "the JSON report")
    text = json.dumps(_clean(json.loads(json.dumps(data, default=json_default))), indent=2)
    return write_atomic(path, text, parents=True)
