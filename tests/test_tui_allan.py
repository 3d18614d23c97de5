"""The Allan deviation dialog: a snapshot on simulated gyro and magnetometer noise (seeded,
known strength), and the palette command on the bundled BROAD sample mission."""

from __future__ import annotations

import numpy as np
import pytest
from textual.app import App

from gcs_core.sidp.noise import sensor_noise
from gcs_tui.screens.allan import AllanScreen, summary
from gcs_tui.theme import VARIABLES


def _results():
    rng = np.random.default_rng(11)
    dt = 0.01
    t = np.arange(60_000) * dt
    gyro = rng.normal(scale=1e-3 / np.sqrt(dt), size=(t.size, 3)) + \
        np.cumsum(rng.normal(scale=1e-4 * np.sqrt(dt), size=(t.size, 3)), axis=0)
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
    assert text.count(" N ") == 3 and "data book 0.01" in text
