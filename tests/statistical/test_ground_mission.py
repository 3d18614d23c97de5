"""A ground (laboratory) mission against its truth: a unit turned by hand under an attitude
reference, with the field an unknown constant (docs/ground.md).

The truth is simulated here with exact kinematics (the body rate held constant over each
gyro interval, the attitude propagated by exact rotations ``exp(−[ω Δt×])``, the time-tag
offsets applied by rotating on at the rate of the interval they fall in) and written as a
mission directory with ``[ephemeris] ground_position_km``. The fit (batch, Q = 0: the gyro
noise walks the attitude by ~1e-4 rad over the span, a tenth of the reference's noise)
must recover the magnetometer's bias, symmetric matrix D, alignment and time offset, the
field, the gyro bias and the reference's time offset within :data:`Z_MAX` of their σ.
"""

from __future__ import annotations

import numpy as np
import pytest

from gcs_core.config import default_config
from gcs_core.config_schema import ElementConfig
from gcs_core.errors import InputError
from gcs_core.frames.rotations import euler123_to_dcm, quat_from_dcm, rotvec_to_dcm
from gcs_core.io.importer import load_mission
from gcs_core.session import Analysis

DT = 0.02  # s (50 Hz)
N = 3000  # 60 s
GYRO_NOISE = 1e-4  # rad/s per sample
MAG_NOISE = 300.0  # nT
OPT_NOISE = 1e-3  # rad
B_LAB = np.array([300.0, 17000.0, -45000.0])  # nT, East-North-Up
MAG_BIAS = np.array([500.0, -300.0, 800.0])  # nT
GYRO_BIAS = np.array([3e-3, -2e-3, 4e-3])  # rad/s
#: symmetric D with zero trace: its common part (a scale of the whole magnetometer) is one
#: quantity with the field's magnitude when the field is unknown, and the a priori of the
#: scales holds it at zero
D_TRUE = np.array([[0.01, 0.004, -0.006], [0.004, -0.004, 0.002], [-0.006, 0.002, -0.006]])
MAG_ALIGN_RAD = np.array([0.01, -0.02, 0.015])
MAG_DT = -0.012  # s: the magnetometer samples 12 ms early
OPT_DT = 0.004  # s
#: the lab attitude at t = 0 (roll, pitch, yaw [rad], Euler 1-2-3)
RPY0 = (0.3, -0.2, 1.0)
#: a-priori σ of a MEMS unit (the flight defaults, 1e-5 rad/s of gyro bias and 1e-3 of its
#: matrix, are those of a navigation-grade IRU): the gyro bias and matrix free, the
#: magnetometer's non-orthogonality a few percent
MEMS_PRIORS = {
    **{f"GYR.bias_{a}": ElementConfig(sigma=1e-1) for a in "xyz"},
    **{f"GYR.G_{i}{j}": ElementConfig(sigma=0.05) for i in (1, 2, 3) for j in (1, 2, 3)},
    **{f"MAG.nonorth_{p}": ElementConfig(sigma=0.1) for p in ("xy", "xz", "yz")},
}
#: estimates within this many σ of the truth (a seeded draw; 3.3 σ is the two-sided 0.1 %)
Z_MAX = 3.5
one_percent = 0.01


def _rate(t):
    return np.column_stack([0.9 * np.sin(0.31 * t), 0.8 * np.cos(0.23 * t + 1.0), 0.6 * np.sin(0.17 * t + 2.0) + 0.2])


def kinematics(n: int = N, dt: float = DT, scale: float = 1.0):
    """The lab's exact kinematics: the ticks ``t`` (n + 1), the rate ``w`` (n, 3) of each
    interval (t_{k-1}, t_k] (:func:`_rate` times ``scale``), the attitude ``C`` (n + 1, 3, 3)
    at the ticks, and ``shifted(δ)``: C(t_k + δ) for k = 1..n−1 and |δ| < dt, turned on at
    the rate of the interval δ falls in."""
    t = np.arange(n + 1) * dt
    w = scale * _rate(t[1:] - 0.5 * dt)
    C = np.empty((n + 1, 3, 3))
    C[0] = euler123_to_dcm(*RPY0)
    steps = rotvec_to_dcm(w * dt)
    for i in range(n):
        C[i + 1] = steps[i] @ C[i]
    k = np.arange(1, n)

    def shifted(delta):
        rate = w[k] if delta > 0 else w[k - 1]  # interval after / before t_k
        return rotvec_to_dcm(rate * delta) @ C[k]

    return t, w, C, shifted


def _simulate(rng, gyro_rate=None):
    """The lab's telemetry; ``gyro_rate`` (n, 3): what the gyro senses, if not the lab rate
    (the inertial rate, with the Earth's turn, in ``test_earth_rate``)."""
    t, w, _, shifted = kinematics()
    k = np.arange(1, N)
    gyro = (w if gyro_rate is None else gyro_rate) + GYRO_BIAS + rng.normal(scale=GYRO_NOISE, size=w.shape)
    M = euler123_to_dcm(*MAG_ALIGN_RAD)
    B_S = np.einsum("ij,njk,k->ni", (np.eye(3) + D_TRUE) @ M, shifted(MAG_DT), B_LAB) + MAG_BIAS
    B_S += rng.normal(scale=MAG_NOISE, size=B_S.shape)
    C_opt = rotvec_to_dcm(rng.normal(scale=OPT_NOISE, size=(k.size, 3))) @ shifted(OPT_DT)
    return t, gyro, B_S, quat_from_dcm(C_opt)


def _write(root, t, gyro, B_S, q, flag=None):
    """The lab as a mission directory; ``flag`` (optional, per magnetometer row) is written
    as the telemetry's ``flag`` column (non-zero rows are kept in the file, not fitted)."""
    (root / "telemetry").mkdir(parents=True)
    k = np.arange(1, t.size - 1)
    fmt = {"delimiter": ",", "comments": "", "fmt": "%.10g"}
    np.savetxt(root / "telemetry/GYR.csv", np.column_stack([t[1:], gyro]), header="t,wx,wy,wz", **fmt)
    mag, header = np.column_stack([t[k], B_S]), "t,bx,by,bz"
    if flag is not None:
        mag, header = np.column_stack([mag, flag]), header + ",flag"
    np.savetxt(root / "telemetry/MAG.csv", mag, header=header, **fmt)
    np.savetxt(
        root / "telemetry/OPT.csv", np.column_stack([t[k], q]), header="t,q1,q2,q3,q4", **{**fmt, "fmt": "%.12g"}
    )
    arw = GYRO_NOISE * np.sqrt(t[1] - t[0])
    (root / "mission.toml").write_text(f"""
[mission]
name = "lab"
epoch = "2021-01-01T00:00:00Z"
attitude_mode = "inertial"

[ephemeris]
ground_position_km = [0.0, 0.0, 6365.0]

[[sensor]]
name = "GYR"
type = "gyro"
telemetry = "telemetry/GYR.csv"
alignment_deg = [0.0, 0.0, 0.0]
bias = [0.0, 0.0, 0.0]
arw = {arw:.6g}
rrw = 0.0

[[sensor]]
name = "MAG"
type = "magnetometer"
telemetry = "telemetry/MAG.csv"
alignment_deg = [0.0, 0.0, 0.0]
noise = {MAG_NOISE}
bias = [0.0, 0.0, 0.0]

[[sensor]]
name = "OPT"
type = "attitude_reference"
telemetry = "telemetry/OPT.csv"
alignment_deg = [0.0, 0.0, 0.0]
noise = {OPT_NOISE}
""")


@pytest.fixture(scope="module")
def fitted(tmp_path_factory):
    root = tmp_path_factory.mktemp("lab")
    _write(root, *_simulate(np.random.default_rng(2021)))
    mission = load_mission(root)
    cfg = default_config(root)
    cfg = cfg.with_changes(
        physics={"field_model": "constant"},
        state={
            "attitude_sigma_deg": 10.0,
            "elements": MEMS_PRIORS,
            "effects": ("MAG.scale", "MAG.nonorthogonality", "MAG.alignment", "MAG.time_offset", "OPT.time_offset"),
        },
    )
    a = Analysis(cfg, mission=mission)
    res = a.fit(holdout=False)
    return a, res


def test_estimates_against_truth_in_sigma(fitted):
    a, res = fitted
    v = res.state.values()
    truth = {
        **{f"MAG.bias_{x}": MAG_BIAS[i] for i, x in enumerate("xyz")},
        **{f"field.B_{x}": B_LAB[i] for i, x in enumerate("xyz")},
        **{f"GYR.bias_{x}": GYRO_BIAS[i] for i, x in enumerate("xyz")},
        **{f"MAG.align_{i + 1}": MAG_ALIGN_RAD[i] for i in range(3)},
        **{f"MAG.scale_{x}": D_TRUE[i, i] for i, x in enumerate("xyz")},
        "MAG.nonorth_xy": D_TRUE[0, 1],
        "MAG.nonorth_xz": D_TRUE[0, 2],
        "MAG.nonorth_yz": D_TRUE[1, 2],
        "MAG.time_offset": MAG_DT,
        "OPT.time_offset": OPT_DT,
    }
    z = {n: (v[n] - x) / res.sigma[n] for n, x in truth.items()}
    worst = max(z, key=lambda n: abs(z[n]))
    assert abs(z[worst]) < Z_MAX, (worst, z[worst], z)


def test_residuals_at_the_noise_floor(fitted):
    a, _ = fitted
    for sensor, nrms in a.rms().items():
        assert abs(nrms - 1.0) < 5 * one_percent, (sensor, nrms)


def test_a_sun_sensor_is_refused_on_the_ground(tmp_path):
    _write(tmp_path, *_simulate(np.random.default_rng(1)))
    text = (tmp_path / "mission.toml").read_text()
    (tmp_path / "mission.toml").write_text(
        text
        + """
[[sensor]]
name = "FSS1"
type = "fine_sun"
telemetry = "telemetry/MAG.csv"
alignment_deg = [0.0, 0.0, 0.0]
noise = 0.5
coeff_alpha = [0.0, 7.6e-05, 0.0, 50.0]
coeff_beta = [0.0, 7.6e-05, 0.0, 50.0]
fov_deg = 32.0
"""
    )
    with pytest.raises(InputError, match="a ground mission has no Sun"):
        load_mission(tmp_path)
