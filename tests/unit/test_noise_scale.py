"""The long-run noise factor of a sensor's residuals (gcs_core.noise.correlation.noise_scale).

Seeded synthetic residuals: white noise of the stated σ gives 1 within its batch-means
scatter (about 1/sqrt(2 n_b) for n_b windows); each draw held over ten samples gives √10
within the same; bad input is one line.
"""

from __future__ import annotations

from types import SimpleNamespace

import numpy as np
import pytest

from gcs_core.errors import InputError
from gcs_core.noise.correlation import noise_scale

RATE_HZ = 100.0
N = 60_000
WINDOW_S = 2.0
#: the batch-means estimate's scatter: 300 windows, 3 axes -> 1/sqrt(2·900) ≈ 2.4 %; 4σ
TOL = 4.0 / np.sqrt(2 * 3 * N / (RATE_HZ * WINDOW_S))


def _result(r, sigma):
    t = np.arange(r.shape[0]) / RATE_HZ
    res = SimpleNamespace(t=t, used=np.ones(r.shape[0], bool), residual=r, sigma=np.full(3, sigma))
    return SimpleNamespace(residuals={"OPT": res})


def test_white_noise_gives_one_and_held_draws_root_n():
    rng = np.random.default_rng(12)
    sigma = 1e-3
    white = sigma * rng.normal(size=(N, 3))
    assert abs(noise_scale(_result(white, sigma), "OPT", block_s=WINDOW_S) - 1.0) < TOL
    held = np.repeat(sigma * rng.normal(size=(N // 10, 3)), 10, axis=0)
    s = noise_scale(_result(held, sigma), "OPT", block_s=WINDOW_S)
    assert abs(s / np.sqrt(10.0) - 1.0) < TOL, s


def test_bad_input_is_one_line():
    res = _result(np.zeros((100, 3)), 1.0)
    with pytest.raises(InputError, match="positive"):
        noise_scale(res, "OPT", block_s=0.0)
    with pytest.raises(InputError, match="MAG"):
        noise_scale(res, "MAG", block_s=1.0)
