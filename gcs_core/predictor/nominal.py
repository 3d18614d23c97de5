"""The predictor's nominal state: attitude along the plan, and when each sensor sees.

A predictor keeps the state "at its nominal values" (seed §3.2.2); only the geometry
matters. The nominal three-axis attitude is the reference-frame attitude with the
plan's maneuvers (Eq 4-4, 4-6, 4-35, 4-36)::

    C_BI(t) = T3(ψ(t)) T2(θ(t)) T1(φ(t)) A(t),   (φ, θ, ψ)(t) = (φ0, θ0, ψ0) + Δ(t)

with ``Δ(t)`` the maneuver offsets of :meth:`DataPlan.maneuver_offsets`. The nominal
body rate over a gyro interval is taken from two attitudes by Eq 4-33
(:func:`gcs_core.models.gyro.rate_from_quaternions`), which is what a gyro would read.

The predictor's attitude providers (:class:`~gcs_core.problem.attitude.ManeuverAttitude`,
:class:`~gcs_core.problem.attitude.BodyErrorAttitude`) live with the others.

Sensor availability (seed §4.3, "the times at which the data is available"):

* Sun sensors: in full sunlight — neither umbra nor penumbra of the conical shadow
  model (:func:`gcs_core.ephem.sun.sunlit_fraction` = 1; a partly hidden disk shifts
  the measured Sun centroid) — and the Sun inside the square field of view
  ``|atan(S_y/S_x)|, |atan(S_z/S_x)| ≤ fov`` (no margin);
* star trackers: the boresight (sensor +x) farther than ``earth_exclusion_deg``
  (default 10°) from the Earth limb and than ``sun_exclusion_deg`` (default 30°) from
  the Sun — data-book keys, kept by the mission reader as extra keys;
* plane-field Sun sensor and horizon scanner: in full sunlight (the horizon timing
  starts at the Sun sighting); whether the Sun crosses the slit and the scan cone crosses the
  Earth is the models' own ``valid`` flag;
* magnetometer, gyro: always.

Which star a tracker frame identifies (the star models) is :mod:`gcs_core.predictor.stars`.
"""

from __future__ import annotations

import numpy as np

from gcs_core.ephem.sun import earth_occults, sunlit_fraction
from gcs_core.frames.reference import spin_axis
from gcs_core.frames.rotations import euler123_to_dcm, quat_from_dcm
from gcs_core.io.types import SensorSpec
from gcs_core.models import common
from gcs_core.models.gyro import rate_from_quaternions
from gcs_core.problem.attitude import ReferenceAttitude
from gcs_core.units import DEG

#: default exclusion angles of a star tracker [deg] (typical FHST values)
EARTH_EXCLUSION_DEG = 10.0
SUN_EXCLUSION_DEG = 30.0
#: visible fraction of the solar disk that counts as full sunlight (round-off margin)
FULL_SUN = 1.0 - 1e-9


class PlanAttitude:
    """Reference attitude + maneuvers (three-axis) or a fixed spin axis (spinning).

    Parameters
    ----------
    mode : mission attitude mode.
    ephemeris : :class:`~gcs_core.ephem.ephemeris.Ephemeris`.
    plan : the :class:`~gcs_core.predictor.plan.DataPlan` (maneuvers).
    rpy0 : (3,) roll, pitch, yaw at ``plan.start`` [rad] (three-axis).
    spin_axis_I : (3,) unit spin axis (spinning).
    """

    def __init__(self, mode: str, ephemeris, plan, rpy0=(0.0, 0.0, 0.0), spin_axis_I=None):
        self.mode = mode
        self.ephemeris = ephemeris
        self.plan = plan
        self.rpy0 = np.asarray(rpy0, dtype=float)
        self.spin_axis_I = None if spin_axis_I is None else np.asarray(spin_axis_I, dtype=float)
        self.reference = ReferenceAttitude(mode, ephemeris) if mode != "spinning" else None

    @property
    def spinning(self) -> bool:
        return self.mode == "spinning"

    def rpy(self, t) -> np.ndarray:
        """(N, 3) nominal roll, pitch, yaw [rad] (Eq 4-36)."""
        return self.rpy0[None, :] + self.plan.maneuver_offsets(t)

    def dcm(self, t) -> np.ndarray:
        """(N, 3, 3) nominal ``C_BI`` (Eq 4-6)."""
        t = np.atleast_1d(np.asarray(t, dtype=float))
        a = self.rpy(t)
        assert self.reference is not None  # a three-axis plan (not spinning)
        return euler123_to_dcm(a[:, 0], a[:, 1], a[:, 2]) @ self.reference.reference(t)

    def mean_rates(self, knots) -> np.ndarray:
        """(K, 3) body rate averaged over each interval ``(τ_{k−1}, τ_k]`` (Eq 4-33)."""
        knots = np.asarray(knots, dtype=float)
        q = quat_from_dcm(self.dcm(knots))
        return rate_from_quaternions(q[:-1], q[1:], np.diff(knots))


# ----------------------------------------------------------------------------------------
def _alignment(sensor: SensorSpec) -> np.ndarray:
    a = np.zeros(3) if sensor.alignment_deg is None else np.asarray(sensor.alignment_deg) * DEG
    return euler123_to_dcm(*a)


def _book_deg(sensor: SensorSpec, key: str, default: float) -> float:
    value = common.book_scalar(sensor, key, default)
    return float(value) * DEG


def available(sensor: SensorSpec, t: np.ndarray, nominal: PlanAttitude) -> np.ndarray:
    """(N,) True where ``sensor`` can deliver a frame at ``t`` (module docstring)."""
    t = np.asarray(t, dtype=float)
    if t.size == 0 or sensor.type in ("magnetometer", "gyro"):
        return np.ones(t.shape, dtype=bool)
    eph = nominal.ephemeris
    r, _ = eph.state(t, what=f"the plan of {sensor.name}")
    s = eph.sun_geocentric(t, what=f"the plan of {sensor.name}")
    sun_hat = (s - r) / np.linalg.norm(s - r, axis=-1, keepdims=True)
    sunlit = sunlit_fraction(r, s) >= FULL_SUN
    if sensor.type in ("plane_field_sun", "horizon"):
        return sunlit
    M_C = _alignment(sensor)[None] @ nominal.dcm(t)  # GCI -> sensor
    if sensor.type in ("fine_sun", "coarse_sun"):
        S = np.einsum("nij,nj->ni", M_C, sun_hat)
        ok = S[:, 0] > 0.0
        fov = common.fov_rad(sensor)
        if fov is not None:
            ok &= (np.abs(np.arctan2(S[:, 1], S[:, 0])) <= fov) & (np.abs(np.arctan2(S[:, 2], S[:, 0])) <= fov)
        return ok & sunlit
    if sensor.type == "star_tracker":
        bore = M_C[:, 0, :]  # sensor +x in GCI
        earth_margin = _book_deg(sensor, "earth_exclusion_deg", EARTH_EXCLUSION_DEG)
        sun_margin = _book_deg(sensor, "sun_exclusion_deg", SUN_EXCLUSION_DEG)
        near_sun = np.einsum("ni,ni->n", bore, sun_hat) > np.cos(sun_margin)
        return ~earth_occults(r, bore, earth_margin) & ~near_sun
    return np.ones(t.shape, dtype=bool)


def nominal_spin_axis(ra_deg: float, dec_deg: float) -> np.ndarray:
    """(3,) Eq 4-2 from degrees."""
    return spin_axis(ra_deg * DEG, dec_deg * DEG)
