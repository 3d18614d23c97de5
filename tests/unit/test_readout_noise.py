"""The gyro's read-out noise σ_e in the whole-span normal equations (gcs_core.filtr.readout).

Checked against a dense form: every row of the pass formed explicitly (static partials,
knot partials, residual, attitude partials D), grouped by epoch, and each epoch's rows
weighted by the inverse of their full covariance ``R + σ_e² D Dᵀ`` (an m_k × m_k inverse
per epoch, no Woodbury). The per-epoch elimination gives the same static normal matrix,
gradient, χ² and knot blocks to round-off; σ_e = 0 leaves the pass unchanged.
"""

from __future__ import annotations

from collections import defaultdict

import numpy as np
from test_filter_consistency import sim_problem, simulate

from gcs_core.filtr import knots as kn
from gcs_core.filtr import smoothing_batch as sb
from gcs_core.filtr import whole_span_passes as wsp
from gcs_core.filtr.batch import BatchOptions, batch_fit
from gcs_core.filtr.mekf import attitude_gyro_noise
from gcs_core.problem.linearization import iter_blocks

NO_EDIT = BatchOptions(edit_k=None)
#: relative round-off of the Woodbury elimination against the dense inverse
ROUND_OFF = 1e-8
#: a read-out noise comparable to the trackers' (2e-5 rad in this simulator)
SIGMA_E = 3e-5


def _setup(sig_e: float, seed: int = 3):
    mission, _ = simulate(seed, duration_s=300.0, electronic=sig_e, tracker_every=1)
    problem = sim_problem(mission)
    batch = batch_fit(problem, NO_EDIT)
    names = batch.solve_for
    state = problem.state
    x_bar = np.array([state[nm].value for nm in names])
    prior = 1.0 / np.array([state[nm].sigma0 for nm in names]) ** 2
    noise = attitude_gyro_noise(problem)
    grid = sb.make_knots(problem, noise, batch.information, names, spacing=30.0)
    passes = wsp.Passes(problem, names, grid, x_bar, prior, noise.sigma_e**2)
    passes.stream = False
    return problem, batch, grid, passes


def _dense_rows(problem, passes, x, z, R):
    """Per epoch time: the whitened rows [H | U | r] and D (module docstring)."""
    passes.set_x(x)
    prob = wsp.Dynamics(passes.grid, z, R).problem(problem)
    rows = defaultdict(list)
    n = len(passes.names)
    for blk in iter_blocks(prob, passes.values, passes.names, weighted=True):
        sd = blk.sensor
        t = sd.t[blk.lo : blk.hi]
        w = blk.used[:, None] / sd.sigma[None, :]
        D = np.nan_to_num(blk.pred.d_att) * w[:, :, None]
        C = kn.chained_attitude(blk.geom.C_BI, passes.grid, z, R, t)
        U = kn.knot_rows(D, C, t, passes.grid.index(t), passes.grid, R)
        H = np.zeros(D.shape[:2] + (n,))
        H[:, :, blk.cols] = blk.H
        rw = np.where(blk.used[:, None], blk.r, 0.0) * w
        for i, ti in enumerate(t):
            rows[float(ti)].append((H[i], U[i], rw[i], D[i]))
    return rows


def test_epoch_elimination_equals_the_dense_covariance():
    """A, b, χ² and the knot blocks of a pass with σ_e equal the dense per-epoch weighting."""
    problem, batch, grid, passes = _setup(SIGMA_E)
    assert passes.sig_e2 == SIGMA_E**2
    x = np.asarray(batch.x)
    rng = np.random.default_rng(7)
    z = np.zeros((grid.K, grid.d))
    z[1:, :3] = rng.normal(0, 1e-5, (grid.K - 1, 3))
    z[1:, 3:] = rng.normal(0, 1e-8, (grid.K - 1, 3))
    A, b, chi2, _, sysk, R = passes.run(x, z, {})
    n = x.size
    A_d, b_d, chi_d = np.zeros((n, n)), np.zeros(n), 0.0
    Dk, Bk = np.zeros_like(sysk.Dk), np.zeros_like(sysk.Bk)
    for t, rs in _dense_rows(problem, passes, x, z, R).items():
        H = np.concatenate([r[0] for r in rs])
        U = np.concatenate([r[1] for r in rs])
        r = np.concatenate([r[2] for r in rs])
        D = np.concatenate([r[3] for r in rs])
        W = np.linalg.inv(np.eye(r.size) + SIGMA_E**2 * D @ D.T)  # (R + σ_e² D Dᵀ)⁻¹, whitened
        A_d += H.T @ W @ H
        b_d += H.T @ W @ r
        chi_d += r @ W @ r
        j = int(grid.index(np.array([t]))[0])
        Dk[j] += U.T @ W @ U
        Bk[j, :, :n] += U.T @ W @ H
        Bk[j, :, n] += U.T @ W @ r
    scale = np.sqrt(np.diag(A_d))
    assert np.max(np.abs(A - A_d) / np.outer(scale, scale)) < ROUND_OFF
    assert np.max(np.abs(b - b_d) / scale) < ROUND_OFF * np.sqrt(chi_d)
    assert abs(chi2 - chi_d) < ROUND_OFF * chi_d
    np.testing.assert_allclose(sysk.Dk, Dk, rtol=ROUND_OFF, atol=ROUND_OFF * np.abs(Dk).max())
    np.testing.assert_allclose(sysk.Bk, Bk, rtol=1e-6, atol=ROUND_OFF * np.abs(Bk).max())
    # the line search's χ² (no Jacobian) is the same generalized χ²
    assert abs(passes.run(x, z, {}, jacobian=False)[2] - chi_d) < ROUND_OFF * chi_d
