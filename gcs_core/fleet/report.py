"""The fleet report (JSON): status per spacecraft-day, moved parameters, discovered effects,
each sensor type's parameters across the fleet with the outliers named, and trends.

Everything but a run's errors is read back from the spacecraft's SCDS histories (the
``fleet`` provenance of each version, :mod:`gcs_core.fleet.store`), so the report of a
re-run or a resumed day is the same as the first one's.

* **Moved**: a sensor's parameter ``x`` (the attitude elements are states, not
  calibration) of a day's version against the latest *accepted* earlier version (the
  fit converged and its goodness of fit was consistent with noise), as
  :func:`gcs_core.io.scds.diff_versions` does:
  ``z = (x_new − x_old) / √(σ_new² + σ_old²)``; moved when ``|z| > moved_sigma``.
* **Distribution** of each sensor type's parameter (``bias_x`` of every magnetometer, ...)
  across the fleet on the latest day: median and robust spread ``s = 1.4826 · MAD``; a
  value is an outlier when ``|x − median| / √(s² + σ²) > outlier_sigma`` (with four values
  or more). The MAD's 1.4826 makes ``s`` the standard deviation of a normal population
  (Rousseeuw & Croux 1993, *J. Am. Stat. Assoc.* 88, 1273).
* **Trends**: each element's value and 1-σ per spacecraft over the days.
"""

from __future__ import annotations

import math
from collections import defaultdict
from collections.abc import Mapping
from datetime import UTC, datetime
from typing import Any

import numpy as np

from gcs_core.fleet.manifest import Manifest
from gcs_core.fleet.store import FLEET_KEY, FleetStore
from gcs_core.io import scds

__all__ = ["build_report", "MAD_TO_SIGMA", "MIN_FOR_OUTLIERS"]

#: the MAD of a normal population times this is its standard deviation
MAD_TO_SIGMA = 1.4826
#: fewer values than this: no outlier is named
MIN_FOR_OUTLIERS = 4


def _accepted(prov: Mapping[str, Any]) -> bool:
    fleet = prov.get(FLEET_KEY) or {}
    return prov.get("status") == "converged" and fleet.get("adequate", True) is not False


def _finite(x: float) -> float | None:
    return float(x) if math.isfinite(x) else None


def _sensor_element(v: scds.ScdsVersion, name: str) -> bool:
    """A sensor's calibration parameter (not the attitude or another state element)."""
    return name.partition(".")[0] in (v.provenance.get("models") or {})


def _moved(new: scds.ScdsVersion, old: scds.ScdsVersion, n_sigma: float) -> list[dict]:
    out = []
    for name, (x1, s1, unit) in new.params.items():
        if name not in old.params or not _sensor_element(new, name):
            continue
        x0, s0, _ = old.params[name]
        scale = math.hypot(s0, s1)
        if not scale > 0:
            continue
        z = (x1 - x0) / scale
        if abs(z) > n_sigma:
            out.append(
                {
                    "element": name,
                    "before": x0,
                    "after": x1,
                    "delta": x1 - x0,
                    "z": z,
                    "unit": unit,
                    "since_version": old.version,
                }
            )
    return sorted(out, key=lambda d: -abs(d["z"]))


def _spacecraft_history(store: FleetStore, name: str, days: list[str], n_sigma: float):
    """day -> (version, facts, moved) of the spacecraft's latest version per day."""
    path = store.scds_path(name)
    if not path.exists():
        return {}, []
    versions = scds.read_versions(path)
    per_day: dict = {}
    for i, v in enumerate(versions):
        facts = v.provenance.get(FLEET_KEY) or {}
        day = facts.get("day")
        if day not in days:
            continue
        base = next((w for w in reversed(versions[:i]) if _accepted(w.provenance)), None)
        moved = _moved(v, base, n_sigma) if base is not None else []
        per_day[day] = (v, facts, moved)
    return per_day, versions


def _day_row(day: str, v, facts: dict, moved: list, entry) -> dict:
    row: dict = {"day": day, "state": entry.state if entry else "stored"}
    if entry is not None and entry.error:
        row["error"] = entry.error
    if v is not None:
        prov = v.provenance
        row.update(
            {
                "scds_version": v.version,
                "status": prov.get("status"),
                "adequate": facts.get("adequate"),
                "verdict": facts.get("verdict", ""),
                "flag": facts.get("flag"),
                "flag_reason": facts.get("flag_reason", ""),
                "discovered": list(facts.get("discovered") or []),
                "moved": moved,
                "warnings": list(facts.get("warnings") or []),
                "chi2": prov.get("chi2"),
                "dof": prov.get("dof"),
            }
        )
    return row


def _distributions(latest: dict, outlier_sigma: float) -> dict:
    """sensor type -> parameter -> the fleet's values, median, spread, outliers (module docstring)."""
    groups: dict = defaultdict(lambda: defaultdict(list))
    for sc, v in latest.items():
        models = v.provenance.get("models") or {}
        solve = set(v.provenance.get("solve_for") or v.params)
        for name, (x, s, unit) in v.params.items():
            sensor, _, kind = name.partition(".")
            if sensor not in models or name not in solve:
                continue
            groups[models[sensor]][kind].append((sc, sensor, x, s, unit))
    out: dict = {}
    for stype in sorted(groups):
        out[stype] = {}
        for kind in sorted(groups[stype]):
            rows = groups[stype][kind]
            x = np.array([r[2] for r in rows])
            s = np.array([r[3] for r in rows])
            med = float(np.median(x))
            spread = MAD_TO_SIGMA * float(np.median(np.abs(x - med)))
            scale = np.sqrt(spread**2 + s**2)
            with np.errstate(divide="ignore", invalid="ignore"):
                z = np.where(scale > 0, (x - med) / scale, 0.0)
            values = [
                {"spacecraft": r[0], "sensor": r[1], "value": r[2], "sigma": r[3], "z": _finite(float(zi))}
                for r, zi in zip(rows, z)
            ]
            outliers = (
                [f"{r[0]}/{r[1]}" for r, zi in zip(rows, z) if abs(zi) > outlier_sigma]
                if len(rows) >= MIN_FOR_OUTLIERS
                else []
            )
            out[stype][kind] = {
                "unit": rows[0][4],
                "n": len(rows),
                "median": med,
                "robust_sigma": spread,
                "values": values,
                "outliers": outliers,
            }
    return out


def _trends(history: dict, days: list[str]) -> dict:
    """element -> unit and, per spacecraft, [day, value, sigma] over the days."""
    out: dict = {}
    for sc, per_day in history.items():
        for day in days:
            if day not in per_day:
                continue
            v = per_day[day][0]
            solve = set(v.provenance.get("solve_for") or v.params)
            for name, (x, s, unit) in v.params.items():
                if name not in solve or not _sensor_element(v, name):
                    continue
                t = out.setdefault(name, {"unit": unit, "series": {}})
                t["series"].setdefault(sc, []).append([day, x, s])
    return {k: out[k] for k in sorted(out)}


def build_report(m: Manifest, run=None, *, days: list[str] | None = None) -> dict:
    """The fleet report of ``days`` (default: the manifest's) after ``run`` (module docstring)."""
    days = list(days or m.days)
    store = FleetStore(m.output)
    entries = {(e.spacecraft, e.day): e for e in (run.entries if run is not None else [])}
    rows, history, latest = [], {}, {}
    errors, moved_all, discovered_all = [], [], []
    for sc in m.spacecraft:
        per_day, _ = _spacecraft_history(store, sc.name, days, m.moved_sigma)
        history[sc.name] = per_day
        day_rows = []
        for day in days:
            e = entries.get((sc.name, day))
            v, facts, moved = per_day.get(day, (None, {}, []))
            if e is not None and e.state == "error":
                v, facts, moved = None, {}, []
            if v is None and e is None:
                continue
            row = _day_row(day, v, facts, moved, e)
            day_rows.append(row)
            if row.get("error"):
                errors.append({"spacecraft": sc.name, "day": day, "error": row["error"]})
            moved_all += [{"spacecraft": sc.name, "day": day, **mv} for mv in row.get("moved", [])]
            discovered_all += [{"spacecraft": sc.name, "day": day, "effect": d} for d in row.get("discovered", [])]
        last = [per_day[d][0] for d in days if d in per_day]
        if last:
            latest[sc.name] = last[-1]
        rows.append({"name": sc.name, "days": day_rows})
    report = {
        "fleet": m.name,
        "manifest": str(m.path),
        "generated_utc": datetime.now(UTC).strftime("%Y-%m-%dT%H:%M:%SZ"),
        "days": days,
        "moved_sigma": m.moved_sigma,
        "outlier_sigma": m.outlier_sigma,
        "spacecraft": rows,
        "errors": errors,
        "moved": moved_all,
        "discovered": discovered_all,
        "distributions": _distributions(latest, m.outlier_sigma),
        "trends": _trends(history, days),
    }
    if run is not None:
        states = [e.state for e in run.entries]
        report["run"] = {
            "workers": run.workers,
            "wall_s": run.wall_s,
            "spacecraft_days": len(states),
            "calibrated": states.count("calibrated"),
            "completed": states.count("completed"),
            "already_done": states.count("already done"),
            "errors": states.count("error"),
            "worker_memory_mb": run.worker_memory_mb,
            # CPU seconds over compute_s: the submitter (missions read, appends, Dask) and each worker
            "compute_s": run.compute_s,
            "submitter_cpu_s": run.client_cpu_s,
            "worker_cpu_s": run.worker_cpu_s,
            "per_minute": states.count("calibrated") / (run.compute_s / 60.0) if run.compute_s > 0 else None,
        }
    return report
