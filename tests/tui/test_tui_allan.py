"""The Allan deviation dialog: a snapshot on simulated gyro and magnetometer noise (seeded,
known strength), and the palette command on the bundled BROAD sample mission."""

from __future__ import annotations

import numpy as np
import pytest
from repo_paths import ROOT
from textual.app import App

from gcs_core.noise.measured import sensor_noise
from gcs_tui.tui.screens.allan import AllanScreen, summary
from gcs_tui.tui.theme import VARIABLES


def _results():
    rng = np.random.default_rng(11)
    dt = 0.01
    t = np.arange(60_000) * dt
    gyro = rng.normal(scale=1e-3 / np.sqrt(dt), size=(t.size, 3)) + np.cumsum(
        rng.normal(scale=1e-4 * np.sqrt(dt), size=(t.size, 3)), axis=0
    )
    mag = rng.normal(scale=300.0, size=(t.size, 3))
    g = sensor_noise("IRU", "gyro", t, dict(zip(("wx", "wy", "wz"), gyro.T)), stated=0.01)
    m = sensor_noise("TAM1", "magnetometer", t, dict(zip(("bx", "by", "bz"), mag.T)), stated=250.0)
    return [g, m]


class _Host(App):
    """The dialog over an empty app that offers the GCS theme variables."""

    def get_css_variables(self) -> dict[str, str]:
        return {**super().get_css_variables(), **VARIABLES}

    def on_mount(self) -> None:
        self.push_screen(AllanScreen(_results(), "Allan deviation · simulated"))


async def _drawn(pilot) -> None:
    await pilot.pause()
    await pilot.pause(0.2)


def test_allan_screen_snapshot(snap_compare):
    assert snap_compare(_Host(), terminal_size=(100, 40), run_before=_drawn)


def test_summary_reads_the_gyro_terms():
    text = summary(_results()[0])
    assert text.count(" N ") == 3 and "data book 0.01 (spread 1.00" in text


async def test_palette_command_on_the_broad_sample(tmp_path):
    """``noise: allan deviation`` on the bundled BROAD mission (real data, Laidig et al.,
    Data 6(7), 2021, doi:10.3390/data6070072, CC BY 4.0) opens the dialog, one chart per
    sensor; escape closes it."""

    from tui_testing import settle

    from gcs_tui.tui.app import GcsApp
    from gcs_tui.tui.workbench import Workbench

    config = ROOT / "sample_data/configs/real-broad-02-slow-rotation.toml"
    if not config.is_file():
        pytest.skip("the BROAD sample mission is not bundled")
    wb = Workbench.open(config, save_path=tmp_path / "a.toml", scds_path=tmp_path / "h.scds.h5")
    app = GcsApp(workbench=wb, start_view="mission")
    async with app.run_test(size=(120, 40)) as pilot:
        await settle(pilot)
        await app.run_action("noise")
        await pilot.pause()
        assert isinstance(app.screen, AllanScreen)
        assert [r.name for r in app.screen.results] == ["GYR", "MAG", "OPT"]
        await pilot.press("escape")
        await pilot.pause()
        assert not isinstance(app.screen, AllanScreen)
