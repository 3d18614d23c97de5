"""Shared fixtures: the conformance mission and named tolerances."""

from __future__ import annotations

import os

# Small matrices dominate GCS; OpenBLAS threads only contend on a 2-core machine.
os.environ.setdefault("OPENBLAS_NUM_THREADS", "1")

from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parents[1]
SHARED_EXAMPLE = ROOT.parent / "shared" / "examples" / "sunpoint-nominal"
SAMPLE_MISSIONS = ROOT / "sample_data" / "missions"
SAMPLE_ANSWERS = ROOT / "sample_data" / "answers"


@pytest.fixture(scope="session")
def example_dir() -> Path:
    if not SHARED_EXAMPLE.is_dir():
        pytest.skip("the shared conformance mission is not beside this checkout")
    return SHARED_EXAMPLE
