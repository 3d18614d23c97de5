"""Every estimator's result is read through one shape (gcs_core.estimators.results.FitResult):
the batch, the whole-span fit and the Kalman filter + smoother each give every member the
diagnosis and the reports read, with no conversion between them."""

from __future__ import annotations

import dataclasses
import typing

import pytest

from gcs_core.estimators import results
from gcs_core.estimators.whole_span.result import SmoothedResult


def protocol_members() -> set[str]:
    hints = set(typing.get_type_hints(results.FitResult))
    props = {n for n, v in vars(results.FitResult).items() if isinstance(v, property)}
    return hints | props


@pytest.mark.parametrize("cls", [results.BatchResult, SmoothedResult, results.FilterResult])
def test_every_estimator_result_has_every_member_of_the_fit_shape(cls):
    fields = {f.name for f in dataclasses.fields(cls)}
    missing = {m for m in protocol_members() if m not in fields and not hasattr(cls, m)}
    assert missing == set(), f"{cls.__name__} lacks {sorted(missing)}"


def test_no_estimator_result_is_converted_into_another():
    """The session returns the filter's own result (no batch-shaped copy with zero information)."""
    import inspect

    from gcs_core import session

    src = inspect.getsource(session)
    assert "BatchResult(" not in src and "np.zeros((n, n))" not in src
