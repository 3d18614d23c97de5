"""The batch's second-order terms and its refinement of a sensor's own non-linear parameters.

The fine Sun sensor's transfer function ``A3 sin(k tan α)`` (seed Eq 4-23) is bilinear in
``A3`` and ``k``: with ``A3`` near 0 the Gauss–Newton matrix leaves ``k`` flat while the
cost still bends along ``A3·k``. Checked here:

* the Newton terms ``K = −Σ (r/σ²) ∂²h`` added to ``Hᵀ R⁻¹ H`` equal the Hessian of the
  cost by central differences of its gradient (Nocedal & Wright 2006, §10.3: the
  least-squares Hessian is the Gauss–Newton matrix plus the residual-weighted second
  derivatives);
* the model's held evaluation (geometry held) equals its full prediction;
* the refinement (:mod:`gcs_core.estimators.batch.local_refine`) leaves the refined elements at the
  minimum of the cost with everything else held;
* the batch with both reaches the same minimum as plain Gauss–Newton iterated to the end,
  in fewer linearizations.
"""

from __future__ import annotations

import numpy as np
import pytest
from model_fixtures import fine_sun_case

from gcs_core.estimators.batch import least_squares as batch_mod
from gcs_core.estimators.batch import local_refine
from gcs_core.estimators.batch.least_squares import BatchOptions, batch_fit, normal_equations
from gcs_core.io.importer import load_mission
from gcs_core.models import common
from gcs_core.problem.build import ElementOverride, StateOptions, build_problem
from gcs_core.problem.state import SOLVE_FOR
from gcs_core.sim.scenarios import nominal_threeaxis
from gcs_core.sim.writer import write_mission

#: "the same minimum": every element within this fraction of its σ
same_minimum = 1e-3
#: the Newton matrix against the differenced gradient, relative to √(N_ii N_jj)
hessian_agreement = 1e-3


@pytest.fixture(scope="module")
def problem(tmp_path_factory):
    """Twenty minutes of the Sun-pointing sample mission (FSS, TAM, trackers, gyro); the
    data-book transfer function is the truth (A3 = 0: k rests on its a priori). The
    frequencies, held by default with a zero book amplitude, are solved for here."""
    cfg = nominal_threeaxis("sun_pointing", seed=7, duration_s=1200.0)
    cfg.sensors = [s for s in cfg.sensors if s.type != "coarse_sun"]
    mdir = write_mission(cfg, tmp_path_factory.mktemp("newton") / "m")
    solve_k = {n: ElementOverride(role=SOLVE_FOR) for n in ("FSS1.k_alpha", "FSS1.k_beta")}
    return build_problem(load_mission(mdir), options=StateOptions(overrides=solve_k))


@pytest.fixture(scope="module")
def fitted(problem):
    return batch_fit(problem, BatchOptions(edit_k=None, tol_step_sigma=1e-6, tol_chi2=1e-9, max_iterations=40))


def _gradient(problem, names, x):
    values = problem.state.values()
    values.update(dict(zip(names, x)))
    K = np.zeros((len(names), len(names)))
    A, b, _, _ = normal_equations(problem, values, names, {}, second_order=K)
    return A, b, K


def test_newton_terms_equal_the_differenced_hessian(problem, fitted):
    names = list(problem.state.solve_for)
    x = fitted.x
    sig = np.sqrt(np.diag(fitted.P))
    A, _, K = _gradient(problem, names, x)
    N = A + K
    sel = [j for j, nm in enumerate(names) if nm.startswith("FSS1.")]
    for j in sel:
        h = 1e-2 * sig[j]
        xp, xm = x.copy(), x.copy()
        xp[j] += h
        xm[j] -= h
        # b = Hᵀ R⁻¹ r = −½ ∂χ²/∂x: the column of ½ ∂²χ²/∂x² is −(b⁺ − b⁻)/2h
        col = -(_gradient(problem, names, xp)[1] - _gradient(problem, names, xm)[1]) / (2 * h)
        scale = np.sqrt(np.abs(np.diag(N)[sel] * N[j, j]))
        err = np.abs(col[sel] - N[sel, j]) / scale
        assert err.max() < hessian_agreement, (names[j], err.max())
    # the Gauss–Newton matrix alone misses the A3·k bend the data give
    kb = names.index("FSS1.k_beta")
    b3 = names.index("FSS1.B3")
    assert abs(K[kb, b3]) > 0.05 * np.sqrt(A[kb, kb] * A[b3, b3])


def test_held_evaluation_equals_the_prediction():
    rng = np.random.default_rng(3)
    model, geom, params = fine_sun_case(rng)
    p = {**model.nominal(), **params}
    held = model.held(geom, p)
    moved = {**p, "A3": p["A3"] * 1.5 + 1e-4, "k_beta": p["k_beta"] + 0.7, "B2": p["B2"] * (1 + 1e-4)}
    pred, hp = model.predict(geom, moved), held(moved)
    np.testing.assert_allclose(hp.y, pred.y, rtol=1e-13, atol=1e-9)
    for name, (c, v) in hp.d_par.items():
        np.testing.assert_allclose(np.broadcast_to(v, (geom.n,)), pred.d_par[name][:, c], rtol=1e-12, atol=1e-12)
    for pair, entry in hp.d2_par.items():
        c, v = common.component_values(entry, geom.n)
        c2, v2 = common.component_values(pred.d2_par[pair], geom.n)
        assert c == c2
        np.testing.assert_allclose(v, v2, rtol=1e-12, atol=1e-12)
    rows = np.array([0, 2, 3])
    np.testing.assert_allclose(model.held(geom, p, rows=rows)(moved).y, pred.y[rows], rtol=1e-13)


def test_refinement_ends_at_the_conditional_minimum(problem, fitted):
    """From a state with the FSS elements moved off, the refinement returns them to the
    minimum of the cost with everything else held: the local Newton step is negligible."""
    names = list(problem.state.solve_for)
    groups = local_refine.own_nonlinear(problem, names)
    assert set(groups) == {"FSS1"} and "FSS1.k_beta" in groups["FSS1"]
    state = problem.state
    x_bar = np.array([state[n].value for n in names])
    s0 = np.array([state[n].sigma0 for n in names])
    prior_info = 1.0 / s0**2
    sig = np.sqrt(np.diag(fitted.P))
    x = fitted.x.copy()
    for e in groups["FSS1"]:
        x[names.index(e)] += 0.8 * sig[names.index(e)]
    values = state.values()
    x_ref = local_refine.refine_local(problem, values, names, x, x_bar, prior_info, {}, groups, 1e-6)
    sel = [names.index(e) for e in groups["FSS1"]]
    other = [j for j in range(len(names)) if j not in sel]
    np.testing.assert_array_equal(x_ref[other], x[other])
    A, b, K = _gradient(problem, names, x_ref)
    N = (A + K + np.diag(prior_info))[np.ix_(sel, sel)]
    step = np.linalg.solve(N, (b + prior_info * (x_bar - x_ref))[sel])
    assert np.max(np.abs(step) / sig[sel]) < 1e-4


def test_batch_reaches_the_gauss_newton_minimum_in_fewer_passes(problem, fitted, monkeypatch):
    names = list(problem.state.solve_for)
    sig = np.sqrt(np.diag(fitted.P))
    passes = []
    original = batch_mod.normal_equations

    def counted(*a, **k):
        passes.append(k.get("jacobian", True))
        return original(*a, **k)

    monkeypatch.setattr(batch_mod, "normal_equations", counted)
    res = batch_fit(problem, BatchOptions(edit_k=None))
    fast = sum(passes)
    passes.clear()
    # plain Gauss–Newton (no refinement, no Newton terms): more passes to its stopping
    # rule, and iterated to the end, the same minimum
    monkeypatch.setattr(local_refine, "own_nonlinear", lambda *a: {})
    monkeypatch.setattr(batch_mod.curvature, "newton_matrix", lambda *a: None)
    batch_fit(problem, BatchOptions(edit_k=None))
    assert fast < sum(passes), (fast, sum(passes))
    plain = batch_fit(problem, BatchOptions(edit_k=None, tol_step_sigma=1e-6, tol_chi2=1e-9, max_iterations=60))
    assert np.max(np.abs(res.x - fitted.x) / sig) < same_minimum
    assert np.max(np.abs(plain.x - fitted.x) / sig) < same_minimum
    assert list(res.state.solve_for) == names
