"""Simulated missions with one hidden drift no catalogue effect holds (issue 26).

Each kind is the sensor's own physics in the simulator (:mod:`gcs_core.sim.drifts`): a
tracker's optics bending with the bench temperature or over the orbit, a Sun sensor's
offset and a magnetometer's gains following the temperature, and a tracker error following
the star's magnitude (a form no family holds), and the gyro's drift-rate bias stepping while
its heater is on (the aux channel ``iru_heater``, a thermostat's duty cycle). :func:`run_case` simulates, runs discovery
with the default whole-span method, and returns what the acceptance checks need.
"""

from __future__ import annotations

from dataclasses import dataclass, field
from pathlib import Path

import numpy as np
from discovery_cases import scenario

from gcs_core.config_schema import AnalysisConfig
from gcs_core.diagnosis.families import channel_of
from gcs_core.session import Analysis
from gcs_core.sim._rot import dcm_to_rpy, rotvec_to_dcm, rpy_to_dcm
from gcs_core.sim.scenarios import ORBIT_BEND_PHASE, with_effect
from gcs_core.sim.writer import write_mission

ARCSEC = np.radians(1.0 / 3600.0)
DEG_PER_HOUR = np.radians(1.0) / 3600.0
#: the gyro's bias step with its heater on: 0.05 °/h along (0.6, −0.48, 0.64) (sim/scenarios.py)
HEATER_STEP = 0.05 * DEG_PER_HOUR
HEATER_PATTERN = (0.6, -0.48, 0.64)


@dataclass(frozen=True)
class DriftCase:
    """One kind: the hidden effect id and magnitude, the sensor and channel(s) expected."""

    kind: str
    effect: str
    magnitude: float
    sensor: str
    channels: tuple[str, ...]  # search channels the first effect may be made on
    options: dict = field(default_factory=dict)

    @property
    def id(self) -> str:
        return self.kind


KINDS = [
    DriftCase(
        "tracker_temperature",
        "FHST2.alignment_vs_tam_temp",
        4.0 * ARCSEC,
        "FHST2",
        ("aux:tam_temp", "orbit_phase"),
        {"axis": (0.0, 1.0, 0.0)},
    ),
    DriftCase("tracker_orbit", "FHST2.alignment_vs_orbit1", 10.0 * ARCSEC, "FHST2", ("orbit_phase",)),
    DriftCase("sun_sensor_bias_temperature", "FSS1.bias_vs_tam_temp", 3e-5, "FSS1", ("aux:tam_temp", "orbit_phase")),
    DriftCase(
        "magnetometer_scale_temperature", "TAM1.scale_vs_tam_temp", 1e-3, "TAM1", ("aux:tam_temp", "orbit_phase")
    ),
    DriftCase("gyro_heater", "IRU.bias_vs_iru_heater", HEATER_STEP, "IRU", ("aux:iru_heater",)),
]
#: the form no family holds: the report must name the channel and add nothing
MAGNITUDE = DriftCase("tracker_magnitude", "FHST2.magnitude_error", 4.0 * ARCSEC, "FHST2", ("tlm:mag",))


def simulate(case: DriftCase | None, seed: int, folder: Path, hours: float) -> Path:
    base = scenario("sun_pointing", seed, hours * 3600.0)
    cfg = base if case is None else with_effect(base, case.effect, case.magnitude, **case.options)
    return write_mission(cfg, folder / "mission", truth_path=folder / "truth.json")


def analyse(mission: Path, method: str = "whole_span") -> Analysis:
    a = Analysis(AnalysisConfig(mission=mission, method=method))
    a.fit()
    a.discover()
    return a


def true_slopes(case: DriftCase, analysis: Analysis) -> dict[str, float]:
    """element -> its true value for the family on the right channel (aux channels only)."""
    sensor = case.sensor
    if case.kind == "tracker_temperature":
        book = analysis.mission.spec.sensor(sensor).alignment_deg or (0.0, 0.0, 0.0)
        M = rpy_to_dcm(*np.radians(np.asarray(book, dtype=float)))
        axis = np.asarray(case.options["axis"], dtype=float)

        def rpy(dT: float) -> np.ndarray:
            return np.asarray(dcm_to_rpy(rotvec_to_dcm(case.magnitude * dT * axis) @ M))

        d = (rpy(0.5) - rpy(-0.5)) / 1.0
        return {f"{sensor}.align_{i + 1}_vs_tam_temp": float(d[i]) for i in range(3)}
    if case.kind == "tracker_orbit":
        # the simulator's tilt A sin(u + φ) about its axis (sim/scenarios.py: φ = 0.7 rad, axis y)
        # = A sin φ cos u + A cos φ sin u: each harmonic's coefficient times the change of the
        # alignment's angles per radian turned about the axis
        book = analysis.mission.spec.sensor(sensor).alignment_deg or (0.0, 0.0, 0.0)
        M = rpy_to_dcm(*np.radians(np.asarray(book, dtype=float)))
        axis = np.asarray(case.options.get("axis", (0.0, 1.0, 0.0)), dtype=float)
        eps = ARCSEC
        g = (
            np.asarray(dcm_to_rpy(rotvec_to_dcm(eps * axis) @ M))
            - np.asarray(dcm_to_rpy(rotvec_to_dcm(-eps * axis) @ M))
        ) / (2 * eps)
        phase = ORBIT_BEND_PHASE
        out = {}
        for i in range(3):
            out[f"{sensor}.align_{i + 1}_vs_orbit1_cos"] = float(case.magnitude * np.sin(phase) * g[i])
            out[f"{sensor}.align_{i + 1}_vs_orbit1_sin"] = float(case.magnitude * np.cos(phase) * g[i])
        return out
    if case.kind == "sun_sensor_bias_temperature":
        return {f"{sensor}.A1_vs_tam_temp": case.magnitude, f"{sensor}.B1_vs_tam_temp": -0.6 * case.magnitude}
    if case.kind == "gyro_heater":
        return {f"{sensor}.bias_{ax}_vs_iru_heater": case.magnitude * p for ax, p in zip("xyz", HEATER_PATTERN)}
    if case.kind == "magnetometer_scale_temperature":
        return {f"{sensor}.scale_{ax}_vs_tam_temp": case.magnitude * p for ax, p in zip("xyz", (1.0, -0.7, 0.5))}
    return {}


def outcome(case: DriftCase, analysis: Analysis) -> dict:
    """What the acceptance asks of one run: the first effect's sensor and channel, any effect
    on another sensor, the worst normalized RMS fitted and held-out, the elements' z."""
    added = [s.effect for s in analysis.steps if s.action == "add" and s.effect]
    first = added[0] if added else None
    first_sensor = first.split(".", 1)[0] if first else None
    first_channel = channel_of(first.split(".", 1)[1]) if first else None
    others = [e for e in added if not e.startswith(case.sensor + ".")]
    z = {}
    res = analysis.result
    for name, truth in true_slopes(case, analysis).items():
        if res is not None and name in res.sigma and res.sigma[name] > 0:
            z[name] = (res.state[name].value - truth) / res.sigma[name]
    return {
        "added": added,
        "right_sensor_channel": first_sensor == case.sensor and first_channel in case.channels,
        "other_sensors": others,
        "rms": max(analysis.rms().values()),
        "holdout_rms": max(analysis.holdout_rms.values()) if analysis.holdout_rms else float("nan"),
        "z": z,
    }
