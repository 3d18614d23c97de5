"""The analyst's screen over SSH: nothing written behind the TUI, nothing lost at 80×24,
units kept, poor choices and unsaved edits asked about, files written beside the mission
with the usual permissions, one display rule for the CLI and the TUI.

One Pilot session at 80×24 on a copy of the bundled sample mission carries most checks
(a fit is the slow part, so it is done once).
"""

from __future__ import annotations

import io
import logging
import os
import shutil
import subprocess
import sys
import time
from pathlib import Path
from types import SimpleNamespace

import numpy as np
import pytest
from textual.widgets import DataTable, Label, Static
from tui_testing import ROOT, sample_mission, settle

from gcs_core import display as fmt
from gcs_core import reporting
from gcs_core.units import ARCSEC, DEG
from gcs_tui.cli import tables
from gcs_tui.cli.progress import LogHandler, Progress
from gcs_tui.tui.app import GcsApp
from gcs_tui.tui.app_logging import LOGGERS, detached_terminal_logging
from gcs_tui.tui.derive import poor_choice
from gcs_tui.tui.screens.dialogs import ConfirmScreen, Field, FormScreen

MISSION = "hidden-tam-contamination"
one_arcsecond = ARCSEC
#: a usable TUI must refuse a missing terminal at once, not after importing the world
REFUSAL_SECONDS = 1.0


def _umask() -> int:
    m = os.umask(0o022)
    os.umask(m)
    return m


@pytest.fixture()
def mission_copy(tmp_path) -> Path:
    src = sample_mission(MISSION)
    if src is None:
        pytest.skip(f"sample_data/missions/{MISSION} is not generated")
    dst = tmp_path / "missions" / MISSION
    shutil.copytree(src, dst)
    return dst


# ---------------------------------------------------------------------------- no terminal
def test_tui_without_a_terminal_exits_2_at_once():
    """stdin and stdout not a terminal: one line, exit 2, well within a second."""
    env = dict(os.environ, PYTHONPATH=str(ROOT))
    start = time.monotonic()
    run = subprocess.run(
        [sys.executable, "-m", "gcs_tui.cli", "tui", str(ROOT / "sample_data" / "missions" / MISSION)],
        stdin=subprocess.DEVNULL,
        capture_output=True,
        text=True,
        timeout=10,
        cwd=ROOT,
        env=env,
    )
    elapsed = time.monotonic() - start
    assert run.returncode == 2, run.stderr
    assert elapsed < REFUSAL_SECONDS, elapsed
    lines = run.stderr.strip().splitlines()
    assert len(lines) == 1 and "needs a terminal" in lines[0]
    assert run.stdout == ""


# ---------------------------------------------------------------------------- the session
async def test_session_at_80x24_keeps_the_terminal_clean_and_asks_first(mission_copy, capfd):
    """A fit's warning shows inside the app, whole, and nothing reaches the terminal behind it;
    the estimates and p adj are on screen at 80×24; the explanation scrolls; a poor
    candidate is asked about; the screenshot and config go beside the mission (0644);
    q with unsaved edits asks."""
    terminal = io.StringIO()
    cli_handler = LogHandler(Progress(terminal, mode="plain"))  # what `gcs` installs
    for name in LOGGERS:
        logging.getLogger(name).addHandler(cli_handler)
    try:
        # the pure batch (gyro taken as exact) warns over 2 h: a warning raised during a fit
        config = mission_copy.parent / "batch.toml"
        config.write_text(f'[analysis]\nmission = "{mission_copy}"\nmethod = "batch"\n')
        app = GcsApp(config)
        with detached_terminal_logging():
            async with app.run_test(size=(80, 24)) as pilot:
                await settle(pilot)
                await pilot.press("f")
                await settle(pilot)
                # the batch over 2 h warns about the gyro's random walk: inside, whole
                assert app.messages, "the fit's warning did not reach the app"
                level, text = app.messages[0]
                assert level == "warning" and text.startswith("batch method:") and text.endswith("p-values.")
                shown = [n.message for n in app._notifications]
                assert text in shown

                await pilot.press("3")  # State: estimate ± σ at 80 columns
                await settle(pilot)
                table = app.screen.query_one("#elements", DataTable)
                labels = [str(c.label) for c in table.columns.values()]
                assert labels[:2] == ["element", "estimate ± σ"]
                row = table.get_row("att.roll")
                assert "±" in str(row[1]) and "arcsec" in str(row[1])

                await pilot.press("7")  # Diagnosis
                await settle(pilot)
                table = app.screen.query_one("#candidates", DataTable)
                labels = [str(c.label) for c in table.columns.values()]
                assert "p adj" in labels and "aliases" in labels
                explanation = str(app.screen.query_one("#explanation", Static).render())
                assert "p adj" in explanation and "Aliases in the state" in explanation
                box = app.screen.query_one("#explanation-box")
                assert box.max_scroll_y > 0  # longer than its pane: it scrolls

                cands = app.workbench.analysis.candidates
                alpha = app.workbench.config.diagnosis.significance
                k = next(i for i, c in enumerate(cands) if poor_choice(c, alpha))
                table.focus()
                await pilot.press(*["down"] * k, "a")
                await pilot.pause()
                assert isinstance(app.screen, ConfirmScreen)
                question = str(app.screen.query_one(".dialog-text", Static).render())
                assert "not significant" in question or "not identifiable" in question
                await pilot.press("n")
                await settle(pilot)
                assert not isinstance(app.screen, ConfirmScreen)
                assert [s.action for s in app.workbench.analysis.steps] == ["fit"]

                shot = Path(app.deliver_screenshot())  # palette: Screenshot
                assert shot.parent == mission_copy.parent and shot.is_file()
                assert (os.stat(shot).st_mode & 0o777) == 0o666 & ~_umask()

                await pilot.press("3", "s")  # an edit: the role of att.roll
                await settle(pilot)
                assert app.workbench.unsaved
                await pilot.press("q")
                await pilot.pause()
                assert isinstance(app.screen, ConfirmScreen)  # asks, does not quit
                await pilot.press("escape")
                await pilot.pause()
                out = app.save_config_to(app.workbench.default_save_path())
                assert out.parent == mission_copy.parent  # beside the mission, not the cwd
                assert (os.stat(out).st_mode & 0o777) == 0o666 & ~_umask()
                assert not app.workbench.unsaved
                await pilot.press("q")
        assert app.return_code in (0, None)
    finally:
        for name in LOGGERS:
            logging.getLogger(name).removeHandler(cli_handler)
    assert terminal.getvalue() == "", terminal.getvalue()  # nothing behind the TUI
    assert capfd.readouterr().err == ""  # nor on the process's stderr


async def test_dialog_labels_keep_their_units():
    """``value [deg]`` is text, not markup: the unit survives."""
    app = GcsApp()
    async with app.run_test(size=(80, 24)) as pilot:
        app.push_screen(
            FormScreen(
                "Edit att.roll",
                [Field("value", "value [deg]", "1.5"), Field("t", "start [s]", "0"), Field("b", "bias [nT]", "0")],
            )
        )
        await pilot.pause()
        texts = [str(lab.render()) for lab in app.screen.query(".form-label").results(Label)]
        assert texts == ["value [deg]", "start [s]", "bias [nT]"]


# ---------------------------------------------------------------------------- one display rule
@pytest.mark.parametrize(
    "unit, value, sigma",
    [
        ("rad", 5.6 * DEG, 3 * one_arcsecond),  # a large angle known to arcseconds: arcsec
        ("rad", 0.2 * DEG, 3 * one_arcsecond),
        ("rad", 30 * DEG, 2 * DEG),  # σ of degrees: deg
        ("rad/s", 1e-6, 1e-7),
        ("rad/s2", 1.7e-12, 1.4e-12),
        ("nT", 12.3, 0.4),
        ("1", 0.99996, 4.3e-5),
    ],
)
def test_cli_and_tui_choose_the_same_unit_and_digits(unit, value, sigma):
    """The ``gcs`` state table and the TUI show one element's estimate alike: the same
    unit chosen from its σ and the same digits."""
    el = SimpleNamespace(name="X.p", role="solve-for", value=value, sigma0=sigma, unit=unit)
    res = SimpleNamespace(state=[el], sigma={"X.p": sigma}, solve_for=("X.p",), P=np.array([[sigma**2]]))
    row = tables.state_table(SimpleNamespace(result=res))[1]
    tui = fmt.estimate(value, sigma, unit)
    assert row.split(None, 2)[2] == tui
    label = fmt.unit_label(fmt.shown_unit(unit, value, sigma))
    assert tui.endswith(label) if label else True


def test_rows_with_similar_sigma_share_a_unit():
    roll = fmt.estimate(0.01 * DEG, 3 * one_arcsecond, "rad")
    pitch = fmt.estimate(5.6 * DEG, 3 * one_arcsecond, "rad")
    assert roll.endswith("arcsec") and pitch.endswith("arcsec")
    assert fmt.estimate(1.7e-12, 1.4e-12, "rad/s2") == "0.0013 ± 0.0010 deg/h²"
    assert fmt.estimate(0.5, 0.01, "1") == "0.500 ± 0.010"  # no unit "1"


def test_no_p_of_zero_in_the_cli_table():
    cand = SimpleNamespace(
        id="TAM1.scale",
        effect=SimpleNamespace(sensor="TAM1", effect="scale"),
        delta_chi2=5000.0,
        dof=3,
        p_value=0.0,
        p_adjusted=0.0,
        identifiable=True,
        passes=True,
    )
    lines = tables.candidate_table([cand], alpha=0.001)
    assert "< 1e-16" in lines[1] and " 0 " not in lines[1]
    assert any("ranked by p" in ln for ln in lines)


def test_value_prefill_at_sigma_precision():
    assert fmt.value_text(0.044629361519 * DEG, 0.001 * DEG, "rad", "deg") == "0.04463"  # σ-s digits and one more
    assert fmt.value_text(12.345678, 0.23, "nT", "nT") == "12.346"


def test_round_ticks():
    assert fmt.nice_ticks(0.0, 360.0, 5) == [0.0, 100.0, 200.0, 300.0]
    ticks = fmt.nice_ticks(-3.1, 1141.5, 5)
    assert all(float(t) % 100 == 0 for t in ticks)
    assert fmt.tick_labels([0.0, 0.5, 1.0]) == ["0.0", "0.5", "1.0"]


# ---------------------------------------------------------------------------- config hints
def _cli(args, capsys):
    from gcs_tui.cli.commands import main

    code = main(["-q", *args])
    return code, capsys.readouterr().err


def test_typo_in_an_element_name_suggests_the_right_one(tmp_path, capsys):
    mission = sample_mission(MISSION)
    if mission is None:
        pytest.skip("no sample mission")
    cfg = tmp_path / "a.toml"
    cfg.write_text(f'[analysis]\nmission = "{mission}"\n[state.elements."TAM1.bias_q"]\nrole = "held"\n')
    code, err = _cli(["batch", str(cfg)], capsys)
    assert code == 2 and "did you mean 'TAM1.bias_" in err and 'state.elements."TAM1.bias_q"' in err
    assert len(err.strip().splitlines()) == 1


def test_missing_mission_names_the_key(tmp_path, capsys):
    cfg = tmp_path / "a.toml"
    cfg.write_text('[analysis]\nmission = "nowhere/m"\n')
    code, err = _cli(["batch", str(cfg)], capsys)
    assert code == 2 and "analysis.mission" in err and str(cfg) in err


def test_plain_progress_prints_each_discovery_step_once():
    from gcs_tui.cli.commands import step_messages

    out = io.StringIO()
    prog = Progress(out, mode="plain")
    with prog.task("discovering missing effects") as task:
        step_messages(prog, task)("adding TAM1.scale (Δχ² = 812.0)")
    assert out.getvalue().count("adding TAM1.scale") == 1


def test_verification_speaks_one_unit_in_both_faces():
    """The CLI summary, the flag's reason and the TUI table use the unit chosen from the largest
    σ or threshold: a 100″ offset against a 36″ requirement reads in arcsec everywhere."""
    from gcs_core.frames.rotations import euler123_to_dcm, quat_from_dcm
    from gcs_core.verif.compare import verify
    from gcs_tui.tui.screens.verification import shown_unit

    t = np.arange(0.0, 600.0, 10.0)
    q_g = np.tile([0.0, 0.0, 0.0, 1.0], (t.size, 1))
    off = 100 * one_arcsecond
    q_ob = np.tile(quat_from_dcm(euler123_to_dcm(np.array([off]), np.zeros(1), np.zeros(1)))[0], (t.size, 1))
    v = verify(t, q_ob, t, q_g, np.full(3, 1 * one_arcsecond), requirement_rad=0.01 * DEG)
    assert v.flag
    assert shown_unit(v) == "arcsec"
    assert "arcsec" in v.reason and "°" not in v.reason
    summary = v.summary()
    assert "[arcsec]" in summary and "[deg]" not in summary and "RMS" in summary


def test_kalman_passes_and_unobservable_are_said_in_words():
    from gcs_core.estimators.results import passes_text

    assert passes_text(3, "max_passes").startswith("3 passes done, as configured")
    assert passes_text(2, "converged") == "converged after 2 passes"
    assert "pass(es)" not in passes_text(1, "single_pass")
    res = SimpleNamespace(
        residuals={}, message="converged", chi2=10.0, dof=10, unobservable=["TAM1.align_1 + att.roll"]
    )
    lines = tables.fit_table(SimpleNamespace(result=res, holdout_rms={}))
    assert lines[-1] == tables.UNOBSERVABLE_NOTE and "a priori" in lines[-1]


def test_reports_and_configs_get_the_usual_permissions(tmp_path):
    from gcs_core.config import save_config
    from gcs_core.config_schema import AnalysisConfig

    usual = 0o666 & ~_umask()
    rep = reporting.write_json_atomic(tmp_path / "report.json", {"mission": "x"})
    cfg = save_config(AnalysisConfig(mission=tmp_path), tmp_path / "a.toml")
    for p in (rep, cfg):
        assert (os.stat(p).st_mode & 0o777) == usual, oct(os.stat(p).st_mode)
