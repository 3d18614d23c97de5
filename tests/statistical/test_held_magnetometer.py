"""A magnetometer read by a faster bus, against its truth: held repeats and interpolated
samples must be flagged, not fitted (docs of :mod:`gcs_core.convert.holds`).

The truth is the laboratory of ``test_ground_mission`` (exact kinematics: the body rate
constant over each bus interval, the attitude propagated by exact rotations, the
magnetometer's time-tag offset applied by rotating on at the rate of the interval it falls
in) with the bus of the BROAD unit: every channel is read at each bus tick, but the
magnetometer measures only on some ticks, :data:`BUS_PATTERN` (``N`` a new measurement at
that tick, ``h`` the value before read again, ``m`` the mean of its neighbours, as the real
unit's telemetry shows). Fitted at their time stamps, the held values are old by one or two
bus intervals: the magnetometer's time offset comes out late by many σ. Flagged by
:func:`gcs_core.convert.holds.bus_check` (the converter's own check) and left out by the
import, the time offset, the bias and the matrix come back within :data:`Z_MAX` of their σ,
the residual sits at the noise and is white (the sandwich leaves the σ as they are);
unflagged, its correlation makes the fit's σ optimistic by a factor of 1.5–2.
"""

from __future__ import annotations

import numpy as np
import pytest
from test_ground_mission import B_LAB, GYRO_BIAS, GYRO_NOISE, MEMS_PRIORS, OPT_NOISE, Z_MAX, _write, kinematics

from gcs_core.config import default_config
from gcs_core.convert.holds import FLAG_HELD, FLAG_INTERPOLATED, bus_check
from gcs_core.frames.rotations import quat_from_dcm, rotvec_to_dcm
from gcs_core.io.importer import load_mission
from gcs_core.session import Analysis

DT = 0.01  # s: the bus (100 Hz)
N = 3000  # 30 s
BUS_PATTERN = "NmNhhm"  # one period of the magnetometer on the bus (BROAD's)
MAG_NOISE = 300.0  # nT per measurement
MAG_BIAS = np.array([500.0, -300.0, 800.0])  # nT
#: the magnetometer's non-orthogonality (symmetric, no scale: the field's magnitude is free)
D_TRUE = np.array([[0.0, 0.004, -0.006], [0.004, 0.0, 0.002], [-0.006, 0.002, 0.0]])
MAG_DT = -0.004  # s: the magnetometer measures 4 ms before its tick
OPT_DT = 0.003  # s
#: the lab motion of test_ground_mission, this many times faster (BROAD's fast trials reach 10 rad/s)
RATE_SCALE = 4.0
EFFECTS = ("MAG.nonorthogonality", "MAG.time_offset", "OPT.time_offset")
#: the held fit's time offset must be off by at least this many σ (it is tens)
BIASED = 5.0
one_percent = 0.01
#: the sandwich's window [s] (100 bus ticks, 35 measurements), and the scale that separates
#: white residuals (0.8–1.2) from held ones (1.5–2.1)
SANDWICH_S = 1.0
HONEST_SCALE = 1.3


def _simulate(rng):
    t, w, _, shifted = kinematics(N, DT, RATE_SCALE)  # up to ~4 rad/s: hand motions in the lab
    k = np.arange(1, N)
    gyro = w + GYRO_BIAS + rng.normal(scale=GYRO_NOISE, size=w.shape)
    B = np.einsum("ij,njk,k->ni", np.eye(3) + D_TRUE, shifted(MAG_DT), B_LAB) + MAG_BIAS
    B += rng.normal(scale=MAG_NOISE, size=B.shape)
    kind = np.array([BUS_PATTERN[j % len(BUS_PATTERN)] for j in range(B.shape[0])])
    kind[-1] = "N"
    for j in range(1, B.shape[0]):  # the bus: held values, then interpolated ones
        if kind[j] == "h":
            B[j] = B[j - 1]
    for j in np.flatnonzero(kind == "m"):
        B[j] = 0.5 * (B[j - 1] + B[j + 1])
    C_opt = rotvec_to_dcm(rng.normal(scale=OPT_NOISE, size=(k.size, 3))) @ shifted(OPT_DT)
    return t, gyro, B, quat_from_dcm(C_opt), kind


def _fit(root):
    cfg = default_config(root).with_changes(
        method="batch",
        physics={"field_model": "constant"},
        state={"attitude_sigma_deg": 10.0, "elements": MEMS_PRIORS, "effects": EFFECTS},
    )
    a = Analysis(cfg, mission=load_mission(root))
    return a, a.fit(holdout=False)


TRUTH = {
    **{f"MAG.bias_{x}": MAG_BIAS[i] for i, x in enumerate("xyz")},
    "MAG.nonorth_xy": D_TRUE[0, 1],
    "MAG.nonorth_xz": D_TRUE[0, 2],
    "MAG.nonorth_yz": D_TRUE[1, 2],
    "MAG.time_offset": MAG_DT,
    "OPT.time_offset": OPT_DT,
    **{f"GYR.bias_{x}": GYRO_BIAS[i] for i, x in enumerate("xyz")},
}


@pytest.fixture(scope="module")
def fits(tmp_path_factory):
    t, gyro, B, q, kind = _simulate(np.random.default_rng(2026))
    flag, lines = bus_check("magnetometer", B, np.ones(B.shape[0], dtype=bool), DT)
    out = {"kind": kind, "flag": flag, "lines": lines}
    for name, f in (("flagged", flag), ("held", np.zeros_like(flag))):
        root = tmp_path_factory.mktemp(name)
        _write(root, t, gyro, B, q, f)
        out[name] = _fit(root)
    return out


def _z(res):
    v = res.state.values()
    return {n: (v[n] - x) / res.sigma[n] for n, x in TRUTH.items()}


def test_the_check_flags_exactly_the_bus_samples(fits):
    kind, flag = fits["kind"], fits["flag"]
    assert np.array_equal(flag == FLAG_HELD, kind == "h"), fits["lines"]
    assert np.array_equal(flag == FLAG_INTERPOLATED, kind == "m"), fits["lines"]


def test_flagged_estimates_within_their_sigma_of_truth(fits):
    a, res = fits["flagged"]
    z = _z(res)
    worst = max(z, key=lambda n: abs(z[n]))
    assert abs(z[worst]) < Z_MAX, (worst, z[worst], z)
    assert abs(a.rms()["MAG"] - 1.0) < 5 * one_percent


def test_held_samples_fitted_at_their_stamp_bias_the_time_offset(fits):
    """Unflagged, the held values are old: the magnetometer seems to sample earlier than it
    does (by about the held repeats' share of one to two bus intervals) by many σ, and its
    residual sits above the noise."""
    a, res = fits["held"]
    z = _z(res)
    assert z["MAG.time_offset"] < -BIASED, z
    assert a.rms()["MAG"] > 1.0 + 5 * one_percent


def test_held_samples_make_the_sigma_optimistic(fits):
    """A held repeat counts one noise draw two or three times: the unflagged fit's residuals
    are correlated and the batch-means sandwich scales its magnetometer σ up by 1.5–2
    (:mod:`gcs_core.noise.correlation`); flagged, the residuals are white and the
    scales sit at 1 within the estimator's own scatter (0.8–1.2 over seeds)."""
    from gcs_core.noise.correlation import sigma_scale

    scales = {}
    for name in ("flagged", "held"):
        a, res = fits[name]
        sc = sigma_scale(a.problem, res, block_s=SANDWICH_S).scale
        scales[name] = [v for n, v in sc.items() if n.startswith("MAG.")]
    assert max(scales["flagged"]) < HONEST_SCALE < min(scales["held"]), scales
