"""The bundled BROAD sample mission (real data: D. Laidig, M. Caruso, A. Cereatti, T. Seel,
"BROAD - A Benchmark for Robust Inertial Orientation Estimation", Data 6(7), 2021,
doi:10.3390/data6070072, CC BY 4.0): a small slice of ``benchmarks/broad_consistency.py``.

The 45 s are cut into halves at t = 52.5 s and each is fitted with the sample config's
state plus the effects discovery adds (the time offsets, the lab field's gradient over the
optical position, the non-orthogonality). What must hold on real data is what the
benchmark found to hold: the magnetometer's time offset (against the gyro-carried
attitude) agrees between the halves within 3σ and lies 3 to 5 samples early (the config's
method, ``whole_span``, carries the attitude with the gyro's own angle and rate random
walks); the magnetometer then sits at its noise (normalized RMS near 1: its held repeats
and interpolated samples flagged, the samples used are nearly white, docs/case_studies/broad.md); the optical
reference lags the gyro by 1 to 4 ms; and the magnetometer's bias and matrix, the field
and its gradient agree between the halves within 3σ once the σ carry the residuals'
correlation (the batch-means sandwich, :mod:`gcs_core.noise.correlation`, in windows
of :data:`WINDOW_S`: 23 per half); with the fit's white-noise σ they do not.
"""

from __future__ import annotations

import shutil
from pathlib import Path

import numpy as np
import pytest
from repo_paths import ROOT

from gcs_core.config import load_config
from gcs_core.estimators.gyro_bias import gyro_bias_at
from gcs_core.io.importer import load_mission
from gcs_core.noise.correlation import sigma_scale
from gcs_core.session import Analysis

CONFIG = ROOT / "sample_data" / "configs" / "real-broad-02-slow-rotation.toml"
SPLIT_S = 52.5
SAMPLE_S = 1.0 / 285.714
three_sigma = 3.0
#: the sandwich's window [s]: longer than the optical residual's correlation (≈0.1 s), and
#: 23 windows per 22.5-s half (4-s windows, as the benchmark uses on whole trials, leave 5)
WINDOW_S = 1.0
EFFECTS = ("MAG.time_offset", "OPT.time_offset", "MAG.field_gradient", "MAG.nonorthogonality")
MAGNETIC = (
    tuple(f"MAG.bias_{a}" for a in "xyz")
    + ("MAG.nonorth_xy", "MAG.nonorth_xz", "MAG.nonorth_yz")
    + tuple(f"field.B_{a}" for a in "xyz")
    + tuple(f"field.G_{ab}" for ab in ("xx", "xy", "xz", "yy", "yz"))
)


def _half(tmp: Path, first: bool) -> Path:
    src = load_config(CONFIG).mission
    out = tmp / ("h1" if first else "h2")
    shutil.copytree(src, out)
    for f in (out / "telemetry").glob("*.csv"):
        lines = f.read_text().splitlines()
        n_head = next(i for i, ln in enumerate(lines) if ln.startswith("t,")) + 1  # comments, header
        keep = [ln for ln in lines[n_head:] if (float(ln.split(",", 1)[0]) < SPLIT_S) == first]
        f.write_text("\n".join([*lines[:n_head], *keep]) + "\n")
    return out


@pytest.fixture(scope="module")
def halves(tmp_path_factory):
    if not CONFIG.is_file():
        pytest.skip("the BROAD sample mission is not bundled")
    tmp = tmp_path_factory.mktemp("broad")
    out = []
    for first in (True, False):
        cfg = load_config(CONFIG)
        cfg = cfg.with_changes(mission=_half(tmp, first), state={"effects": EFFECTS})
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
        assert 0.9 < a.rms()["MAG"] < 1.1
        assert 1e-3 < res.state.values()["OPT.time_offset"] < 4e-3


def test_magnetometer_and_field_agree_between_halves_with_honest_sigma(halves):
    (a_an, a), (b_an, b) = halves
    sa = sigma_scale(a_an.problem, a, block_s=WINDOW_S).honest_sigma(a.sigma)
    sb = sigma_scale(b_an.problem, b, block_s=WINDOW_S).honest_sigma(b.sigma)
    va, vb = a.state.values(), b.state.values()
    z = {n: (va[n] - vb[n]) / np.hypot(sa[n], sb[n]) for n in MAGNETIC}
    z_fit = {n: (va[n] - vb[n]) / np.hypot(a.sigma[n], b.sigma[n]) for n in MAGNETIC}
    worst = max(z, key=lambda n: abs(z[n]))
    assert abs(z[worst]) < three_sigma, (worst, z[worst], z)
    assert max(abs(x) for x in z_fit.values()) > three_sigma  # the white-noise σ are optimistic


@pytest.mark.xfail(
    reason="on this 45 s sample the halves' gyro bias_x at the time they meet "
    "(gcs_core.estimators.gyro_bias.gyro_bias_at, σ with the walk), with the config's "
    "long-run weighting of the optical reference, is 2.8 against 9.6 mrad/s, 12 σ "
    "apart (the rests' mean is 3.5; with white weights −2.1 against +11.5, 32 σ): "
    "in 22.5 s of hand motion the second half's bias_x is carried with its roll "
    "and drift; on the whole trials the halves agree within 2.7 σ that way "
    "(docs/benchmarks.md, BROAD)",
    strict=False,
)
def test_gyro_bias_agrees_between_halves(halves):
    """The halves' gyro bias where they meet (``GYR.bias`` is the bias at a span's first
    knot: the two halves' are taken 22.5 s apart), with σ carrying the walk between."""
    (an_a, a), (an_b, b) = halves
    ga = gyro_bias_at(an_a.problem, a, np.array([SPLIT_S]))
    gb = gyro_bias_at(an_b.problem, b, np.array([SPLIT_S]))
    z = (ga.b[0] - gb.b[0]) / np.hypot(ga.sigma[0], gb.sigma[0])
    assert np.all(np.abs(z) < three_sigma), (ga.b[0], gb.b[0], z)
