"""Where the tests find the repository, its sample data and their own data files."""

from __future__ import annotations

from pathlib import Path

#: the repository's root (this file is tests/helpers/repo_paths.py)
ROOT = Path(__file__).resolve().parents[2]
#: small data files of the tests themselves
TEST_DATA = ROOT / "tests" / "data"
SAMPLE_MISSIONS = ROOT / "sample_data" / "missions"
SAMPLE_ANSWERS = ROOT / "sample_data" / "answers"
#: the independent simulator's missions, beside the checkout (read through the
#: ``shared_example`` fixture of tests/conftest.py, which skips when they are absent)
SHARED_EXAMPLES = ROOT.parent / "shared" / "examples"
