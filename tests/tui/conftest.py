"""Every TUI test leaves the bundled files as they were: ``git status`` of ``sample_data/``
is the same after each test as before it (a save, a screenshot or an SCDS written among
the bundled files fails the test that wrote it)."""

from __future__ import annotations

import shutil
import subprocess

import pytest
from repo_paths import ROOT


def _bundled_status() -> str | None:
    if shutil.which("git") is None or not (ROOT / ".git").exists():
        return None
    done = subprocess.run(
        ["git", "-C", str(ROOT), "status", "--porcelain", "--untracked-files=all", "--", "sample_data"],
        capture_output=True,
        text=True,
        timeout=30,
        check=False,
    )
    return done.stdout if done.returncode == 0 else None


@pytest.fixture(autouse=True)
def bundled_files_unchanged():
    before = _bundled_status()
    yield
    after = _bundled_status()
    assert before == after, f"a TUI test changed the bundled files:\n{after}"
