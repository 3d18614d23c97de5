"""Saving is safe (issue 22, issue 23 item 3): ``--out`` is honoured and its folder made,
an existing file is never replaced without asking (and kept when the answer is no), a
bundled file is never the default target, and a default name built from the mission's
name stays a plain file inside the chosen folder. An unhandled error in the app exits 4
with one line naming the log that holds the traceback."""

from __future__ import annotations

import shutil
from pathlib import Path

import pytest
from textual.widgets import Input
from tui_testing import SAMPLE_DATA, sample_mission, settle

from gcs_tui.cli import commands
from gcs_tui.tui import paths
from gcs_tui.tui.app import GcsApp
from gcs_tui.tui.screens.dialogs import ConfirmScreen, FormScreen
from gcs_tui.tui.widgets.plots import GcsPlot

SMALL = "spinner-hidden-horizon"  # the smallest sample mission (1117 + 1116 rows)


def small_mission(tmp_path: Path, name: str | None = None) -> Path:
    src = sample_mission(SMALL)
    if src is None:
        pytest.skip(f"sample_data/missions/{SMALL} is not generated")
    dst = tmp_path / "missions" / SMALL
    shutil.copytree(src, dst)
    if name is not None:
        toml = dst / "mission.toml"
        toml.write_text(toml.read_text().replace(f'name = "{SMALL}"', f"name = {name}"))
    return dst


@pytest.mark.parametrize(
    "name, stem",
    [
        ("victimdir/pyproject", "victimdir_pyproject"),
        ("../../etc/passwd", "etc_passwd"),
        ("/abs/path", "abs_path"),
        ("ok\x1b]2;PWNED\x07", "ok_2_PWNED"),
        ("..", "gcs"),
        ("nominal-sunpoint", "nominal-sunpoint"),
    ],
)
def test_safe_stem(name, stem, tmp_path):
    assert paths.safe_stem(name) == stem
    target = paths.inside(tmp_path, name, ".toml")
    assert target.parent == tmp_path and "/" not in target.name


async def test_mission_name_cannot_reach_outside_the_folder(tmp_path, monkeypatch):
    """Issue 23 item 3's reproducer: ``name = "victimdir/pyproject"`` and ctrl+s used to
    replace ``victimdir/pyproject.toml``; the default is now ``victimdir_pyproject.toml``."""
    mission = small_mission(tmp_path, '"victimdir/pyproject"')
    victim = tmp_path / "missions" / "victimdir" / "pyproject.toml"
    victim.parent.mkdir()
    victim.write_text("[project]\nname = 'victim'\n")
    app = GcsApp(mission)
    async with app.run_test(size=(80, 24)) as pilot:
        await settle(pilot)
        await pilot.press("ctrl+s")
        await pilot.pause()
        field = app.screen.query_one("#field-path", Input)
        assert Path(field.value) == (tmp_path / "missions" / "victimdir_pyproject.toml").resolve()
        await pilot.press("enter")
        await settle(pilot)
        assert (tmp_path / "missions" / "victimdir_pyproject.toml").is_file()
    assert victim.read_text() == "[project]\nname = 'victim'\n"


async def test_out_into_a_new_folder(tmp_path):
    """``gcs tui CONFIG --out NEW/FOLDER``: ctrl+s is pre-filled there (not the bundled
    config) and `k` (calibration) creates the folder."""
    if sample_mission(SMALL) is None:
        pytest.skip(f"sample_data/missions/{SMALL} is not generated")
    bundled = SAMPLE_DATA / "configs" / f"{SMALL}.toml"
    out = tmp_path / "new" / "folder"
    app = GcsApp(bundled)
    app.workbench.out_dir = out
    async with app.run_test(size=(80, 24)) as pilot:
        await settle(pilot)
        await pilot.press("ctrl+s")
        await pilot.pause()
        field = app.screen.query_one("#field-path", Input)
        assert Path(field.value) == out.resolve() / f"{SMALL}.toml"
        await pilot.press("enter")
        await settle(pilot)
        assert (out / f"{SMALL}.toml").is_file()
        assert str(out.resolve()) in app.last_notice  # the full path is shown

        shutil.rmtree(tmp_path / "new")  # the calibration's folder does not exist either
        await pilot.press("f")
        await settle(pilot)
        await pilot.press("0", "k")
        await pilot.pause()
        assert isinstance(app.screen, FormScreen)
        assert Path(app.screen.query_one("#field-path", Input).value).parent == out.resolve()
        await pilot.press("enter")
        await settle(pilot)
        assert list(out.glob("*.scds.h5")), app.last_notice


@pytest.mark.parametrize("comments", [True, False])
async def test_existing_file_asked_then_kept(tmp_path, comments):
    mission = small_mission(tmp_path)
    target = tmp_path / "mine.toml"
    text = ("# my notes\n" if comments else "") + '[analysis]\nmission = "missions/spinner-hidden-horizon"\n'
    target.write_text(text)
    app = GcsApp(mission)
    async with app.run_test(size=(80, 24)) as pilot:
        await settle(pilot)
        await pilot.press("ctrl+s")
        await pilot.pause()
        app.screen.query_one("#field-path", Input).value = str(target)
        await pilot.press("enter")
        await pilot.pause()
        assert isinstance(app.screen, ConfirmScreen)  # asked
        await pilot.press("n")
        await settle(pilot)
        assert target.read_text() == text  # kept
        assert "kept" in app.last_notice
        if comments:  # yes writes a new file beside it; the commented one stays
            await pilot.press("ctrl+s")
            await pilot.pause()
            app.screen.query_one("#field-path", Input).value = str(target)
            await pilot.press("enter", "y")
            await settle(pilot)
            assert target.read_text() == text
            assert (tmp_path / "mine-2.toml").is_file()


def test_bundled_config_is_never_the_default(tmp_path, monkeypatch):
    from gcs_tui.tui.workbench import Workbench

    if sample_mission(SMALL) is None:
        pytest.skip(f"sample_data/missions/{SMALL} is not generated")
    monkeypatch.chdir(tmp_path)
    wb = Workbench.open(SAMPLE_DATA / "configs" / f"{SMALL}.toml")
    target = wb.default_save_path()
    assert not paths.protected(target) and target.parent == tmp_path.resolve() / "out"


def test_a_fault_in_a_plot_widget_exits_4_with_one_line(tmp_path, monkeypatch, capsys):
    """A bug in a widget (here: GcsPlot.render raising) ends ``gcs tui`` with exit 4, one line
    on stderr that names the log, and the traceback in that log."""
    mission = small_mission(tmp_path)
    monkeypatch.setenv("XDG_STATE_HOME", str(tmp_path / "state"))
    monkeypatch.setattr(commands, "terminal_problem", lambda: "")

    def broken(self):
        raise RuntimeError("injected fault")

    monkeypatch.setattr(GcsPlot, "render", broken)
    run = GcsApp.run
    monkeypatch.setattr(GcsApp, "run", lambda self, **kw: run(self, headless=True, size=(80, 24)))
    code = commands.main(["tui", str(mission)])
    err = capsys.readouterr().err
    assert code == 4
    assert len(err.strip().splitlines()) == 1, err
    assert "injected fault" in err and "Traceback" not in err
    logs = list((tmp_path / "state" / "gcs").glob("tui-crash-*.log"))
    assert len(logs) == 1 and "injected fault" in logs[0].read_text()


async def test_a_plot_error_is_drawn_not_raised(tmp_path):
    """A painter that fails (plotext on degenerate data) leaves one line in the plot's frame."""
    app = GcsApp()
    async with app.run_test(size=(80, 24)) as pilot:
        await pilot.pause()
        plot = GcsPlot(id="probe")
        await app.screen.mount(plot)
        plot.styles.height = 10

        def bad(plt):
            raise ValueError("not enough values to unpack")

        plot.paint(bad)
        await pilot.pause()
        assert "plot not drawn" in str(plot.render())


async def test_a_toast_shows_a_hostile_name_as_text(tmp_path):
    """Error toasts carry paths and messages from files others wrote: control and bidi
    characters are shown escaped and brackets stay text (no markup, no MarkupError)."""
    app = GcsApp()
    async with app.run_test(size=(80, 24)) as pilot:
        app.notify("bad file [red]x\x1b]2;PWNED\x07\u202e.csv[/]", title="open\x1b[2J failed", severity="error")
        await pilot.pause()
        (toast,) = list(app._notifications)
        assert "\x1b" not in toast.message and "\u202e" not in toast.message
        assert "[red]x\\x1b]2;PWNED\\x07\\u202e.csv[/]" in toast.message
        assert toast.title == "open\\x1b[2J failed" and toast.markup is False
