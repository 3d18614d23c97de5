"""Noise from the data (gcs_core.noise.measured) against simulated noise of known strength.

The reference relations are IEEE Std 952-1997, Annex C: for a rate carrying white noise
of density N (angle random walk) and a random walk of strength K (rate random walk),
``σ²(τ) = N²/τ + K² τ/3``; N is read on the −1/2 line at τ = 1 s and K on the +1/2 line
at τ = 3 s. The tolerances are the estimators' own scatter at these spans (stated below).
"""

from __future__ import annotations

import numpy as np
import pytest
from repo_paths import TEST_DATA

from gcs_core.errors import InputError
from gcs_core.noise import measured as noise

DT = 0.01  # s
N_ARW = 1e-3  # rad/s^0.5
K_RRW = 1e-4  # rad/s^1.5
#: overlapping ADEV at τ0 from 4e5 samples scatters by ~0.2 %; N by ~1 % on its line
arw_tolerance = 0.03
#: K is read where few clusters remain (τ ~ 100-1000 s of a 4000 s span): ~15 % scatter
rrw_tolerance = 0.35
white_tolerance = 0.03


def _gyro(seed, n=400_000):
    rng = np.random.default_rng(seed)
    t = np.arange(n) * DT
    white = rng.normal(scale=N_ARW / np.sqrt(DT), size=(n, 1))
    walk = np.cumsum(rng.normal(scale=K_RRW * np.sqrt(DT), size=(n, 1)), axis=0)
    return t, white + walk


@pytest.mark.parametrize("seed", [0, 1])
def test_white_plus_random_walk_known_strength(seed):
    t, y = _gyro(seed)
    curve = noise.allan_deviation(t, y)[0]
    assert np.allclose(np.diff(np.log2(curve.tau)), 1.0)  # octaves
    g = noise.gyro_terms(curve)
    assert abs(g.arw / N_ARW - 1) < arw_tolerance and not g.arw_bound
    assert abs(g.rrw / K_RRW - 1) < rrw_tolerance and not g.rrw_bound
    # the model curve sqrt(N²/τ + K²τ/3) where both terms are well measured
    model = np.sqrt(N_ARW**2 / curve.tau + K_RRW**2 * curve.tau / 3)
    short = curve.tau < 10.0
    assert np.max(np.abs(curve.adev[short] / model[short] - 1)) < arw_tolerance
    # the white-noise line as a per-sample σ
    sigma, _, bound = noise.white_level(curve, DT)
    assert abs(sigma / (N_ARW / np.sqrt(DT)) - 1) < arw_tolerance and not bound


def test_white_noise_on_a_moving_signal_with_hits_and_held_samples():
    rng = np.random.default_rng(3)
    t = np.arange(50_000) * DT
    sigma = np.array([300.0, 50.0, 2.0])
    signal = 4e4 * np.column_stack([np.sin(0.5 * t), np.cos(0.3 * t), np.sin(0.2 * t + 1)])
    y = signal + rng.normal(size=(t.size, 3)) * sigma
    y[rng.choice(t.size, 20, replace=False)] += 1e5  # telemetry hits
    held = np.repeat(np.arange(t.size)[::2], 2)[: t.size]  # every value read twice
    est = noise.white_noise(t, y[held])
    assert np.max(np.abs(est / sigma - 1)) < white_tolerance


def test_quaternion_noise_in_radians():
    from gcs_core.frames.rotations import quat_from_dcm, rotvec_to_dcm

    rng = np.random.default_rng(4)
    n = 20_000
    t = np.arange(n) * DT
    truth = rotvec_to_dcm(np.column_stack([0.3 * t, 0.1 * t, 0 * t]))
    sigma = 1e-4
    q = quat_from_dcm(rotvec_to_dcm(rng.normal(scale=sigma, size=(n, 3))) @ truth)
    est = noise.white_noise(t, q, quaternion=True)
    assert np.max(np.abs(est / sigma - 1)) < white_tolerance


def test_too_few_samples_is_input_error():
    with pytest.raises(InputError):
        noise.allan_deviation(np.arange(5.0), np.zeros((5, 1)))


def test_both_converters_mark_estimated_noise_one_way(tmp_path):
    """One marker: the Astro Pi and BROAD converters' missions are both read as 'noise
    estimated from the data' for every sensor whose noise they estimated; a data book
    without the marker is not."""

    from test_convert_broad import _trial

    from gcs_core.convert import convert
    from gcs_core.noise.measured import ESTIMATED_MARK, noise_estimated

    data = TEST_DATA / "astropi"
    convert("astropi", data / "astropi_extract.csv", tmp_path / "a", tle=data / "iss-2022-01-31.tle")
    src = tmp_path / "trial.hdf5"
    _trial(src)
    convert("broad", src, tmp_path / "b")
    astro = (tmp_path / "a" / "mission.toml").read_text(encoding="utf-8")
    broad = (tmp_path / "b" / "mission.toml").read_text(encoding="utf-8")
    assert noise_estimated(astro, "MAG")
    assert all(noise_estimated(broad, s) for s in ("GYR", "MAG", "OPT"))
    assert not noise_estimated(broad, "NOPE")
    book = broad.replace(ESTIMATED_MARK, "from the data book")
    assert not any(noise_estimated(book, s) for s in ("GYR", "MAG", "OPT"))


def test_irregular_samples_give_the_noise_per_sample_used():
    """A sensor measured on some ticks of a faster bus only (held repeats and interpolated
    samples flagged and left out: BROAD's magnetometer, measurements 2 or 4 ticks apart).
    White noise of σ per measurement: the Allan curve's white line at the mean interval
    and the second differences over unequal intervals both give σ; on regular samples the
    curve is Eq C.2's (the per-window means of a full grid)."""
    rng = np.random.default_rng(12)
    gaps = rng.choice([2, 4], p=[0.6, 0.4], size=40_000)
    t = np.cumsum(gaps) * 0.0035  # s, the 285.7-Hz bus
    sigma = 700.0
    y = rng.normal(scale=sigma, size=(t.size, 3)) + 1e3 * np.sin(0.2 * t)[:, None]  # slow motion
    curves = noise.allan_deviation(t, y)
    tau_bar = noise.mean_interval(t)
    assert abs(tau_bar / (np.mean(gaps) * 0.0035) - 1.0) < 1e-3
    line = np.array([noise.white_level(c, tau_bar)[0] for c in curves])
    assert np.all(np.abs(line / sigma - 1.0) < white_tolerance), line
    spread = noise.white_noise(t, y)
    assert np.all(np.abs(spread / sigma - 1.0) < white_tolerance), spread
    # regular samples: the window means give the overlapping estimator of Eq C.2 exactly
    tr = np.arange(4096) * DT
    yr = rng.normal(size=(4096, 1))
    got = noise.allan_deviation(tr, yr)[0]
    theta = np.concatenate([[0.0], np.cumsum(yr[:, 0]) * DT])
    for k, m in enumerate((1, 4, 32)):
        j = int(np.log2(m))
        d2 = theta[2 * m :] - 2.0 * theta[m:-m] + theta[: -2 * m]
        want = np.sqrt(np.mean(d2**2) / (2.0 * (m * DT) ** 2))
        assert abs(got.adev[j] / want - 1.0) < 1e-9, (k, m)
