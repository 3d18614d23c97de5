"""The Astro Pi path against truth: a simulated unit on the ISS's TLE orbit, written in the
Astro Pi CSV format, converted, imported and fitted; the estimates against the truth in σ.

The simulation uses only the ``sgp4`` package (TEME states), the simulator's own IGRF
(``gcs_core.sim.field``, ppigrf) and rotations (``gcs_core.sim._rot``), never the model
code it checks. Truth: an LVLH attitude with a constant offset, an unknown mounting, a
bias, a symmetric 3×3 (scale and non-orthogonality), a time offset, white noise of 150 nT
quantized to 0.1 µT as the real file is, and a start-up settle from zero.
"""

from __future__ import annotations

from datetime import UTC, datetime, timedelta
from pathlib import Path

import numpy as np
import pytest
from repo_paths import TEST_DATA

from gcs_core.config import load_config
from gcs_core.convert import convert
from gcs_core.io.importer import load_mission
from gcs_core.session import Analysis
from gcs_core.sim._rot import rpy_to_dcm
from gcs_core.sim.field import igrf_gci

DATA = TEST_DATA / "astropi"
TLE = DATA / "iss-2022-01-31.tle"
EPOCH = datetime(2022, 1, 31, 12, 21, 15, tzinfo=UTC)
JD0 = 2459611.0 + (12 * 3600 + 21 * 60 + 15) / 86400.0 - 0.5  # JD of EPOCH (UTC)
SPAN_S, STEP_S = 6 * 3600.0, 5.0
SIGMA_NT = 150.0
ATT_DEG = (1.4, 4.0, 0.2)
MOUNT_DEG = (-10.0, -31.0, -31.0)
BIAS_NT = np.array([-6000.0, -100.0, -1000.0])
D_TRUE = np.array([[-0.03, -0.07, 0.013], [-0.07, 0.07, 0.03], [0.013, 0.03, -0.14]])
#: the time-tag offset. The model's is first order in Δt (``B_I + Δt Ḃ_I``, magnetometer.py):
#: at −20 s (the size the real file shows) the second-order field change, 10–40 nT, moves
#: the scale factors by ≈ 0.1 % (z up to −3.3 in this simulation); at −5 s it is 16 times less
DT_TRUE_S = -5.0
N_SETTLE = 5


def _states(t):
    from sgp4.api import Satrec

    lines = [ln for ln in TLE.read_text().splitlines() if ln[:2] in ("1 ", "2 ")]
    sat = Satrec.twoline2rv(*lines)
    jd = JD0 + t / 86400.0
    whole = np.floor(jd)
    err, r, v = sat.sgp4_array(whole, jd - whole)
    assert not np.any(err)
    return r, v


def _lvlh(r, v):
    z = -r / np.linalg.norm(r, axis=1)[:, None]
    h = np.cross(r, v)
    y = -h / np.linalg.norm(h, axis=1)[:, None]
    return np.stack([np.cross(y, z), y, z], axis=1)


def _simulate(path: Path) -> None:
    rng = np.random.default_rng(2022)
    t = np.arange(0.0, SPAN_S, STEP_S)
    te = t + DT_TRUE_S  # the instant each sample is of
    r, v = _states(te)
    B_I = igrf_gci(EPOCH, JD0, te, r)
    C = rpy_to_dcm(*np.radians(ATT_DEG)) @ _lvlh(r, v)
    M = rpy_to_dcm(*np.radians(MOUNT_DEG))
    B_S = np.einsum("ij,njk,nk->ni", (np.eye(3) + D_TRUE) @ M, C, B_I) + BIAS_NT
    B_S += rng.normal(0.0, SIGMA_NT, B_S.shape)
    B_S[:N_SETTLE] *= (1.0 - np.exp(-np.arange(1, N_SETTLE + 1) / 1.2))[:, None]
    ut = np.round(B_S / 100.0) / 10.0  # µT with one decimal, as published
    with open(path, "w") as fh:
        fh.write("Date/Time,Latitude,Longitude,MagX,MagY,MagZ\n")
        for ti, b in zip(t, ut):
            stamp = EPOCH + timedelta(seconds=float(ti))
            fh.write(f"{stamp:%Y-%m-%d %H:%M:%S},0,0,{b[0]:.1f},{b[1]:.1f},{b[2]:.1f}\n")


@pytest.fixture(scope="module")
def fitted(tmp_path_factory):
    root = tmp_path_factory.mktemp("astropi_truth")
    _simulate(root / "sim.csv")
    rep = convert("astropi", root / "sim.csv", root / "mission", tle=TLE)
    cfg = root / "cfg.toml"
    cfg.write_text(
        f"""[analysis]
mission = "{root / "mission"}"
[state]
effects = ["MAG.scale", "MAG.nonorthogonality", "MAG.time_offset"]
attitude_sigma_deg = 10.0
[state.elements."MAG.bias_x"]
sigma = inf
[state.elements."MAG.bias_y"]
sigma = inf
[state.elements."MAG.bias_z"]
sigma = inf
[state.elements."MAG.time_offset"]
sigma = 100.0
"""
        + "".join(
            f'[state.elements."MAG.{n}"]\nsigma = 0.5\n'
            for n in ("scale_x", "scale_y", "scale_z", "nonorth_xy", "nonorth_xz", "nonorth_yz")
        )
    )
    config = load_config(cfg)
    a = Analysis(config, mission=load_mission(config.mission))
    a.fit(holdout=False)
    return rep, a


def test_converter_estimates_against_truth(fitted):
    rep, a = fitted
    assert N_SETTLE - 1 <= rep.flagged["MAG"] <= N_SETTLE + 3
    noise = a.mission.spec.sensor("MAG").noise
    # 150 nT white plus 0.1 µT quantization (29 nT): 152.8 nT; the estimate's spread ≈ 2 nT
    assert noise == pytest.approx(np.hypot(SIGMA_NT, 100.0 / np.sqrt(12.0)), abs=8.0)


def test_fit_recovers_truth_within_sigma(fitted):
    _, a = fitted
    res = a.result
    assert res.status == "converged"
    est, sig = res.state.values(), res.sigma
    truth = {"MAG.time_offset": DT_TRUE_S}
    truth.update({f"MAG.bias_{ax}": BIAS_NT[i] for i, ax in enumerate("xyz")})
    truth.update({f"MAG.scale_{ax}": D_TRUE[i, i] for i, ax in enumerate("xyz")})
    truth.update({"MAG.nonorth_xy": D_TRUE[0, 1], "MAG.nonorth_xz": D_TRUE[0, 2], "MAG.nonorth_yz": D_TRUE[1, 2]})
    z = {k: (est[k] - v) / sig[k] for k, v in truth.items()}
    assert max(abs(x) for x in z.values()) < 4.0, z
    # the fitted normalized RMS is the noise floor (the data book noise was estimated)
    assert res.residuals["MAG"].rms_normalized == pytest.approx(1.0, abs=0.05)


def test_attitude_times_mounting_is_the_true_rotation(fitted):
    """Mounting and attitude offset are one rotation: their product against the truth."""
    _, a = fitted
    from gcs_core.frames.rotations import euler123_to_dcm

    est = a.result.state.values()
    spec = a.mission.spec.sensor("MAG")
    M_c = euler123_to_dcm(*np.radians(spec.alignment_deg))
    B_f = euler123_to_dcm(est["att.roll"], est["att.pitch"], est["att.yaw"])
    true = rpy_to_dcm(*np.radians(MOUNT_DEG)) @ rpy_to_dcm(*np.radians(ATT_DEG))
    err = np.arccos(np.clip((np.trace((M_c @ B_f).T @ true) - 1.0) / 2.0, -1.0, 1.0))
    sig = max(a.result.sigma[n] for n in ("att.roll", "att.pitch", "att.yaw"))
    assert err < 5.0 * sig, (np.degrees(err) * 3600, np.degrees(sig) * 3600)
