"""80×24 is a first-class size (issue 22): after a fit, every screen opens on every
sample mission and on the first 900 s of each, and nothing raises.

The 80×24 crash this guards against: ``gcs tui spinner-hidden-horizon``, ``f``, ``6``
raised in plotext from the hidden histogram (``ValueError: not enough values to
unpack``); the first 900 s of a mission did the same. The fits use the cheapest settings
(batch, no held-out refit, 5 iterations): the screens are under test, not the fit.
"""

from __future__ import annotations

import shutil
from pathlib import Path

import pytest
from repo_paths import SAMPLE_MISSIONS
from tui_testing import settle

from gcs_core.config import save_config
from gcs_core.config_schema import AnalysisConfig
from gcs_tui.tui.app import GcsApp
from gcs_tui.tui.keys import VIEWS

MISSIONS = sorted(p.name for p in SAMPLE_MISSIONS.glob("*") if (p / "mission.toml").is_file())
#: the cut: the first this many seconds of every telemetry and auxiliary file
CUT_S = 900.0


def _first_time(line: str) -> float | None:
    try:
        return float(line.split(",", 1)[0])
    except ValueError:  # a comment or the header
        return None


def cut_mission(src: Path, dst: Path, seconds: float) -> Path:
    """A copy of mission ``src`` whose telemetry, auxiliary and onboard files keep the first
    ``seconds`` (from the earliest telemetry time); ephemeris and orbit stay whole."""
    shutil.copytree(src, dst)
    files = sorted((dst / "telemetry").glob("*.csv")) + [
        p for p in (dst / "aux.csv", dst / "onboard_attitude.csv") if p.is_file()
    ]
    starts = []
    for f in sorted((dst / "telemetry").glob("*.csv")):
        with f.open(encoding="utf-8") as fh:
            starts += [t for t in (_first_time(line) for line in fh) if t is not None][:1]
    end = min(starts) + seconds
    for f in files:
        lines = f.read_text(encoding="utf-8").splitlines(keepends=True)
        kept = [line for line in lines if (t := _first_time(line)) is None or t < end]
        f.write_text("".join(kept), encoding="utf-8")
    return dst


def cheap_config(mission: Path, tmp_path: Path) -> Path:
    cfg = AnalysisConfig().with_changes(
        mission=mission, filter={"max_iterations": 5}, diagnosis={"holdout_fraction": 0.0}
    )
    from dataclasses import replace

    return save_config(replace(cfg, method="batch"), tmp_path / "cheap.toml")


@pytest.mark.slow
@pytest.mark.parametrize("cut", [False, True], ids=["whole", "900s"])
@pytest.mark.parametrize("name", MISSIONS)
async def test_every_screen_at_80x24(name, cut, tmp_path):
    mission = SAMPLE_MISSIONS / name
    if cut:
        mission = cut_mission(mission, tmp_path / name, CUT_S)
    app = GcsApp(cheap_config(mission, tmp_path))
    app.workbench.out_dir = tmp_path / "out"
    async with app.run_test(size=(80, 24)) as pilot:
        await settle(pilot)
        assert app.workbench.ready, app.job_errors
        await pilot.press("f")
        await settle(pilot)
        for mode, key, _, _ in VIEWS:
            await pilot.press(key)
            await settle(pilot)
            assert app.current_mode == mode
        await pilot.press("5", "n")  # one FILTR block
        await settle(pilot)
        await pilot.press("6", "x", "x", "x", "v", "v")  # residual axes and plot kinds
        await settle(pilot)
        await pilot.press("question_mark", "escape")
        await settle(pilot)
    # Pilot re-raises anything the app met; an unhandled error would also set crash_line
    assert app.crash_line == ""


async def test_the_reported_crash_at_80x24():
    """Issue 22's reproducer as typed: ``gcs tui sample_data/missions/spinner-hidden-horizon``,
    ``f``, ``6`` at 80×24 (default config) raised in plotext from the hidden histogram."""
    mission = SAMPLE_MISSIONS / "spinner-hidden-horizon"
    if not (mission / "mission.toml").is_file():
        pytest.skip("sample_data/missions/spinner-hidden-horizon is not generated")
    app = GcsApp(mission)
    async with app.run_test(size=(80, 24)) as pilot:
        await settle(pilot)
        await pilot.press("f")
        await settle(pilot)
        await pilot.press("6")
        await settle(pilot)
        assert app.current_mode == "residuals" and app.workbench.result is not None
    assert app.crash_line == ""
