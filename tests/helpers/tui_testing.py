"""Helpers for driving the GCS TUI from tests (Pilot) — no engine logic here.

* :func:`sample_mission` finds a bundled sample mission (``sample_data/missions``)
  and its answer file;
* :func:`settle` waits until background jobs are done and the screen has redrawn;
* :func:`type_text` types a string key by key (what a user does).
"""

from __future__ import annotations

import json
from pathlib import Path

from repo_paths import ROOT

from gcs_tui.tui.app import GcsApp

SAMPLE_DATA = ROOT / "sample_data"


def sample_mission(name: str) -> Path | None:
    """``sample_data/missions/<name>`` if it is there, else None."""
    path = SAMPLE_DATA / "missions" / name
    return path if (path / "mission.toml").is_file() else None


def sample_answer(name: str) -> dict:
    """The answer file ``sample_data/answers/<name>.json`` (hidden effects, physics)."""
    return json.loads((SAMPLE_DATA / "answers" / f"{name}.json").read_text(encoding="utf-8"))


async def settle(pilot, *, timeout: float = 300.0) -> None:
    """Wait for every worker (one engine job may queue another) and for the redraw."""
    import asyncio

    app: GcsApp = pilot.app
    loop = asyncio.get_running_loop()
    end = loop.time() + timeout
    while True:
        await pilot.pause()
        await app.workers.wait_for_complete()
        await pilot.pause()
        if not app.busy and not any(w.is_running for w in app.workers):
            break
        if loop.time() > end:
            raise TimeoutError("the TUI stayed busy")
    await pilot.pause()


async def type_text(pilot, text: str) -> None:
    """Type ``text`` into the focused widget one key at a time."""
    await pilot.press(*list(text))
