"""Shared fixtures: the independent example missions and the helpers' import path.

The tests live in folders by kind (``unit``, ``reference``, ``statistical``, ``tui``,
``conformance``); the modules they share (``honesty_cases``, ``model_fixtures``, ...,
``repo_paths``) live in ``tests/helpers``, put on the import path here.
"""

from __future__ import annotations

import os
import sys
from pathlib import Path

# Small matrices dominate GCS; OpenBLAS threads only contend on a 2-core machine.
os.environ.setdefault("OPENBLAS_NUM_THREADS", "1")
# helpers first; the kinds' folders too, so a test that reuses another's simulation
# (``from test_filter_consistency import simulate``) imports it whatever is collected first
for _folder in ("conformance", "tui", "unit", "reference", "statistical", "helpers"):
    sys.path.insert(0, str(Path(__file__).resolve().parent / _folder))

import pytest  # noqa: E402 — after the helpers' folders are on sys.path
from repo_paths import SHARED_EXAMPLES  # noqa: E402 — found on the path set above

#: why a test that needs the independent example missions is skipped
NEEDS_SHARED = (
    f"conformance: needs the independent example missions in {SHARED_EXAMPLES} (../shared/examples beside the checkout)"
)


def pytest_collection_modifyitems(config, items):
    """Without ../shared/examples, mark every test that needs them skipped up front, so that
    ``-rs`` gives one line per file with the reason rather than one per test."""
    if SHARED_EXAMPLES.is_dir():
        return
    skip = pytest.mark.skip(reason=NEEDS_SHARED)
    for item in items:
        if "shared_example" in getattr(item, "fixturenames", ()):
            item.add_marker(skip)


@pytest.fixture(scope="session")
def shared_example():
    """``shared_example(name)``: the path of the independent simulator's mission ``name``
    (``sunpoint-nominal``, ``spinner-nominal``, ...); the test is skipped when the shared
    missions are not beside this checkout."""

    def find(name: str = "sunpoint-nominal") -> Path:
        path = SHARED_EXAMPLES / name
        if not path.is_dir():
            pytest.skip(
                f"conformance: needs the independent example mission {name!r} in {SHARED_EXAMPLES} "
                "(../shared/examples beside the checkout)"
            )
        return path

    return find


@pytest.fixture(scope="session")
def example_dir(shared_example) -> Path:
    """The conformance mission ``sunpoint-nominal``."""
    return shared_example("sunpoint-nominal")
