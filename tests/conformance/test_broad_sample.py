"""The bundled BROAD sample mission (real data: D. Laidig, M. Caruso, A. Cereatti, T. Seel,
"BROAD - A Benchmark for Robust Inertial Orientation Estimation", Data 6(7), 2021,
doi:10.3390/data6070072, CC BY 4.0): a small slice of ``benchmarks/broad_consistency.py``.

The 45 s are cut into halves at t = 52.5 s and each is fitted with the sample config's
state plus the time offsets. What must hold on real data is what the benchmark found to
hold: the magnetometer's time offset (against the gyro-carried attitude) agrees between
the halves within 3σ and lies 3 to 5 samples early (the config's method, ``whole_span``,
carries the attitude with the gyro's own angle and rate random walks); the magnetometer
then sits at its
noise (normalized RMS near 0.6, the per-sample spread against the white-noise line of its
correlated samples, README); the optical reference lags the gyro by 1 to 4 ms.
"""

from __future__ import annotations

import shutil
from pathlib import Path

import numpy as np
import pytest

from gcs_core.config import load_config
from gcs_core.session import Analysis
from gcs_core.io.importer import load_mission
from repo_paths import ROOT

CONFIG = ROOT / "sample_data" / "configs" / "real-broad-02-slow-rotation.toml"
SPLIT_S = 52.5
SAMPLE_S = 1.0 / 285.714
three_sigma = 3.0


def _half(tmp: Path, first: bool) -> Path:
    src = load_config(CONFIG).mission
    out = tmp / ("h1" if first else "h2")
    shutil.copytree(src, out)
    for f in (out / "telemetry").glob("*.csv"):
        lines = f.read_text().splitlines()
        keep = [ln for ln in lines[1:] if (float(ln.split(",", 1)[0]) < SPLIT_S) == first]
        f.write_text("\n".join([lines[0], *keep]) + "\n")
    return out


@pytest.fixture(scope="module")
def halves(tmp_path_factory):
    if not CONFIG.is_file():
        pytest.skip("the BROAD sample mission is not bundled")
    tmp = tmp_path_factory.mktemp("broad")
    out = []
    for first in (True, False):
        cfg = load_config(CONFIG)
        cfg = cfg.with_changes(mission=_half(tmp, first),
                               state={"effects": ("MAG.time_offset", "OPT.time_offset", "MAG.nonorthogonality")})
        a = Analysis(cfg, mission=load_mission(cfg.mission))
        res = a.fit(holdout=False)
        out.append((a, res))
    return out


def test_magnetometer_time_offset_agrees_between_halves(halves):
    (_, a), (_, b) = halves
    name = "MAG.time_offset"
    va, vb = a.state.values()[name], b.state.values()[name]
    z = (va - vb) / np.hypot(a.sigma[name], b.sigma[name])
    assert abs(z) < three_sigma, (va, vb, z)
    for v in (va, vb):
        assert -5 * SAMPLE_S < v < -3 * SAMPLE_S


def test_magnetometer_at_its_noise_and_reference_lag(halves):
    for a, res in halves:
        assert 0.5 < a.rms()["MAG"] < 0.7
        assert 1e-3 < res.state.values()["OPT.time_offset"] < 4e-3


@pytest.mark.xfail(reason="the whole-span fit of the sample's second half (22.5 s) stops "
                   "'diverged' (no step lowers its cost) at a gyro bias_x 18 σ from the first "
                   "half's; the whole trial's halves agree (docs/benchmarks.md)", strict=False)
def test_gyro_bias_agrees_between_halves(halves):
    """With the gyro's noise as process noise the halves agree on its bias (the batch,
    carrying the attitude as exact, put them tens of σ apart: docs/benchmarks.md)."""
    (_, a), (_, b) = halves
    for axis in "xyz":
        name = f"GYR.bias_{axis}"
        va, vb = a.state.values()[name], b.state.values()[name]
        z = (va - vb) / np.hypot(a.sigma[name], b.sigma[name])
        assert abs(z) < three_sigma, (name, va, vb, z)
