"""Batch least squares (Eq 3-1, 3-2): observability naming and consider covariance."""

from __future__ import annotations

import math

import numpy as np
import pytest

from gcs_core.config_schema import AnalysisConfig, ElementConfig
from gcs_core.errors import UnobservableError
from gcs_core.estimators.batch.least_squares import BatchOptions, batch_fit, name_combinations
from gcs_core.session import Analysis


def _tam_only(example_dir, **kw):
    models = {"IRU": "off", "FHST1": "off", "FHST2": "off", "FSS1": "off", "CSS1": "off"}
    return AnalysisConfig(mission=example_dir, models=models).with_changes(state=kw)


def test_tam_misalignment_against_attitude_is_named(example_dir):
    """Seed §2.1.2: at a fixed attitude a TAM misalignment cannot be told from an attitude
    error. With no a priori on either, the normal matrix is singular and the error names
    the combination instead of inventing numbers."""
    inf = math.inf
    elements = {f"att.{a}": ElementConfig(sigma=inf) for a in ("roll", "pitch", "yaw")}
    elements.update({f"TAM1.align_{i}": ElementConfig(sigma=inf) for i in (1, 2, 3)})
    cfg = _tam_only(example_dir, effects=("TAM1.alignment",), elements=elements)
    a = Analysis(cfg)
    with pytest.raises(UnobservableError) as err:
        batch_fit(a.problem, BatchOptions(edit_k=None))
    text = str(err.value)
    assert "TAM1.align" in text and "att." in text


def test_with_a_priori_the_fit_runs_and_reports_the_combination(example_dir):
    cfg = _tam_only(example_dir, effects=("TAM1.alignment",))
    a = Analysis(cfg)
    res = batch_fit(a.problem, BatchOptions(edit_k=None))
    assert res.unobservable, "the alignment/attitude combination must be reported"
    assert any("TAM1.align" in u and "att." in u for u in res.unobservable)


def test_name_combinations_on_a_known_matrix():
    H = np.array([[1.0, 1.0, 0.0], [2.0, 2.0, 1.0], [0.0, 0.0, 3.0]])
    combos = name_combinations(H.T @ H, ["a", "b", "c"], 1e-10)
    assert len(combos) == 1 and "a" in combos[0] and "b" in combos[0] and "c" not in combos[0]


def test_consider_covariance_grows_sigma(example_dir):
    base = Analysis(_tam_only(example_dir))
    r0 = batch_fit(base.problem, BatchOptions(edit_k=None))
    cfg = _tam_only(example_dir, effects=(), elements={"TAM1.scale_x": ElementConfig(role="consider", sigma=1e-3)})
    a = Analysis(cfg)
    r1 = batch_fit(a.problem, BatchOptions(edit_k=None))
    assert "TAM1.scale_x" in r1.consider
    assert r1.sigma["TAM1.bias_x"] > r0.sigma["TAM1.bias_x"]
    assert np.allclose(r1.P, r0.P, rtol=1e-6)  # noise-only part unchanged
    assert set(r1.consider_budget) == {"TAM1.scale_x"}
