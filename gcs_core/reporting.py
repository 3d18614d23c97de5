"""Plain-text tables and the JSON report writer for headless runs.

Numbers are shown with honest precision: an estimate is rounded to the decimal place
of the second significant digit of its σ, and angles are shown in arcsec or degrees
rather than radians.
"""

from __future__ import annotations

import json
import math
import os
import tempfile
from pathlib import Path

import numpy as np

from gcs_core.units import ARCSEC, DEG


def display_unit(unit: str, value: float, sigma: float | None = None) -> tuple[float, float | None, str]:
    """(value, sigma, unit) converted for display: rad → arcsec (or deg when large)."""
    if unit == "rad":
        big = abs(value) > 1.0 * DEG and (sigma is None or not math.isfinite(sigma) or sigma > 0.01 * DEG)
        if big:
            return value / DEG, (sigma / DEG if sigma is not None else None), "deg"
        return value / ARCSEC, (sigma / ARCSEC if sigma is not None else None), "arcsec"
    if unit == "rad/s":
        return value / DEG * 3600, (sigma / DEG * 3600 if sigma is not None else None), "deg/h"
    return value, sigma, unit


def format_estimate(value: float, sigma: float | None, unit: str) -> str:
    """``value ± sigma unit`` rounded to the σ's second significant digit."""
    v, s, u = display_unit(unit, value, sigma)
    if s is None or not math.isfinite(s) or s <= 0:
        return f"{v:.6g} {u}".strip()
    digits = max(0, 1 - int(math.floor(math.log10(s))))
    return f"{v:.{digits}f} ± {s:.{digits}f} {u}".strip()


def fit_table(analysis) -> list[str]:
    res = analysis.result
    lines = [f"{'sensor':10s} {'n':>7s} {'edited':>6s} {'norm. RMS':>9s} {'held-out':>9s}  RMS per component"]
    for name, r in res.residuals.items():
        rms = r.rms
        comp = ", ".join(f"{c} {v:.3g}" for c, v in zip(r.components, rms))
        ho = analysis.holdout_rms.get(name, float("nan"))
        lines.append(f"{name:10s} {r.n:7d} {int(np.count_nonzero(r.edited)):6d} {r.rms_normalized:9.3f} "
                     f"{ho:9.3f}  {comp} [{r.unit}]")
    lines.append(f"status: {res.message}; χ² {res.chi2:.1f} on {res.dof} dof")
    for u in res.unobservable:
        lines.append(f"unobservable from the data: {u}")
    return lines


def state_table(analysis) -> list[str]:
    res = analysis.result
    sig = res.sigma
    lines = [f"{'element':28s} {'role':10s} estimate"]
    for e in res.state:
        if e.role == "held":
            continue
        lines.append(f"{e.name:28s} {e.role:10s} {format_estimate(e.value, sig.get(e.name, e.sigma0), e.unit)}")
    return lines


def prediction_table(res) -> list[str]:
    names = list(res.names)
    final = res.sigma[-1] if len(res.sigma) else []
    lines = [f"{'element':28s} predicted 1-sigma at end of plan"]
    for n, s in zip(names, final):
        unit = res.units[names.index(n)] if hasattr(res, "units") else ""
        _, s_disp, u = display_unit(unit, 0.0, float(s))
        lines.append(f"{n:28s} {s_disp:.3g} {u}")
    return lines


def _default(o):
    if isinstance(o, (np.floating, np.integer)):
        return o.item()
    if isinstance(o, np.ndarray):
        return o.tolist()
    if isinstance(o, Path):
        return str(o)
    raise TypeError(f"not JSON serializable: {type(o).__name__}")


def _clean(o):
    if isinstance(o, float) and not math.isfinite(o):
        return None
    if isinstance(o, dict):
        return {k: _clean(v) for k, v in o.items()}
    if isinstance(o, (list, tuple)):
        return [_clean(v) for v in o]
    return o


def write_json_atomic(path: Path, data: dict) -> Path:
    """Write JSON (NaN/inf as null) to a temp file, fsync, then replace ``path``."""
    path = Path(path)
    path.parent.mkdir(parents=True, exist_ok=True)
    text = json.dumps(_clean(json.loads(json.dumps(data, default=_default))), indent=2)
    fd, tmp = tempfile.mkstemp(dir=path.parent, prefix=f".{path.name}.", suffix=".tmp")
    try:
        with os.fdopen(fd, "w", encoding="utf-8") as fh:
            fh.write(text)
            fh.flush()
            os.fsync(fh.fileno())
        os.replace(tmp, path)
    except BaseException:
        if os.path.exists(tmp):
            os.unlink(tmp)
        raise
    return path
