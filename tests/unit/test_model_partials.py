"""One battery: the analytic partials of every observation model against finite differences.

Each model is checked at several seeded random states (parameters near the data book,
random attitudes keeping the Sun/star in view, horizon crossings that exist) with the
shared checker :mod:`gcs_core.models.checks`. Tolerances are those of the
finite-difference scheme (``CENTRAL_DIFFERENCE_RTOL``, ``FORWARD_DIFFERENCE_RTOL``).
"""

from __future__ import annotations

import dataclasses

import numpy as np
import pytest
from model_fixtures import CASES

from gcs_core.models.base import Prediction
from gcs_core.models.checks import (
    CENTRAL_DIFFERENCE_RTOL,
    FORWARD_DIFFERENCE_RTOL,
    assert_partials_match,
    check_partials,
)

SEEDS = (0, 1, 2, 3)


@pytest.mark.parametrize("seed", SEEDS)
@pytest.mark.parametrize("case", sorted(CASES))
def test_partials_central_difference(case, seed):
    model, geom, params = CASES[case](np.random.default_rng(seed))
    report = assert_partials_match(model, geom, params, scheme="central", rtol=CENTRAL_DIFFERENCE_RTOL)
    assert report.n_valid == geom.n  # the fixtures keep every frame usable
    names = {e.name for e in report.elements}
    second = {f"d2:{a},{b}" for a, b in model.predict(geom, params).d2_par}
    assert names == {p.name for p in model.parameters()} | {"att_1", "att_2", "att_3"} | second


@pytest.mark.parametrize("case", sorted(CASES))
def test_partials_forward_difference(case):
    model, geom, params = CASES[case](np.random.default_rng(100))
    assert_partials_match(model, geom, params, scheme="forward", rtol=FORWARD_DIFFERENCE_RTOL)


@pytest.mark.parametrize("case", sorted(CASES))
def test_prediction_shapes_and_vectorization(case):
    """Shapes follow the contract, and N frames at once equal the frames one by one."""
    model, geom, params = CASES[case](np.random.default_rng(7))
    pred = model.predict(geom, params)
    n, m = geom.n, len(model.components)
    assert pred.y.shape == (n, m) and pred.d_att.shape == (n, m, 3) and pred.valid.shape == (n,)
    assert set(pred.d_par) == {p.name for p in model.parameters()}
    assert all(d.shape == (n, m) for d in pred.d_par.values())
    assert model.sigma().shape == (m,)
    for i in (0, n - 1):
        one = model.predict(_frame(geom, i), params)
        np.testing.assert_allclose(one.y[0], pred.y[i], rtol=1e-12, atol=1e-12)
        np.testing.assert_allclose(one.d_att[0], pred.d_att[i], rtol=1e-9, atol=1e-12)


def _frame(geom, i):
    """The geometry of frame ``i`` alone (a single (3,) spin axis is kept as it is)."""

    def pick(name, x):
        if x is None or (name == "spin_axis_I" and np.ndim(x) == 1):
            return x
        return np.asarray(x)[i : i + 1]

    changes = {
        f.name: pick(f.name, getattr(geom, f.name))
        for f in dataclasses.fields(geom)
        if f.name not in ("aux", "extra", "ephemeris", "field_model")
    }
    changes["aux"] = {k: np.asarray(v)[i : i + 1] for k, v in geom.aux.items()}
    changes["extra"] = {k: np.asarray(v)[i : i + 1] for k, v in geom.extra.items()}
    return dataclasses.replace(geom, **changes)


class _CorruptedModel:
    """Wraps a model and scales one analytic partial by (1 + 1e-4): the checker must object."""

    def __init__(self, model, name):
        self._model, self._name = model, name

    def __getattr__(self, attr):
        return getattr(self._model, attr)

    def predict(self, geom, params):
        p = self._model.predict(geom, params)
        d_par = dict(p.d_par)
        d_par[self._name] = d_par[self._name] * (1.0 + 1e-4)
        return Prediction(p.y, p.d_att, d_par, p.valid)


@pytest.mark.parametrize(
    "case, name", [("magnetometer", "align_2"), ("horizon", "d_rho"), ("fine_sun", "k_alpha"), ("gyro", "G_23")]
)
def test_checker_catches_a_wrong_partial(case, name):
    model, geom, params = CASES[case](np.random.default_rng(1))
    report = check_partials(_CorruptedModel(model, name), geom, params)
    assert [e.name for e in report.failures()] == [name]
    with pytest.raises(AssertionError, match=name):
        assert_partials_match(_CorruptedModel(model, name), geom, params)
