"""What a simulated mission is made of: plain dataclasses (see scenarios.py for builders).

A sensor carries two sets of values:

* ``book``: the data-book keys of ICD §5 (``alignment_deg``, ``noise``, ``bias``,
  ``scale``, ``coeff_alpha``...), written to mission.toml: what the team believes;
* ``true``: overrides of those keys used to simulate, plus the physics the book does
  not mention (``misalignment_rad``, ``response`` (TAM 3×3), ``G`` (gyro 3×3),
  ``contamination`` ({channel: (3,)}), ``time_offset_s``, ``harmonic`` (FSS second
  harmonic per axis), ``misid_fraction``, horizon ``d_gamma, d_phi, d_rho, eps_H,
  flattening_excess`` (in units of the WGS-84 flattening), star-tracker exclusion angles...).

Mission-wide physics (aberrations, solar parallax) is real by default
(:data:`REAL_PHYSICS`), like the data of a real spacecraft.

A *hidden effect* is any difference between truth and book, or physics the book does
not mention; each one is recorded as a :class:`HiddenEffect` so the answer file
(truth.json) can list it with the id ``<SENSOR>.<effect>`` or ``model.<effect>``.
"""

from __future__ import annotations

import copy
from dataclasses import dataclass, field
from typing import Any

import numpy as np

THREE_AXIS_MODES = ("inertial", "earth_pointing", "sun_pointing")
ATTITUDE_MODES = THREE_AXIS_MODES + ("spinning",)
SENSOR_TYPES = ("magnetometer", "gyro", "star_tracker", "fine_sun", "coarse_sun", "plane_field_sun", "horizon")
#: physics present in real data; a switch turned off gives data without it.
REAL_PHYSICS = {"stellar_aberration": True, "solar_aberration": True, "sun_parallax": True, "earth_oblateness": True}

__all__ = [
    "OrbitElements",
    "Slew",
    "ThreeAxisProfile",
    "SpinProfile",
    "AuxConfig",
    "OnboardConfig",
    "SensorConfig",
    "HiddenEffect",
    "MissionConfig",
    "THREE_AXIS_MODES",
    "ATTITUDE_MODES",
    "SENSOR_TYPES",
    "REAL_PHYSICS",
]


@dataclass
class OrbitElements:
    """Mean Keplerian elements at the epoch (propagated with secular J2, orbit.py)."""

    a_km: float = 6898.137
    """semi-major axis [km] (520 km altitude by default)."""
    e: float = 0.0012
    """eccentricity."""
    i_deg: float = 28.5
    """inclination [deg]."""
    raan_deg: float = 35.0
    """right ascension of the ascending node at the epoch [deg]."""
    argp_deg: float = 60.0
    """argument of perigee at the epoch [deg]."""
    mean_anomaly_deg: float = 10.0
    """mean anomaly at the epoch [deg]."""


@dataclass
class Slew:
    """A constant-rate maneuver about one Euler axis (Eq 4-35, 4-36).

    The angle grows as ``φ = φ0 + φ̇ (t − t_start)``; the rate is switched on and off
    with raised-cosine ramps of ``ramp_s`` seconds so body rates stay continuous. The
    total turn is ``rate_deg_s * duration_s``.
    """

    t_start: float
    """start of the maneuver [s]."""
    duration_s: float
    """length of the maneuver, ramps included [s]."""
    axis: str
    """'roll', 'pitch' or 'yaw'."""
    rate_deg_s: float
    """plateau rate [deg/s]."""
    ramp_s: float = 20.0
    """length of each raised-cosine ramp [s]."""


@dataclass
class ThreeAxisProfile:
    """Roll, pitch, yaw relative to the reference frame (Eq 4-4, 4-6), as functions of time.

    ``rpy(t) = rpy0 + drift t + Σ_axis wobble_amp sin(2π t / wobble_period + phase) + slews``
    """

    rpy0_deg: tuple[float, float, float] = (0.0, 0.0, 0.0)
    """initial roll, pitch, yaw [deg]."""
    drift_deg_s: tuple[float, float, float] = (0.0, 0.0, 0.0)
    """constant drift of roll, pitch, yaw [deg/s]."""
    wobble_amp_deg: tuple[float, float, float] = (0.05, 0.04, 0.06)
    """amplitude of the slow sinusoidal motion per axis [deg]."""
    wobble_period_s: tuple[float, float, float] = (1100.0, 1530.0, 870.0)
    """period of the slow motion per axis [s]."""
    wobble_phase_rad: tuple[float, float, float] = (0.3, 1.9, 4.1)
    """phase of the slow motion per axis [rad]."""
    slews: list[Slew] = field(default_factory=list)
    """maneuvers (Eq 4-36)."""


@dataclass
class SpinProfile:
    """A spinner: fixed spin axis ``Â`` (Eq 4-2) and spin phase ``φ(t) = φ0 + ω t + ω̇ t²/2``.

    Body axes: ``z_B = Â``; ``x_B`` at phase 0 is ``ẑ_GCI × Â`` normalized; the body
    turns right-handed about ``Â``: ``C_BI = T3(φ) A`` with rows of ``A`` the
    phase-0 body axes.
    """

    ra_deg: float = 303.5
    """right ascension of the spin axis [deg]."""
    dec_deg: float = -25.5
    """declination of the spin axis [deg]."""
    rate_rpm: float = 10.0
    """spin rate [rev/min]."""
    phase0_deg: float = 0.0
    """spin phase at the epoch [deg]."""
    rate_dot_rad_s2: float = 0.0
    """spin-rate drift [rad/s²]."""
    guess_error_deg: tuple[float, float] = (0.6, -0.4)
    """pre-launch guess minus truth (RA, Dec) for mission.toml's spin_axis_guess_deg."""


@dataclass
class AuxConfig:
    """Auxiliary channels (ICD §6): torquer dipoles and a magnetometer temperature."""

    cadence_s: float = 1.0
    """row spacing of aux.csv [s]; switch times are multiples of it."""
    mtb_levels: tuple[float, ...] = (-60.0, 0.0, 60.0)
    """possible torquer dipoles [A m²]."""
    mtb_dwell_s: tuple[float, float] = (120.0, 900.0)
    """shortest and longest time between switches [s]."""
    temp_mean_c: float = 22.0
    """tam_temp mean [°C]."""
    temp_amp_c: float = 3.0
    """tam_temp amplitude [°C]."""
    temp_period_s: float = 5700.0
    """tam_temp period [s] (about one orbit)."""
    heater: bool = False
    """write the IRU heater's on/off channel ``iru_heater`` (a thermostat, drifts.py)."""


@dataclass
class OnboardConfig:
    """Onboard attitude (ICD §6): the truth rotated by an injected error, plus noise."""

    cadence_s: float = 10.0
    """row spacing [s]."""
    error_deg: tuple[float, float, float] = (0.05, 0.0, 0.0)
    """constant body-frame rotation vector [deg]: ``C_onboard = exp(−[δ×]) C_true``."""
    noise_arcsec: float = 2.0
    """1-sigma random rotation per axis [arcsec]."""


@dataclass
class HiddenEffect:
    """One difference between truth and data book, listed in truth.json."""

    id: str
    """``<SENSOR>.<effect>`` or ``model.<effect>``."""
    magnitude: float
    """size of the effect in ``unit``."""
    unit: str
    """unit of ``magnitude``."""
    description: str = ""
    """one line for humans."""


@dataclass
class SensorConfig:
    """One simulated sensor: data book (written) and truth (used)."""

    name: str
    """unique name; the telemetry file is telemetry/<name>.csv."""
    type: str
    """one of :data:`SENSOR_TYPES`."""
    cadence_s: float
    """sample spacing [s] (ignored by spinner sensors: one sample per spin)."""
    book: dict[str, Any]
    """ICD §5 data-book keys, in the order they are written to mission.toml."""
    true: dict[str, Any] = field(default_factory=dict)
    """true values: book-key overrides and unwritten physics (see module docstring)."""

    def value(self, key: str, default: Any = None) -> Any:
        """True value of ``key``: the override if any, else the data-book value."""
        if key in self.true:
            return self.true[key]
        return self.book.get(key, default)


@dataclass
class MissionConfig:
    """A whole simulated mission."""

    name: str
    """mission name (mission.toml and the directory name)."""
    epoch: str
    """UTC epoch, ISO 8601 with Z."""
    attitude_mode: str
    """inertial | earth_pointing | sun_pointing | spinning."""
    duration_s: float
    """span of the data [s]."""
    orbit: OrbitElements = field(default_factory=OrbitElements)
    """truth orbit."""
    attitude: ThreeAxisProfile | SpinProfile = field(default_factory=ThreeAxisProfile)
    """truth attitude profile."""
    sensors: list[SensorConfig] = field(default_factory=list)
    """sensor inventory."""
    aux: AuxConfig | None = field(default_factory=AuxConfig)
    """auxiliary channels, or None."""
    onboard: OnboardConfig | None = field(default_factory=OnboardConfig)
    """onboard attitude, or None."""
    seed: int = 1
    """master seed: same seed, same files."""
    ephemeris_cadence_s: float = 30.0
    """ephemeris.csv row spacing [s] (ICD §4: 60 s or finer)."""
    catalog_seed: int = 20240320
    """seed of the synthetic star catalog (shared by all missions)."""
    physics: dict[str, bool] = field(default_factory=lambda: dict(REAL_PHYSICS))
    """always-on physics in the data (the real world by default): ``stellar_aberration``
    (stars shifted by (v_earth + v_sc)/c), ``solar_aberration`` (Sun shifted by v_sc/c),
    ``sun_parallax`` (Sun seen from the spacecraft, s − r, instead of the Earth's centre),
    ``earth_oblateness`` (horizon scanners see the WGS-84 ellipsoid under the CO2 layer,
    crossed exactly at each scan's own tangent point, not the ICD's sphere)."""
    ephemeris_time_error_s: float = 0.0
    """in-track timing error Δt of the written ephemeris: row t holds the orbit at t − Δt."""
    chunk_s: float = 21600.0
    """time span simulated and written per chunk (bounded memory)."""
    effects: list[HiddenEffect] = field(default_factory=list)
    """hidden effects, for truth.json."""

    def sensor(self, name: str) -> SensorConfig:
        for s in self.sensors:
            if s.name == name:
                return s
        raise KeyError(name)

    def copy(self) -> MissionConfig:
        return copy.deepcopy(self)

    @property
    def spinning(self) -> bool:
        return self.attitude_mode == "spinning"


def as_plain(value: Any) -> Any:
    """JSON-friendly copy (numpy arrays and tuples to lists)."""
    if isinstance(value, dict):
        return {str(k): as_plain(v) for k, v in value.items()}
    if isinstance(value, (list, tuple)):
        return [as_plain(v) for v in value]
    if isinstance(value, np.ndarray):
        return as_plain(value.tolist())
    if isinstance(value, (np.floating, np.integer, np.bool_)):
        return value.item()
    return value
