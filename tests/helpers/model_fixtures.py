"""Synthetic sensors and geometries for the observation-model tests.

Every builder takes a seeded ``np.random.Generator`` and returns ``(model, geom, params)``
with parameters drawn near their data-book values and a geometry in which the model is
defined at every frame (Sun or star inside the field of view, horizon crossings that
exist). Nothing here is a reference value: these are inputs for self-consistency checks.
"""

from __future__ import annotations

from dataclasses import dataclass
from pathlib import Path

import numpy as np

from gcs_core import units
from gcs_core.frames.rotations import T1, T3, quat_to_dcm, rotvec_to_dcm
from gcs_core.io.types import SensorSpec
from gcs_core.models import make_model
from gcs_core.models.base import Geometry
from gcs_core.models.common import alignment_matrix

N_FRAMES = 8


def sensor(name: str, type_: str, *, alignment_deg=(0.0, 0.0, 0.0), noise=1.0, **book) -> SensorSpec:
    return SensorSpec(
        name=name,
        type=type_,
        telemetry=Path(f"telemetry/{name}.csv"),
        alignment_deg=tuple(alignment_deg),
        noise=noise,
        book=book,
    )


def random_unit(rng, n: int) -> np.ndarray:
    v = rng.normal(size=(n, 3))
    return v / np.linalg.norm(v, axis=1, keepdims=True)


def random_dcm(rng, n: int) -> np.ndarray:
    q = rng.normal(size=(n, 4))
    return quat_to_dcm(q / np.linalg.norm(q, axis=1, keepdims=True))


def unit_from_angles(a, b) -> np.ndarray:
    """Sensor-frame unit vector with ``tan α = y/x = tan a``, ``tan β = z/x = tan b``."""
    v = np.column_stack([np.ones_like(a), np.tan(a), np.tan(b)])
    return v / np.linalg.norm(v, axis=1, keepdims=True)


@dataclass(frozen=True)
class CircularOrbit:
    """Circular orbit and a Sun direction turning uniformly: ``t -> (r_I, v_I, sun_I)``.

    ``sun_rate`` is exaggerated in the tests (1e-4 rad/s instead of 2e-7) so that the
    Sun-motion terms of the horizon partials are exercised.
    """

    radius_km: float = 7000.0
    incl: float = 0.9
    raan: float = 0.4
    u0: float = 0.3
    sun0: tuple = (0.8, 0.5, 0.33)
    sun_rate: float = 1e-4

    @property
    def mean_motion(self) -> float:
        return np.sqrt(units.MU_EARTH / self.radius_km**3)

    @property
    def normal(self) -> np.ndarray:
        R = T1(self.incl) @ T3(self.raan)  # GCI -> orbit plane frame
        return R.T @ np.array([0.0, 0.0, 1.0])

    def __call__(self, t):
        t = np.asarray(t, dtype=float)
        u = self.u0 + self.mean_motion * t
        R = T1(self.incl) @ T3(self.raan)
        p = np.column_stack([np.cos(u), np.sin(u), np.zeros_like(u)])
        dp = np.column_stack([-np.sin(u), np.cos(u), np.zeros_like(u)])
        r = self.radius_km * p @ R
        v = self.radius_km * self.mean_motion * dp @ R
        s0 = np.array(self.sun0) / np.linalg.norm(self.sun0)
        axis = np.cross(s0, [0.0, 0.0, 1.0])
        axis /= np.linalg.norm(axis)
        rot = rotvec_to_dcm(-np.outer(self.sun_rate * t, axis))  # rotate s0 by +rate t about axis
        return r, v, rot @ s0


def dipole_field(t, r_I):
    """A tilted-dipole field [nT] (about 30 000 nT at 7000 km), a stand-in for IGRF."""
    r_I = np.asarray(r_I, dtype=float)
    m = np.array([0.05, -0.1, -0.99])
    m /= np.linalg.norm(m)
    rn = np.linalg.norm(r_I, axis=1, keepdims=True)
    rh = r_I / rn
    B0 = 30000.0 * (units.R_EARTH_KM / rn) ** 3 * 1.3
    return B0 * (3.0 * np.sum(m * rh, axis=1, keepdims=True) * rh - m)


def _times(rng, n):
    return np.sort(rng.uniform(0.0, 6000.0, n))


def _aligned(rng, spread_deg=2.0):
    return tuple(rng.uniform(-spread_deg, spread_deg, 3))


def _jitter_alignment(rng, model, params, rad=2e-3):
    for name in ("align_1", "align_2", "align_3"):
        params[name] = model.nominal()[name] + rng.uniform(-rad, rad)


def _pointing(rng, params, S_S_target, v_I_of_C=None):
    """Random C_BI and the inertial vector that lands on ``S_S_target`` in sensor axes."""
    n = S_S_target.shape[0]
    M, _ = alignment_matrix(params)
    C = random_dcm(rng, n)
    v_B = S_S_target @ M  # Mᵀ S_S (row form)
    v_I = np.einsum("nji,nj->ni", C, v_B)  # Cᵀ v_B
    return C, v_I


# --------------------------------------------------------------------------------------
def magnetometer_case(rng, n=N_FRAMES):
    model = make_model(
        sensor("TAM1", "magnetometer", alignment_deg=_aligned(rng), noise=25.0, bias=tuple(rng.uniform(-50, 50, 3))),
        aux_channels=("mtb_x", "tam_temp"),
    )
    orbit = CircularOrbit()
    t = _times(rng, n)
    r, v, _ = orbit(t)
    geom = Geometry(
        t=t,
        C_BI=random_dcm(rng, n),
        r_I=r,
        v_I=v,
        B_I=dipole_field(t, r),
        omega_B=rng.normal(scale=2e-3, size=(n, 3)),
        aux={"mtb_x": rng.uniform(-60, 60, n), "tam_temp": rng.uniform(10, 30, n)},
        field_model=dipole_field,
    )
    params = {f"bias_{a}": rng.uniform(-200, 200) for a in "xyz"}
    _jitter_alignment(rng, model, params)
    params.update({f"scale_{a}": rng.uniform(-2e-3, 2e-3) for a in "xyz"})
    params.update({k: rng.uniform(-2e-3, 2e-3) for k in ("nonorth_xy", "nonorth_xz", "nonorth_yz")})
    params.update({f"contam_{ch}_{a}": rng.uniform(-5, 5) for ch in ("mtb_x", "tam_temp") for a in "xyz"})
    params["time_offset"] = rng.uniform(-0.5, 0.5)
    return model, geom, params


def star_tracker_case(rng, n=N_FRAMES):
    fov = 4.0
    model = make_model(
        sensor(
            "FHST1",
            "star_tracker",
            alignment_deg=(rng.uniform(-180, 180), 30.0, 90.0),
            noise=3.9e-5,
            scale=(1.0, 1.0),
            fov_deg=fov,
        )
    )
    params = {
        "scale_h": 1.0 + rng.uniform(-1e-3, 1e-3),
        "scale_v": 1.0 + rng.uniform(-1e-3, 1e-3),
        "time_offset": rng.uniform(-0.3, 0.3),
    }
    _jitter_alignment(rng, model, params)
    p = {**model.nominal(), **params}
    lim = 0.7 * fov * units.DEG
    C, star_I = _pointing(rng, p, unit_from_angles(rng.uniform(-lim, lim, n), rng.uniform(-lim, lim, n)))
    geom = Geometry(t=_times(rng, n), C_BI=C, star_I=star_I, omega_B=rng.normal(scale=1e-3, size=(n, 3)))
    return model, geom, params


def fine_sun_case(rng, n=N_FRAMES):
    fov = 32.0
    model = make_model(
        sensor(
            "FSS1",
            "fine_sun",
            alignment_deg=_aligned(rng),
            noise=0.577,
            fov_deg=fov,
            coeff_alpha=(0.01, 7.6e-5, 0.002, 50.0),
            coeff_beta=(-0.02, 7.7e-5, 0.003, 45.0),
        )
    )
    params = {
        "A1": 0.01 + rng.uniform(-1e-3, 1e-3),
        "A2": 7.6e-5 * (1 + rng.uniform(-1e-3, 1e-3)),
        "A3": rng.uniform(-3e-3, 3e-3),
        "k_alpha": 50.0 + rng.uniform(-2, 2),
        "B1": -0.02 + rng.uniform(-1e-3, 1e-3),
        "B2": 7.7e-5 * (1 + rng.uniform(-1e-3, 1e-3)),
        "B3": rng.uniform(-3e-3, 3e-3),
        "k_beta": 45.0 + rng.uniform(-2, 2),
        "A4h": rng.uniform(-1e-3, 1e-3),
        "B4h": rng.uniform(-1e-3, 1e-3),
        "time_offset": rng.uniform(-0.3, 0.3),
    }
    _jitter_alignment(rng, model, params)
    p = {**model.nominal(), **params}
    lim = 0.7 * fov * units.DEG
    C, sun_I = _pointing(rng, p, unit_from_angles(rng.uniform(-lim, lim, n), rng.uniform(-lim, lim, n)))
    geom = Geometry(t=_times(rng, n), C_BI=C, sun_I=sun_I, omega_B=rng.normal(scale=1e-3, size=(n, 3)))
    return model, geom, params


def coarse_sun_case(rng, n=N_FRAMES):
    fov = 60.0
    K = 4.3633231e-3
    model = make_model(
        sensor(
            "CSS1",
            "coarse_sun",
            alignment_deg=_aligned(rng),
            noise=0.577,
            fov_deg=fov,
            scale=(K, K * 1.01),
            bias=(0.001, -0.002),
        )
    )
    params = {
        "K_alpha": K * (1 + rng.uniform(-0.01, 0.01)),
        "K_beta": K * (1 + rng.uniform(-0.01, 0.01)),
        "b_alpha": rng.uniform(-0.01, 0.01),
        "b_beta": rng.uniform(-0.01, 0.01),
        "time_offset": rng.uniform(-0.3, 0.3),
    }
    _jitter_alignment(rng, model, params)
    p = {**model.nominal(), **params}
    lim = 0.7 * fov * units.DEG
    C, sun_I = _pointing(rng, p, unit_from_angles(rng.uniform(-lim, lim, n), rng.uniform(-lim, lim, n)))
    geom = Geometry(t=_times(rng, n), C_BI=C, sun_I=sun_I, omega_B=rng.normal(scale=1e-3, size=(n, 3)))
    return model, geom, params


def _sun_with_angle(rng, A, lo_deg, hi_deg, n):
    """Unit vectors making an angle in [lo, hi] degrees with the unit axis A."""
    beta = rng.uniform(lo_deg, hi_deg, n) * units.DEG
    perp = np.cross(A, random_unit(rng, n))
    perp /= np.linalg.norm(perp, axis=1, keepdims=True)
    return np.cos(beta)[:, None] * A + np.sin(beta)[:, None] * perp


def plane_field_sun_case(rng, n=N_FRAMES):
    model = make_model(sensor("PFSS", "plane_field_sun", noise=1e-3, tilt_deg=1.5, bias=0.002))
    A = random_unit(rng, 1)[0]
    sun = _sun_with_angle(rng, np.broadcast_to(A, (n, 3)), 30.0, 150.0, n)
    geom = Geometry(t=_times(rng, n), spin_axis_I=A * 1.0, sun_I=sun)
    params = {"tilt": rng.uniform(-3.0, 3.0) * units.DEG, "bias": rng.uniform(-0.01, 0.01)}
    return model, geom, params


def horizon_case(rng, n=N_FRAMES, observable="in_out"):
    """Spinner in a 7000 km circular orbit, spin axis within 20° of the orbit normal."""
    orbit = CircularOrbit(sun0=tuple(random_unit(rng, 1)[0]))
    model = make_model(
        sensor(
            "HS1",
            "horizon",
            noise=2e-3,
            gamma_deg=rng.uniform(75.0, 95.0),
            phi_h_deg=rng.uniform(0.0, 360.0),
            horizon_height_km=40.0,
            sun_sensor="PFSS",
            observable=observable,
        )
    )
    tilt = rotvec_to_dcm(rng.normal(size=3) * (10.0 * units.DEG / np.sqrt(3.0)))
    A = tilt @ orbit.normal
    # sighting times at which the Sun angle stays within 35°..145° of the spin axis
    t = np.sort(rng.uniform(0.0, 6000.0, 4 * n))
    _, _, s = orbit(t)
    keep = np.abs(s @ A) < np.cos(35.0 * units.DEG)
    t = t[keep][:n]
    if t.size < 2:  # Sun too close to the axis for this draw: move the axis off it
        return horizon_case(rng, n, observable)
    geom = Geometry(t=t, spin_axis_I=A, ephemeris=orbit, extra={"spin_rate": rng.uniform(1.0, 2.0, t.size)})
    deg = units.DEG
    params = {
        "d_gamma": rng.uniform(-0.5, 0.5) * deg,
        "d_rho": rng.uniform(-0.3, 0.3) * deg,
        "d_phi": rng.uniform(-1, 1) * deg,
        "eps_S": rng.uniform(-1, 1) * deg,
        "eps_H": rng.uniform(-1, 1) * deg,
        "d_t": rng.uniform(-5, 5),
        "horizon_height": rng.uniform(-3, 3),
        "oblateness": rng.uniform(0.0, 1.5),
    }
    return model, geom, params


def horizon_width_midscan_case(rng, n=N_FRAMES):
    return horizon_case(rng, n, observable="width_midscan")


def gyro_case(rng, n=N_FRAMES):
    model = make_model(
        sensor(
            "IRU",
            "gyro",
            alignment_deg=_aligned(rng),
            noise=None,
            arw=3.2e-7,
            rrw=3.2e-10,
            bias=tuple(rng.uniform(-1e-5, 1e-5, 3)),
        )
    )
    params = {f"G_{i}{j}": rng.uniform(-2e-3, 2e-3) for i in range(1, 4) for j in range(1, 4)}
    params.update({f"bias_{a}": rng.uniform(-2e-5, 2e-5) for a in "xyz"})
    _jitter_alignment(rng, model, params)
    geom = Geometry(t=_times(rng, n), omega_B=rng.normal(scale=1e-2, size=(n, 3)))
    return model, geom, params


def attitude_reference_case(rng, n=N_FRAMES):
    model = make_model(sensor("MOCAP", "attitude_reference", alignment_deg=_aligned(rng), noise=1e-3))
    params = {"time_offset": rng.uniform(-0.05, 0.05)}
    _jitter_alignment(rng, model, params)
    geom = Geometry(t=_times(rng, n), C_BI=random_dcm(rng, n), omega_B=rng.normal(scale=1.0, size=(n, 3)))
    return model, geom, params


def magnetometer_constant_field_case(rng, n=N_FRAMES):
    model = make_model(
        sensor("MAG", "magnetometer", alignment_deg=_aligned(rng), noise=300.0, bias=tuple(rng.uniform(-500, 500, 3))),
        constant_field=True,
    )
    t = _times(rng, n)
    geom = Geometry(t=t, C_BI=random_dcm(rng, n), B_I=np.zeros((n, 3)), omega_B=rng.normal(scale=1.0, size=(n, 3)))
    params = {f"bias_{a}": rng.uniform(-2000, 2000) for a in "xyz"}
    params.update({f"field_{a}": v for a, v in zip("xyz", (300.0, 17000.0, -45000.0))})
    _jitter_alignment(rng, model, params)
    params.update({f"scale_{a}": rng.uniform(-2e-2, 2e-2) for a in "xyz"})
    params["time_offset"] = rng.uniform(-0.02, 0.02)
    return model, geom, params


def magnetometer_field_gradient_case(rng, n=N_FRAMES):
    """A lab magnetometer carried through a non-uniform field: the position channels give
    the gradient its lever (and no contamination terms); a temperature channel keeps its own."""
    model = make_model(
        sensor("MAG", "magnetometer", alignment_deg=_aligned(rng), noise=300.0, bias=tuple(rng.uniform(-500, 500, 3))),
        aux_channels=("pos_x", "pos_y", "pos_z", "temp"),
        constant_field=True,
    )
    t = _times(rng, n)
    aux = {c: rng.uniform(-0.4, 0.4, n) for c in ("pos_x", "pos_y", "pos_z")}
    aux["temp"] = rng.uniform(10, 30, n)
    geom = Geometry(
        t=t, C_BI=random_dcm(rng, n), B_I=np.zeros((n, 3)), aux=aux, omega_B=rng.normal(scale=1.0, size=(n, 3))
    )
    params = {f"bias_{a}": rng.uniform(-2000, 2000) for a in "xyz"}
    params.update({f"field_{a}": v for a, v in zip("xyz", (300.0, 17000.0, -45000.0))})
    params.update({f"gradient_{ab}": rng.uniform(-5000, 5000) for ab in ("xx", "xy", "xz", "yy", "yz")})
    params.update({f"contam_temp_{a}": rng.uniform(-20, 20) for a in "xyz"})
    _jitter_alignment(rng, model, params)
    params.update({f"scale_{a}": rng.uniform(-2e-2, 2e-2) for a in "xyz"})
    params["time_offset"] = rng.uniform(-0.02, 0.02)
    return model, geom, params


CASES = {
    "magnetometer_field_gradient": magnetometer_field_gradient_case,
    "attitude_reference": attitude_reference_case,
    "magnetometer_constant_field": magnetometer_constant_field_case,
    "magnetometer": magnetometer_case,
    "star_tracker": star_tracker_case,
    "fine_sun": fine_sun_case,
    "coarse_sun": coarse_sun_case,
    "plane_field_sun": plane_field_sun_case,
    "horizon": horizon_case,
    "horizon_width_midscan": horizon_width_midscan_case,
    "gyro": gyro_case,
}
