"""Plain data objects for an imported mission (ICD §1, §3, §5, §6).

These are what the readers return and what the rest of GCS consumes; they carry no
I/O. Angles stay in the units of the ICD here (degrees where the key ends in
``_deg``); models convert to radians when they build their parameters.
"""

from __future__ import annotations

from collections.abc import Mapping
from dataclasses import dataclass, field
from datetime import datetime
from pathlib import Path
from typing import Any

import numpy as np

ATTITUDE_MODES = ("inertial", "earth_pointing", "sun_pointing", "spinning")
SENSOR_TYPES = (
    "magnetometer",
    "gyro",
    "star_tracker",
    "fine_sun",
    "coarse_sun",
    "plane_field_sun",
    "horizon",
    "attitude_reference",
)


@dataclass(frozen=True)
class Table:
    """One CSV file read per ICD §1.

    Attributes
    ----------
    path : the file it came from.
    t : (N,) seconds since the mission epoch, strictly increasing.
    columns : mapping column name -> (N,) float array, every column of the file
        (``t`` included; extra columns are kept).
    lines : (N,) 1-based line number of each kept row in the file, for messages.
    dropped_nan : rows dropped because a field was empty or ``nan``.
    dropped_duplicates : exact duplicate rows dropped (a packet received twice).
    """

    path: Path
    t: np.ndarray
    columns: Mapping[str, np.ndarray]
    lines: np.ndarray
    dropped_nan: int = 0
    dropped_duplicates: int = 0

    def __len__(self) -> int:
        return int(self.t.shape[0])

    def stack(self, names) -> np.ndarray:
        """Columns ``names`` side by side, shape (N, len(names))."""
        return np.column_stack([self.columns[n] for n in names]) if len(self) else np.zeros((0, len(names)))


@dataclass(frozen=True)
class SensorSpec:
    """One ``[[sensor]]`` table of mission.toml.

    Attributes
    ----------
    name : unique sensor name (telemetry files and reports use it).
    type : one of :data:`SENSOR_TYPES`.
    telemetry : path of the telemetry CSV, resolved against the mission directory.
    alignment_deg : ``[a1, a2, a3]`` with ``M = T3(a3) T2(a2) T1(a1)`` (ICD §2), or None.
    noise : 1-sigma random error per component in telemetry units, or None (gyro).
    book : every other data-book key of the table, values as floats or tuples of floats
        (e.g. ``bias``, ``scale``, ``coeff_alpha``, ``fov_deg``, ``tilt_deg``...).
    unknown_keys : keys kept but not known to the sensor type (reported, not ignored).
    """

    name: str
    type: str
    telemetry: Path
    alignment_deg: tuple[float, float, float] | None = None
    noise: float | None = None
    book: Mapping[str, Any] = field(default_factory=dict)
    unknown_keys: tuple[str, ...] = ()

    def get(self, key: str, default: Any = None) -> Any:
        return self.book.get(key, default)


@dataclass(frozen=True)
class MissionSpec:
    """mission.toml as read (ICD §3)."""

    root: Path
    name: str
    epoch: datetime  # UTC, timezone-aware
    attitude_mode: str
    ephemeris_file: Path | None
    sensors: tuple[SensorSpec, ...]
    spin_axis_guess_deg: tuple[float, float] | None = None
    aux_file: Path | None = None
    onboard_file: Path | None = None
    unknown_keys: tuple[str, ...] = ()
    #: a ground (laboratory) mission: the fixed position [km] given by
    #: ``[ephemeris] ground_position_km`` instead of an ephemeris file (docs/ground.md).
    ground_position_km: tuple[float, float, float] | None = None
    #: a ground mission's Earth rotation in the lab frame [rad/s] (``[ephemeris] latitude_deg``
    #: or ``earth_rate_rad_s``, docs/ground.md); None: left in the gyro's bias.
    earth_rate_rad_s: tuple[float, float, float] | None = None
    #: ``[orbit]``: two-line elements instead of an ephemeris file (gcs_core.ephem.tle)
    orbit_tle: Path | None = None
    orbit_frame: str = "teme"
    orbit_step_s: float = 10.0

    def sensor(self, name: str) -> SensorSpec:
        for s in self.sensors:
            if s.name == name:
                return s
        raise KeyError(name)
