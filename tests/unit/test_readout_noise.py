"""The gyro's read-out noise σ_e in the whole-span normal equations (gcs_core.estimators.whole_span.readout).

Checked against a dense form: every row of the pass formed explicitly (static partials,
knot partials, residual, attitude partials D), grouped by epoch, and each epoch's rows
weighted by the inverse of their full covariance ``R + σ_e² D Dᵀ`` (an m_k × m_k inverse
per epoch, no Woodbury). The per-epoch elimination gives the same static normal matrix,
gradient, χ² and knot blocks to round-off; σ_e = 0 leaves the pass unchanged.
"""

from __future__ import annotations

from collections import defaultdict

import numpy as np
import pytest
from test_filter_consistency import sim_problem, simulate

from gcs_core.estimators.batch.least_squares import BatchOptions, batch_fit
from gcs_core.estimators.kalman.mekf import attitude_gyro_noise
from gcs_core.estimators.whole_span import fit as sb
from gcs_core.estimators.whole_span import knots as kn
from gcs_core.estimators.whole_span import passes as wsp
from gcs_core.estimators.whole_span.epoch_errors import EpochErrors
from gcs_core.estimators.whole_span.readout import seed_errors
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
    lin = passes.run(x, z, {})
    A, b, chi2, sysk, R = lin.A, lin.b, lin.chi2, lin.system, lin.R
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
    assert abs(passes.run(x, z, {}, jacobian=False).chi2 - chi_d) < ROUND_OFF * chi_d


def test_epoch_elimination_synthetic_rows_both_forms(monkeypatch):
    """Random rows of two sensors sharing epochs, one sensor with a repeated time: the
    compiled and numpy forms of the elimination give the dense per-epoch weighting."""
    from types import SimpleNamespace

    from gcs_core.estimators.whole_span import readout

    rng = np.random.default_rng(11)
    p = 5
    sensors = [SimpleNamespace(name="S1"), SimpleNamespace(name="S2")]
    blocks = [
        (sensors[0], np.array([0.0, 1.0, 2.0, 3.0]), 2, np.array([0, 2, 4])),
        (sensors[1], np.array([1.0, 1.0, 3.0]), 3, np.array([1, 2])),  # a repeated time
    ]
    data = []
    for sd, t, m, cols in blocks:
        n = t.size
        D = rng.normal(size=(n, m, 3)) * 1e4
        w = np.ones((n, m))
        Hm = rng.normal(size=(n * m, cols.size))
        rw = rng.normal(size=n * m)
        data.append((sd, t, m, cols, D, w, Hm, rw))
    sig_e2 = 1e-8

    def eliminate(compiled: bool):
        monkeypatch.setattr(readout, "COMPILED", compiled)
        A, b = np.zeros((p, p)), np.zeros(p)
        ro = readout.ReadoutEpochs(sig_e2, A, b, None, sensors)
        for sd, t, _m, cols, D, w, Hm, rw in data:
            ro.visit(sd)
            ro.add(t, D, w, None, np.column_stack((Hm, rw)), cols)
        return A, b, ro.finish()

    rows: dict = {}
    for _, t, m, cols, D, _, Hm, rw in data:
        for i, ti in enumerate(t):
            H = np.zeros((m, p))
            H[:, cols] = Hm[i * m : (i + 1) * m]
            rows.setdefault(float(ti), []).append((H, rw[i * m : (i + 1) * m], D[i]))
    A_d, b_d, removed = np.zeros((p, p)), np.zeros(p), 0.0
    for rs in rows.values():
        H = np.concatenate([r[0] for r in rs])
        r = np.concatenate([r[1] for r in rs])
        D = np.concatenate([r[2] for r in rs])
        W = np.eye(r.size) - np.linalg.inv(np.eye(r.size) + sig_e2 * D @ D.T)  # I − (I + σ²DDᵀ)⁻¹
        A_d -= H.T @ W @ H
        b_d -= H.T @ W @ r
        removed += r @ W @ r
    for compiled in (True, False) if readout.COMPILED else (False,):
        A, b, chi = eliminate(compiled)
        np.testing.assert_allclose(A, A_d, rtol=1e-9, atol=1e-9 * np.abs(A_d).max())
        np.testing.assert_allclose(b, b_d, rtol=1e-9, atol=1e-9 * np.abs(b_d).max())
        assert chi == pytest.approx(removed, rel=1e-9)


def test_window_sums_equal_the_per_frame_form(monkeypatch):
    """With the span's epochs known (the fit's case) the blocks go straight into the
    window's epochs (``_add_into_window``), a repeated time included: the same A, b and χ²
    as the per-frame products scattered at the window's end."""
    from types import SimpleNamespace

    from gcs_core.estimators.whole_span import readout

    if not readout.COMPILED:
        pytest.skip("the window sums are the compiled form")
    rng = np.random.default_rng(5)
    p = 4
    t1, t2 = np.array([0.0, 1.0, 2.0, 3.0, 5.0]), np.array([1.0, 1.0, 3.0, 4.0])
    sensors = [SimpleNamespace(name="S1", t=t1, n=t1.size), SimpleNamespace(name="S2", t=t2, n=t2.size)]
    data = []
    for sd, m, cols in ((sensors[0], 2, np.array([0, 3])), (sensors[1], 3, np.array([1, 2, 3]))):
        n = sd.t.size
        D, Hm, rw = rng.normal(size=(n, m, 3)) * 1e4, rng.normal(size=(n * m, cols.size)), rng.normal(size=n * m)
        data.append((sd, m, cols, D, Hm, rw))

    def eliminate(errors):
        A, b = np.zeros((p, p)), np.zeros(p)
        ro = readout.ReadoutEpochs(1e-8, A, b, None, sensors, errors)
        for window in (0, 1):  # each sensor once per window; an epoch's rows in one window
            for sd, m, cols, D, Hm, rw in data:
                lo, hi = (0, 2) if window == 0 else (2, sd.t.size)
                ro.visit(sd)
                w = np.ones((hi - lo, m))
                Hr = np.column_stack((Hm, rw))[lo * m : hi * m]
                ro.add(sd.t[lo:hi], D[lo:hi], w, None, Hr, cols)
        return A, b, ro.finish()

    A0, b0, c0 = eliminate(None)
    A1, b1, c1 = eliminate(EpochErrors(sensors))
    np.testing.assert_allclose(A1, A0, rtol=1e-12, atol=1e-12 * np.abs(A0).max())
    np.testing.assert_allclose(b1, b0, rtol=1e-12, atol=1e-12 * np.abs(b0).max())
    assert c1 == pytest.approx(c0, rel=1e-12)


def test_sorted_union_is_numpy_unique():
    from gcs_core.estimators.whole_span.epoch_errors import _sorted_union

    rng = np.random.default_rng(2)
    ts = [np.sort(rng.integers(0, 50, size=n).astype(float)) for n in (0, 7, 30, 30)]
    np.testing.assert_array_equal(_sorted_union(ts), np.unique(np.concatenate(ts)))
    assert _sorted_union([]).size == 0


def test_seed_from_the_batch_is_the_first_pass():
    """The read-out errors' first optimum from the batch's residuals and attitude partials
    (``readout.seed_errors``) is what a pass without the Jacobian finds at the batch's point."""
    problem, _, grid, passes = _setup(SIGMA_E)
    partials: dict = {}
    batch = batch_fit(problem, NO_EDIT, attitude_partials=partials)
    z = np.zeros((grid.K, grid.d))
    passes.run(np.asarray(batch.x), z, {}, jacobian=False)
    from_pass = passes.errors.cond.copy()
    passes.errors.cond[:] = 0.0
    seed_errors(passes.errors, problem.sensors, batch.residuals, partials, SIGMA_E**2)
    assert passes.errors.seeded
    assert np.max(np.abs(passes.errors.cond - from_pass)) < ROUND_OFF * SIGMA_E


def test_the_joint_step_predicts_the_read_out_errors(monkeypatch):
    """After a step of the statics and knots, the read-out errors' conditional optimum at
    the new point is the recorded pass's prediction (``EpochErrors.predicted``) to second
    order: its miss is a small fraction of the move."""
    problem, batch, grid, passes = _setup(SIGMA_E)
    x = np.asarray(batch.x)
    z = np.zeros((grid.K, grid.d))
    passes.run(x, z, {}, jacobian=False)
    passes.errors.adopt()
    lin = passes.run(x, z, {})  # records the sensitivities
    before = passes.errors.cond.copy()
    rng = np.random.default_rng(3)
    dx = rng.normal(size=x.size) * np.sqrt(np.diag(batch.P))  # a 1-σ step of every static
    dz = np.zeros_like(z)
    dz[1:, :3] = rng.normal(0, 2 * SIGMA_E, (grid.K - 1, 3))
    pred = passes.errors.predicted(dx, dz, grid, lin.R, 1.0 / SIGMA_E**2)
    from gcs_core.estimators.whole_span import epoch_errors

    monkeypatch.setattr(epoch_errors, "COMPILED", False)  # the numpy form gives the same
    np.testing.assert_allclose(
        passes.errors.predicted(dx, dz, grid, lin.R, 1.0 / SIGMA_E**2), pred, atol=1e-9 * SIGMA_E
    )
    monkeypatch.undo()
    passes.run(x + dx, z + dz, {}, jacobian=False)
    after = passes.errors.cond
    move, miss = np.max(np.abs(after - before)), np.max(np.abs(pred - after))
    assert move > 0.05 * SIGMA_E  # the step moves the read-out errors
    assert miss < 0.02 * move, (miss / SIGMA_E, move / SIGMA_E)
