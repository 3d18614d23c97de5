"""A real headless browser for the tests of exported pages (residual plots, fleet report)."""

from __future__ import annotations

import shutil
import subprocess
from pathlib import Path


def chromium() -> str | None:
    """The path of a Chromium (or Chrome) on this machine, or None (`make test` installs it)."""
    for name in ("chromium", "chromium-browser", "google-chrome"):
        path = shutil.which(name)
        if path:
            return path
    return None


def screenshot(browser: str, page: Path, png: Path, *, width: int, height: int, timeout: float = 60.0):
    """Render ``page`` headless into ``png`` at ``width`` × ``height`` px (a fresh profile beside
    the PNG); returns the finished process (its stderr says why when no PNG was written)."""
    cmd = [
        browser,
        "--headless",
        "--no-sandbox",
        "--disable-gpu",
        "--hide-scrollbars",
        f"--user-data-dir={png.parent / 'profile'}",
        f"--window-size={width},{height}",
        f"--screenshot={png}",
        page.as_uri(),
    ]
    return subprocess.run(cmd, capture_output=True, text=True, timeout=timeout)
