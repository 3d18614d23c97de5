"""Dirty telemetry (issue 5): misidentified stars and magnetometer spikes.

A simulated mission with 1 % star misidentifications on both trackers and 0.1 % single-
sample TAM spikes must calibrate to within 3σ of truth, with the bad frames flagged by the
k-σ editing (kept and shown, never silently dropped).

Truth is the simulator's answer file, read as in :mod:`test_truth_recovery` (the gyro bias
is a random walk, not the data-book constant). The fit uses ``method = "kalman"``, whose σ
carries the gyro noise (the batch's exact-gyro σ is optimistic on an hour of data).
"""

from __future__ import annotations

import csv
import json
from pathlib import Path

import numpy as np
import pytest
from test_truth_recovery import normalized_errors, truth_values

from gcs_core.config_schema import AnalysisConfig
from gcs_core.session import Analysis
from gcs_core.sim.scenarios import nominal_threeaxis, with_effect
from gcs_core.sim.writer import write_mission

three_sigma = 3.0
spike_nT = 3000.0  # a telemetry hit: 120 σ of the 25 nT TAM noise


def _inject_spikes(path: Path, fraction: float, rng: np.random.Generator) -> list[float]:
    """Add ``spike_nT`` to one component of a fraction of TAM rows; return their times."""
    rows = list(csv.reader(path.open()))
    header_at = next(i for i, r in enumerate(rows) if r and not r[0].startswith("#"))
    body = rows[header_at + 1 :]
    n = max(1, int(round(fraction * len(body))))
    picks = rng.choice(len(body), size=n, replace=False)
    times = []
    for k in picks:
        comp = 1 + int(rng.integers(0, 3))
        body[k][comp] = f"{float(body[k][comp]) + spike_nT * rng.choice([-1, 1]):.3f}"
        times.append(float(body[k][0]))
    with path.open("w", newline="") as fh:
        csv.writer(fh).writerows(rows[: header_at + 1] + body)
    return sorted(times)


@pytest.fixture(scope="module")
def dirty(tmp_path_factory):
    folder = tmp_path_factory.mktemp("dirty")
    cfg = nominal_threeaxis("sun_pointing", seed=7, duration_s=3600.0)
    for s in cfg.sensors:
        if s.type == "star_tracker":
            s.cadence_s = 1.0
    cfg = with_effect(cfg, "FHST1.misidentification", 0.01)
    cfg = with_effect(cfg, "FHST2.misidentification", 0.01)
    mission = write_mission(cfg, folder / "mission", truth_path=folder / "truth.json")
    spikes = _inject_spikes(mission / "telemetry" / "TAM1.csv", 0.001, np.random.default_rng(11))
    a = Analysis(AnalysisConfig(mission=mission, method="kalman"))
    a.fit(holdout=False)
    truth = json.loads((folder / "truth.json").read_text())
    return a, spikes, truth


def test_spikes_are_flagged_not_dropped(dirty):
    a, spikes, _ = dirty
    r = a.result.residuals["TAM1"]
    flagged_t = set(np.round(r.t[r.edited], 3))
    assert set(np.round(spikes, 3)) <= flagged_t
    assert len(r.t) == len(r.y)  # every frame is still there
    assert np.count_nonzero(r.edited) < 0.01 * r.t.size


def test_misidentified_stars_are_flagged(dirty):
    a, _, truth = dirty
    for name in ("FHST1", "FHST2"):
        r = a.result.residuals[name]
        n_bad = truth["sensors"][name].get("n_misidentified") or truth.get("counters", {}).get(name, {}).get(
            "n_misidentified"
        )
        flagged = int(np.count_nonzero(r.edited))
        assert flagged >= 1
        if n_bad:
            assert flagged >= 0.8 * n_bad, f"{name}: {flagged} flagged of {n_bad} misidentified"
        assert r.rms_normalized <= 1.05


def test_calibration_within_three_sigma_of_truth(dirty):
    """Every solve-for element, attitude included, within 3σ of the simulator's truth
    despite the dirty frames."""
    a, _, truth = dirty
    z = normalized_errors(a.result, truth_values(truth, a.problem, "kalman"))
    outside = {name: round(v, 2) for name, v in z.items() if abs(v) > three_sigma}
    assert not outside, f"outside 3σ of truth: {outside}"


@pytest.mark.parametrize("method", ["batch", "kalman"])
def test_editing_is_configurable_per_sensor(dirty, method):
    """``[filter.edit_k_sensor]``: k = 0 turns one sensor's editing (batch) or innovation
    gate (Kalman) off: its spikes stay in the fit and its RMS shows them; the other
    sensors are edited as before."""
    a, spikes, _ = dirty
    b = Analysis(a.config.with_changes(method=method, filter={"edit_k_sensor": {"TAM1": 0.0}}), mission=a.mission)
    b.fit(holdout=False)
    tam = b.result.residuals["TAM1"]
    assert not tam.edited.any()
    assert tam.rms_normalized > 2.0  # 3000 nT spikes left in
    assert b.result.residuals["FHST1"].edited.any()  # still edited at the global k
