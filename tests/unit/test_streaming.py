"""Streaming by chunks (issue 5): the numbers do not depend on the chunk length.

A short simulated mission is fitted and diagnosed twice: once in one chunk (every frame of
the span at once, the gyro propagation in one block) and once forced into tiny chunks
(97 frames, gyro blocks of 97 knots, so that every carry between blocks and every chunk
edge is exercised). Estimates, covariance, residuals, editing and the ranking's Δχ² agree
to round-off. Smaller pieces are checked on their own: the gyro-carried attitude evaluated
block by block, the factored attitude partials, the held auxiliary channels.
"""

from __future__ import annotations

import numpy as np
import pytest

from gcs_core.config_schema import AnalysisConfig
from gcs_core.diagnosis.ranking import rank_candidates
from gcs_core.estimators.batch.least_squares import BatchOptions, batch_fit, normal_equations
from gcs_core.io.aux_hold import hold_channels
from gcs_core.problem.linearization import chunk_windows, iter_blocks, linearize
from gcs_core.problem.prepare import HeldChannels
from gcs_core.session import Analysis
from gcs_core.sim.scenarios import nominal_threeaxis, with_effect
from gcs_core.sim.writer import write_mission

TINY = 97  # frames per chunk / knots per gyro block, forced
ONE_CHUNK = 10**9  # the whole span at once
round_off = 1e-9  # relative agreement expected between chunkings
one_sigma = 1.0


@pytest.fixture(scope="module")
def mission_dir(tmp_path_factory):
    """40 minutes of the three-axis sample mission with a hidden FHST time offset, and the
    stellar-aberration correction switched off in the analysis: both a sensor effect and a
    physics effect are candidates."""
    folder = tmp_path_factory.mktemp("streaming")
    cfg = with_effect(nominal_threeaxis("sun_pointing", seed=5, duration_s=2400.0), "FHST1.time_offset", 0.5)
    return write_mission(cfg, folder / "m", truth_path=folder / "truth.json")


def _analysis(mission_dir, chunk: int) -> Analysis:
    physics = {"stellar_aberration": False, "solar_aberration": True, "sun_parallax": True, "field_model": "igrf"}
    a = Analysis(AnalysisConfig(mission=mission_dir).with_changes(physics=physics))
    a.problem.set_chunk(chunk)
    return a


@pytest.fixture(scope="module")
def fits(mission_dir):
    out = {}
    for label, chunk in (("one", ONE_CHUNK), ("tiny", TINY)):
        a = _analysis(mission_dir, chunk)
        out[label] = (a, batch_fit(a.problem, BatchOptions()))
    return out


def test_tiny_chunks_really_are_tiny(fits):
    a, _ = fits["tiny"]
    windows = chunk_windows(a.problem, a.problem.sensors)
    assert len(windows) > 20
    assert max(hi - lo for w in windows for lo, hi in w) <= TINY
    seen = 0
    for blk in iter_blocks(a.problem, a.problem.state.values(), list(a.problem.state.solve_for)):
        assert blk.hi - blk.lo <= TINY
        assert len(a.problem.attitude._blocks) <= 1  # one propagation block held
        seen += blk.hi - blk.lo
    assert seen == sum(sd.n for sd in a.problem.sensors)


def test_batch_fit_does_not_depend_on_the_chunk(fits):
    (_, r1), (_, r2) = fits["one"], fits["tiny"]
    assert r1.status == r2.status == "converged" and r1.iterations == r2.iterations
    sig = np.sqrt(np.diag(r1.P))
    assert np.max(np.abs(r1.x - r2.x) / sig) < round_off * 1e3 * one_sigma
    np.testing.assert_allclose(r2.P, r1.P, rtol=round_off, atol=round_off * np.max(np.abs(r1.P)))
    np.testing.assert_allclose(
        r2.information, r1.information, rtol=round_off, atol=round_off * np.max(np.abs(r1.information))
    )
    assert r2.chi2 == pytest.approx(r1.chi2, rel=round_off)
    for name, a in r1.residuals.items():
        b = r2.residuals[name]
        assert np.array_equal(a.valid, b.valid) and np.array_equal(a.edited, b.edited)
        np.testing.assert_allclose(b.normalized, a.normalized, rtol=0, atol=1e-6)
        # relative to the sensor's scale: a prediction that crosses zero has no relative digits
        np.testing.assert_allclose(b.y_pred, a.y_pred, rtol=round_off, atol=round_off * np.nanmax(np.abs(a.y_pred)))


def test_ranking_does_not_depend_on_the_chunk(fits):
    (a1, r1), (a2, _) = fits["one"], fits["tiny"]
    effects = a1.candidate_effects()
    assert any(e.physics for e in effects) and any(not e.physics for e in effects)
    c1 = {c.id: c for c in rank_candidates(a1.problem, r1, effects)}
    c2 = {c.id: c for c in rank_candidates(a2.problem, r1, effects)}
    assert set(c1) == set(c2)
    top = max(c1.values(), key=lambda c: c.delta_chi2)
    assert top.delta_chi2 > 100.0  # the hidden time offset (or its alias) is seen
    for k, c in c1.items():
        assert c2[k].delta_chi2 == pytest.approx(c.delta_chi2, rel=1e-7, abs=1e-6), k
        assert c2[k].dof == c.dof


def test_legacy_linearize_equals_the_blocks(fits):
    a, r = fits["tiny"]
    names = list(r.solve_for)
    values = r.state.values()
    lins = {lin.name: lin for lin in linearize(a.problem, values, names)}
    for blk in iter_blocks(a.problem, values, names):
        lin = lins[blk.name]
        full = lin.H[blk.lo : blk.hi][:, :, blk.cols]
        np.testing.assert_array_equal(full[blk.valid], blk.H[blk.valid])
        others = np.setdiff1d(np.arange(len(names)), blk.cols)
        assert not np.any(lin.H[blk.lo : blk.hi][:, :, others])  # no data depends on them


@pytest.mark.parametrize("label", ["one", "tiny"])
def test_summed_rows_equal_the_stored_rows(fits, label, monkeypatch):
    """The normal equations from rows summed a tile at a time (``chain_gram``, BLAS dsyrk)
    equal those from the stored rows (``chain_rows`` and ``Hrᵀ Hr``), and the blocks that
    were summed are most of them."""
    from gcs_core.compiled import COMPILED
    from gcs_core.problem import kernels as batch_kernels

    a, r = fits[label]
    names = list(r.solve_for)
    values = r.state.values()
    summed = [
        blk.G is not None for blk in iter_blocks(a.problem, values, names, weighted=True, augmented=True, gram=True)
    ]
    A1, b1, c1, m1 = normal_equations(a.problem, values, names, {})
    monkeypatch.setattr(batch_kernels, "DSYRK", None)
    A2, b2, c2, m2 = normal_equations(a.problem, values, names, {})
    if COMPILED:
        assert sum(summed) >= 0.5 * len(summed)
    np.testing.assert_allclose(A1, A2, rtol=round_off, atol=round_off * np.max(np.abs(A2)))
    np.testing.assert_allclose(b1, b2, rtol=round_off, atol=round_off * np.max(np.abs(b2)))
    assert c1 == pytest.approx(c2, rel=round_off) and m1 == m2


def test_gyro_attitude_by_blocks_equals_one_block(fits):
    a, r = fits["one"]
    att = a.problem.attitude
    values = r.state.values()
    t = np.sort(np.concatenate([att.knots[1:], np.random.default_rng(3).uniform(att.knots[0], att.knots[-1], 300)]))
    att.block_knots = ONE_CHUNK
    whole = att.evaluate(values, t)
    att.block_knots = TINY
    parts = att.evaluate(values, t)
    att.block_knots = ONE_CHUNK
    np.testing.assert_allclose(parts.C_BI, whole.C_BI, rtol=0, atol=1e-13)
    np.testing.assert_allclose(parts.J, whole.J, rtol=0, atol=1e-9 * np.max(np.abs(whole.J)))
    np.testing.assert_array_equal(parts.omega_B, whole.omega_B)


def test_factored_partials_chain_like_the_jacobian(fits):
    a, r = fits["one"]
    att = a.problem.attitude
    values = r.state.values()
    t = a.problem.sensors[0].t[:500]
    fr = att.frames(values, t)
    D = np.random.default_rng(4).standard_normal((t.size, 3, 3))
    sel = np.array([0, 2, 3, 4, 5, 12, 13, 19, 20])
    np.testing.assert_allclose(
        fr.chain(D, sel), D @ att.evaluate(values, t).J[:, :, sel], rtol=1e-12, atol=1e-12 * np.max(np.abs(fr.J))
    )


def test_held_channels_equal_the_stored_ones(fits):
    a, _ = fits["one"]
    sd = a.problem.sensor("TAM1")
    aux = a.problem.builder.aux
    ref = hold_channels(aux, sd.t)
    held = sd.geom.aux
    assert isinstance(held, HeldChannels) and set(held) == set(ref)
    for k, v in ref.items():
        np.testing.assert_array_equal(held[k], v)
        np.testing.assert_array_equal(held.window(100, 250)[k], v[100:250])
