"""The first fit (issue 22 item 4): the kernels compile at install (``gcs warmup``), the
progress line says what the fit is doing and for how long, and esc or q stop a fit
within 2 s (the engine's checkpoints, :mod:`gcs_core.cancel`)."""

from __future__ import annotations

import re
import threading
import time

import pytest
from tui_testing import sample_mission, settle

from gcs_core.cancel import Cancelled, cancellable, checkpoint
from gcs_core.config import config_for
from gcs_core.session import Analysis
from gcs_tui.cli.commands import main
from gcs_tui.tui.app import GcsApp

MISSION = "hidden-tam-contamination"
#: esc must stop a fit within this many seconds
CANCEL_LIMIT_S = 2.0


def mission():
    path = sample_mission(MISSION)
    if path is None:
        pytest.skip(f"sample_data/missions/{MISSION} is not generated")
    return path


def test_checkpoint_outside_cancellable_never_raises():
    checkpoint()
    with cancellable(lambda: False):
        checkpoint()
    with cancellable(lambda: True), pytest.raises(Cancelled):
        checkpoint()


def test_a_fit_stops_within_the_limit_once_cancelled():
    a = Analysis(config_for(mission()))
    flag = threading.Event()
    out: dict = {}

    def run():
        with cancellable(flag.is_set):
            try:
                a.fit()
                out["end"] = "finished"
            except Cancelled:
                out["end"] = "cancelled"
        out["t"] = time.monotonic()

    worker = threading.Thread(target=run)
    worker.start()
    time.sleep(0.5)
    t_cancel = time.monotonic()
    flag.set()
    worker.join(30)
    if out.get("end") == "finished" and out["t"] < t_cancel:
        pytest.skip("the fit finished before it could be cancelled")
    assert out["end"] == "cancelled"
    assert out["t"] - t_cancel < CANCEL_LIMIT_S


async def test_progress_shows_stage_and_elapsed_then_esc_cancels():
    app = GcsApp(mission())
    async with app.run_test(size=(80, 24)) as pilot:
        await settle(pilot)
        await pilot.press("f")
        await pilot.pause(1.2)
        if app.busy:  # a fast machine may finish first
            line = app.job.line()
            assert re.match(r"fitting · \d+ s · \S", line), line  # the clock, then the stage
            t = time.monotonic()
            await pilot.press("escape")
            await settle(pilot)
            assert time.monotonic() - t < CANCEL_LIMIT_S + 1.0  # + the event loop's pauses
            assert app.last_notice.endswith("cancelled") or app.workbench.result is not None
        await pilot.press("f")
        await pilot.pause(0.5)
        t = time.monotonic()
        await pilot.press("q")
    assert time.monotonic() - t < CANCEL_LIMIT_S + 1.0


def test_gcs_warmup_compiles_the_kernels(capsys):
    from gcs_core.warmup import cold_start

    assert main(["warmup"]) == 0
    out = capsys.readouterr().out
    assert "gcs warmup: done in" in out
    assert not cold_start()


def test_status_after_a_filtr_run_is_not_not_fitted():
    from gcs_tui.tui import filtr_run
    from gcs_tui.tui.workbench import Workbench

    wb = Workbench.open(mission())
    filtr_run.advance(wb, 1)
    text = GcsApp(workbench=wb).status_text()
    assert "FILTR at block 1/" in text and "not fitted" not in text
