"""A laboratory field that is not uniform, against its truth: the unit is turned by hand
and carried over decimetres through a field with a constant gradient (docs/ground.md).

The truth is the ground mission of ``test_ground_mission`` (exact kinematics, the same
sensors and errors) with the unit also moving: its position ``p(t)`` [m, ENU] is written
as the aux channels ``pos_x/y/z``, and the field it reads is ``B_LAB + G p`` with ``G``
symmetric and trace-free (a current-free room; the expansion is exact for this field),
evaluated at the magnetometer's own sample time ``t + Δt`` (position and attitude both).
A fit without the gradient is a model error; with ``MAG.field_gradient`` the five
elements, the magnetometer's calibration and the field come back within :data:`Z_MAX` of
their σ, and the residual sits at the noise.
"""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest
from test_ground_mission import (
    B_LAB,
    D_TRUE,
    GYRO_BIAS,
    GYRO_NOISE,
    MAG_ALIGN_RAD,
    MAG_BIAS,
    MAG_DT,
    MAG_NOISE,
    MEMS_PRIORS,
    OPT_DT,
    OPT_NOISE,
    Z_MAX,
    N,
    _write,
    kinematics,
)

from gcs_core.config import default_config
from gcs_core.frames.rotations import euler123_to_dcm, quat_from_dcm, rotvec_to_dcm
from gcs_core.io.importer import load_mission
from gcs_core.io.types import SensorSpec
from gcs_core.models.magnetometer import MagnetometerModel
from gcs_core.session import Analysis

#: the field's gradient [nT/m]: symmetric, trace-free, a few µT/m (what the BROAD lab shows)
G_TRUE = np.array([[800.0, 400.0, -900.0], [400.0, 2400.0, -400.0], [-900.0, -400.0, -3200.0]])
GRADIENT = {"xx": G_TRUE[0, 0], "xy": G_TRUE[0, 1], "xz": G_TRUE[0, 2], "yy": G_TRUE[1, 1], "yz": G_TRUE[1, 2]}
EFFECTS = ("MAG.scale", "MAG.nonorthogonality", "MAG.alignment", "MAG.time_offset", "OPT.time_offset")
one_percent = 0.01


def _position(t):
    """The unit's path [m, ENU]: ±0.3 m across, ±0.25 m up and down, over tens of seconds."""
    return np.column_stack([0.3 * np.sin(0.13 * t), 0.3 * np.sin(0.21 * t + 1.0), 0.25 * np.sin(0.07 * t + 2.0)])


def _simulate(rng, hold: int = 1):
    """The truth; ``hold`` > 1 holds each magnetometer noise draw over that many samples
    (errors correlated over ``hold·DT``, which a white-noise fit undercounts)."""
    t, w, _, shifted = kinematics()
    k = np.arange(1, N)
    gyro = w + GYRO_BIAS + rng.normal(scale=GYRO_NOISE, size=w.shape)
    B_at = B_LAB + _position(t[k] + MAG_DT) @ G_TRUE.T  # the field where the unit is
    M = euler123_to_dcm(*MAG_ALIGN_RAD)
    B_S = np.einsum("ij,njk,nk->ni", (np.eye(3) + D_TRUE) @ M, shifted(MAG_DT), B_at) + MAG_BIAS
    draws = rng.normal(scale=MAG_NOISE, size=(-(-B_S.shape[0] // hold), 3))
    B_S += np.repeat(draws, hold, axis=0)[: B_S.shape[0]]
    C_opt = rotvec_to_dcm(rng.normal(scale=OPT_NOISE, size=(k.size, 3))) @ shifted(OPT_DT)
    return t, gyro, B_S, quat_from_dcm(C_opt)


def write_mission(root, rng, hold: int = 1):
    """The truth as a mission directory with the position channels in aux.csv."""
    t, gyro, B_S, q = _simulate(rng, hold)
    _write(root, t, gyro, B_S, q)
    np.savetxt(
        root / "aux.csv",
        np.column_stack([t, _position(t)]),
        delimiter=",",
        header="t,pos_x,pos_y,pos_z",
        comments="",
        fmt="%.10g",
    )
    text = (root / "mission.toml").read_text()
    (root / "mission.toml").write_text(text.replace("[ephemeris]", '[aux]\nfile = "aux.csv"\n\n[ephemeris]'))
    return root


@pytest.fixture(scope="module")
def mission(tmp_path_factory):
    return write_mission(tmp_path_factory.mktemp("lab-gradient"), np.random.default_rng(2022))


def fit(root, effects):
    cfg = default_config(root)
    cfg = cfg.with_changes(
        physics={"field_model": "constant"},
        state={"attitude_sigma_deg": 10.0, "effects": effects, "elements": MEMS_PRIORS},
        filter={"noise_weighting": "stated"},  # the white-noise fit whose σ the sandwich tests judge
    )
    a = Analysis(cfg, mission=load_mission(root))
    return a, a.fit(holdout=False)


def test_the_position_channels_feed_the_gradient_not_contamination():
    sensor = SensorSpec(
        name="MAG",
        type="magnetometer",
        telemetry=Path("MAG.csv"),
        alignment_deg=(0.0, 0.0, 0.0),
        noise=300.0,
        book={"bias": (0.0, 0.0, 0.0)},
    )
    names = {
        p.name
        for p in MagnetometerModel(
            sensor, aux_channels=("pos_x", "pos_y", "pos_z", "temp"), constant_field=True
        ).parameters()
    }
    assert {f"gradient_{ab}" for ab in GRADIENT} <= names
    assert not any(n.startswith("contam_pos") for n in names)
    assert {f"contam_temp_{a}" for a in "xyz"} <= names
    # in flight (the field from a model) the position channels stay contamination channels
    flight = {p.name for p in MagnetometerModel(sensor, aux_channels=("pos_x", "pos_y", "pos_z")).parameters()}
    assert not any(n.startswith("gradient_") for n in flight)


def test_gradient_estimated_against_truth_in_sigma(mission):
    uniform, _ = fit(mission, EFFECTS)
    assert uniform.rms()["MAG"] > 1.5  # a uniform field cannot explain it
    a, res = fit(mission, EFFECTS + ("MAG.field_gradient",))
    v = res.state.values()
    truth = {
        **{f"field.G_{ab}": x for ab, x in GRADIENT.items()},
        **{f"field.B_{x}": B_LAB[i] for i, x in enumerate("xyz")},
        **{f"MAG.bias_{x}": MAG_BIAS[i] for i, x in enumerate("xyz")},
        **{f"MAG.scale_{x}": D_TRUE[i, i] for i, x in enumerate("xyz")},
        "MAG.nonorth_xy": D_TRUE[0, 1],
        "MAG.nonorth_xz": D_TRUE[0, 2],
        "MAG.nonorth_yz": D_TRUE[1, 2],
        **{f"MAG.align_{i + 1}": MAG_ALIGN_RAD[i] for i in range(3)},
        "MAG.time_offset": MAG_DT,
        "OPT.time_offset": OPT_DT,
    }
    z = {n: (v[n] - x) / res.sigma[n] for n, x in truth.items()}
    worst = max(z, key=lambda n: abs(z[n]))
    assert abs(z[worst]) < Z_MAX, (worst, z[worst], z)
    assert abs(a.rms()["MAG"] - 1.0) < 5 * one_percent
