"""Statistical consistency of the Kalman filter (NEES, NIS) on simulated missions.

A small simulator of our own (no dependency on ``gcs_core.sim``) builds in-memory
missions in the ICD's shape: a 1 Hz gyro (Eq 4-32 with scale/misalignment, a
random-walking drift bias, angle random walk), one or two star trackers (Eq 4-29/4-30,
scale factors) and a circular orbit. Every solve-for element's truth is *drawn from its
a priori*, so that a consistent filter gives normalized errors ~ N(0, 1):

* NEES ``eᵀ P⁻¹ e`` of the final filtered state, summed over seeded Monte-Carlo runs,
  lies in its two-sided 95 % χ² band (n·runs degrees of freedom);
* the same for the smoothed state at the reference time (the :class:`FilterResult`);
* NIS summed over every frame of every run lies in its 95 % χ² band.

Reference: Bar-Shalom, Li & Kirubarajan, *Estimation with Applications to Tracking and
Navigation*, Wiley 2001, §5.4 (NEES/NIS tests over Monte-Carlo runs).
"""

from __future__ import annotations

from dataclasses import dataclass
from datetime import UTC, datetime
from pathlib import Path

import numpy as np
import pytest
from scipy import stats

from gcs_core import units
from gcs_core.estimators.kalman.options import FilterOptions
from gcs_core.estimators.kalman.stepping import Filtr
from gcs_core.frames.rotations import T1, T2, T3, dcm_to_rotvec, euler123_to_dcm, rotvec_to_dcm
from gcs_core.io.importer import ImportedMission
from gcs_core.io.types import MissionSpec, SensorSpec, Table
from gcs_core.problem.build import StateOptions, build_problem
from gcs_core.problem.prepare import PhysicsOptions

EPOCH = datetime(2024, 3, 20, 6, 0, 0, tzinfo=UTC)
#: physics the simulator does not model (so the filter must not either)
PHYSICS = PhysicsOptions(stellar_aberration=False, solar_aberration=False, sun_parallax=False, field_model="dipole")
TRACKERS = (("ST1", (0.0, 0.0, 0.0)), ("ST2", (0.0, 60.0, 90.0)))
FOV_DEG = 4.0


@dataclass
class Truth:
    """What the simulator used: attitudes at the gyro knots and element values."""

    knots: np.ndarray
    C: np.ndarray  # (K+1, 3, 3) attitude at the knots
    bias: np.ndarray  # (K+1, 3) gyro drift bias at the knots [rad/s]
    values: dict  # element name -> true value (static elements)


def _table(name: str, t, **cols) -> Table:
    columns = {"t": np.asarray(t, float)} | {k: np.asarray(v, float) for k, v in cols.items()}
    return Table(Path(f"telemetry/{name}.csv"), np.asarray(t, float), columns, np.arange(len(t)) + 2)


def _alignment(deg) -> np.ndarray:
    a = np.radians(deg)
    return T3(a[2]) @ T2(a[1]) @ T1(a[0])


def simulate(
    seed: int,
    *,
    duration_s: float = 1800.0,
    rate_scale: float = 1.0,
    arw: float = 3e-6,
    rrw: float = 3e-9,
    electronic: float = 0.0,
    tracker_noise: float = 2e-5,
    trackers: int = 2,
    tracker_every: int = 1,
    gyro: bool = True,
    attitude_sigma: float = units.DEG,
    outliers: int = 0,
) -> tuple[ImportedMission, Truth]:
    """An in-memory inertial-mode mission and its truth (module docstring).

    ``rate_scale = 0`` gives an inertially fixed attitude (for the gyro-less tests).
    Truths: roll/pitch/yaw ~ N(0, attitude_sigma); gyro ``G_ij`` ~ N(0, 1e-3) and initial
    bias ~ N(0, 1e-5 rad/s); tracker scales ~ N(1, 1e-3) (the models' data-book sigmas).
    """
    rng = np.random.default_rng(seed)
    K = int(duration_s)
    knots = np.arange(K + 1.0)  # 1 Hz; row k ends at τ_k
    tmid = 0.5 * (knots[1:] + knots[:-1])
    omega = rate_scale * np.column_stack(
        [1.5e-3 * np.sin(2 * np.pi * tmid / 1500.0), 8e-4 + 0 * tmid, 1.2e-3 * np.cos(2 * np.pi * tmid / 2100.0)]
    )
    rpy = rng.normal(0.0, attitude_sigma, 3)
    C = np.empty((K + 1, 3, 3))
    C[0] = euler123_to_dcm(*rpy)  # inertial: A = I
    steps = rotvec_to_dcm(omega)  # exp(−[ω Δt ×]), Δt = 1 s
    for k in range(K):
        C[k + 1] = steps[k] @ C[k]
    values = {"att.roll": rpy[0], "att.pitch": rpy[1], "att.yaw": rpy[2]}
    sensors, telemetry = [], {}
    bias = np.zeros((K + 1, 3))
    if gyro:
        dG = rng.normal(0.0, 1e-3, (3, 3))
        bias[0] = rng.normal(0.0, 1e-5, 3)
        bias[1:] = bias[0] + np.cumsum(rrw * rng.normal(size=(K, 3)), axis=0)
        # y = G (ω + b) + ARW noise σ_v/sqrt(Δt)  (Eq 4-32, M = I)
        y = (omega + bias[1:]) @ (np.eye(3) + dG).T + arw * rng.normal(size=(K, 3))
        if electronic:
            e = electronic * rng.normal(size=(K + 1, 3))
            y += e[1:] - e[:-1]  # read-out noise at both ends
        telemetry["IRU"] = _table("IRU", knots[1:], wx=y[:, 0], wy=y[:, 1], wz=y[:, 2])
        book = {"arw": arw, "rrw": rrw, "bias": (0.0, 0.0, 0.0)}
        if electronic:
            book["electronic"] = electronic
        sensors.append(SensorSpec("IRU", "gyro", Path("telemetry/IRU.csv"), (0.0, 0.0, 0.0), None, book))
        values |= {f"IRU.G_{i + 1}{j + 1}": dG[i, j] for i in range(3) for j in range(3)}
    for name, align in TRACKERS[:trackers]:
        idx = np.arange(0, K + 1, tracker_every)
        M = _alignment(align)
        scale = 1.0 + rng.normal(0.0, 1e-3, 2)
        a = rng.uniform(-0.8, 0.8, (idx.size, 2)) * np.radians(FOV_DEG)  # star in the FOV
        F_S = np.column_stack([np.ones(idx.size), np.tan(a[:, 0]), np.tan(a[:, 1])])
        F_S /= np.linalg.norm(F_S, axis=1, keepdims=True)
        F_I = np.einsum("kji,kj->ki", M @ C[idx], F_S)  # (M C)ᵀ F_S
        h = np.arcsin(F_S[:, 2]) / scale[0] + tracker_noise * rng.normal(size=idx.size)
        v = np.arctan2(F_S[:, 1], F_S[:, 0]) / scale[1] + tracker_noise * rng.normal(size=idx.size)
        if outliers:
            bad = rng.choice(idx.size, outliers, replace=False)
            h[bad] += 50 * tracker_noise
        ra = np.degrees(np.arctan2(F_I[:, 1], F_I[:, 0])) % 360.0
        dec = np.degrees(np.arcsin(np.clip(F_I[:, 2], -1, 1)))
        telemetry[name] = _table(name, knots[idx], h=h, v=v, ra=ra, dec=dec, mag=np.full(idx.size, 4.0))
        sensors.append(
            SensorSpec(
                name,
                "star_tracker",
                Path(f"telemetry/{name}.csv"),
                align,
                tracker_noise,
                {"fov_deg": FOV_DEG, "scale": (1.0, 1.0)},
            )
        )
        values |= {f"{name}.scale_h": scale[0], f"{name}.scale_v": scale[1]}
    te = np.arange(-120.0, K + 180.0, 60.0)  # circular orbit, 7000 km
    n_orb = np.sqrt(units.MU_EARTH / 7000.0**3)
    u = n_orb * te
    r = 7000.0 * np.column_stack([np.cos(u), 0.6 * np.sin(u), 0.8 * np.sin(u)])
    v = 7000.0 * n_orb * np.column_stack([-np.sin(u), 0.6 * np.cos(u), 0.8 * np.cos(u)])
    sun = np.broadcast_to([units.AU_KM, 0.0, 0.0], r.shape)
    eph = _table(
        "ephemeris",
        te,
        rx=r[:, 0],
        ry=r[:, 1],
        rz=r[:, 2],
        vx=v[:, 0],
        vy=v[:, 1],
        vz=v[:, 2],
        sx=sun[:, 0],
        sy=sun[:, 1],
        sz=sun[:, 2],
    )
    spec = MissionSpec(
        Path("/nonexistent/sim"), f"sim-{seed}", EPOCH, "inertial", Path("ephemeris.csv"), tuple(sensors)
    )
    return ImportedMission(spec, eph, telemetry), Truth(knots, C, bias, values)


def sim_problem(mission: ImportedMission, **kw):
    """The calibration problem of a simulated mission (bias instability held: not simulated)."""
    exclude = ("IRU.bias_instability",) if "IRU" in mission.telemetry else ()
    return build_problem(mission, physics=PHYSICS, options=StateOptions(exclude=exclude), **kw)


def chi2_band(dof: int, level: float = 0.95) -> tuple[float, float]:
    a = 0.5 * (1.0 - level)
    return float(stats.chi2.ppf(a, dof)), float(stats.chi2.ppf(1.0 - a, dof))


def filtered_error(f: Filtr, truth: Truth) -> np.ndarray:
    """Final filtered error in the filter's columns: δθ with C_true = exp(−[δθ×]) C_est."""
    k = int(np.searchsorted(truth.knots, f.current_time))
    est = f.estimate()
    e = []
    for col in f.columns:
        if col.startswith("kf.dtheta"):
            continue
        if ".bias_" in col and col.startswith("IRU."):
            e.append(truth.bias[k, "xyz".index(col[-1])] - est[col])
        else:
            e.append(truth.values[col] - est[col])
    return np.concatenate([dcm_to_rotvec(truth.C[k] @ f.attitude.T), e])


def smoothed_error(res, truth: Truth) -> np.ndarray:
    """Error of the smoothed estimate at the reference time, element coordinates."""
    out = []
    for name in res.solve_for:
        if name.startswith("IRU.bias_"):
            out.append(truth.bias[0, "xyz".index(name[-1])])
        else:
            out.append(truth.values[name])
    return np.array(out) - res.x


def test_nees_and_nis_monte_carlo():
    """Seeded Monte Carlo (6 runs × 30 min, 1 Hz): NEES of the final filtered state and of
    the smoothed state at t_ref in their 95 % χ² bands; NIS over all frames in its band."""
    nees_f, nees_s, n_f, n_s, nis, dof = 0.0, 0.0, 0, 0, 0.0, 0
    for seed in range(6):
        mission, truth = simulate(seed)
        f = Filtr(sim_problem(mission), options=FilterOptions(max_passes=1), block_seconds=300)
        res = f.run()
        e = filtered_error(f, truth)
        nees_f += float(e @ np.linalg.solve(f.covariance, e))
        n_f += e.size
        e = smoothed_error(res, truth)
        nees_s += float(e @ np.linalg.solve(res.P, e))
        n_s += e.size
        nis, dof = nis + res.nis, dof + res.nis_dof
    lo, hi = chi2_band(n_f)
    assert lo < nees_f < hi, f"filtered NEES {nees_f:.1f} outside [{lo:.1f}, {hi:.1f}] ({n_f} dof)"
    lo, hi = chi2_band(n_s)
    assert lo < nees_s < hi, f"smoothed NEES {nees_s:.1f} outside [{lo:.1f}, {hi:.1f}] ({n_s} dof)"
    lo, hi = chi2_band(dof)
    assert lo < nis < hi, f"NIS {nis:.0f} outside [{lo:.0f}, {hi:.0f}] ({dof} dof)"


@pytest.mark.parametrize("electronic", [0.0, 2e-6])
def test_residuals_at_noise_floor(electronic):
    """Post-fit residuals from the smoothed trajectory sit at the noise floor (RMS ≈ 1σ),
    with and without the gyro read-out noise σ_e (not in Q: a white attitude error seen by
    the measurements; the tracker residuals then carry sqrt(σ² + σ_e² ) ≈ 1.005σ)."""
    mission, truth = simulate(11, electronic=electronic, arw=3e-7)
    res = Filtr(sim_problem(mission), options=FilterOptions(max_passes=2)).run()
    for name in ("ST1", "ST2"):
        assert abs(res.residuals[name].rms_normalized - 1.0) < 0.03, name
    assert abs(res.nis / res.nis_dof - 1.0) < 4 * np.sqrt(2.0 / res.nis_dof)
