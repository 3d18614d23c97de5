"""Issue 23 item 7: control sequences in names from files never reach the terminal.

``name = "ok\\u001b]2;PWNED\\u0007"`` retitled the terminal through ``gcs import``, the
progress lines and the TUI's status line; NUL and U+202E were echoed in error lines.
One sanitiser (:func:`gcs_core.textsafe.terminal_safe`) now shows them escaped.
"""

from __future__ import annotations

import io
import re
import shutil
from types import SimpleNamespace

import pytest
from repo_paths import SAMPLE_MISSIONS

from gcs_core.textsafe import BIDI, is_safe, terminal_safe
from gcs_tui.cli import commands as cli
from gcs_tui.cli.progress import Progress

MISSION = SAMPLE_MISSIONS / "nominal-sunpoint"
PWNED = "ok\x1b]2;PWNED\x07"
OSC52 = "x\x1b]52;c;ZWNobyBwd25lZA==\x07"
#: what a terminal would obey: ESC, BEL, C1 controls, NUL, the bidi overrides
RAW = re.compile("[\x00-\x08\x0b-\x1f\x7f-\x9f" + BIDI + "]")


def test_the_sanitiser_escapes_controls_c1_and_bidi():
    assert terminal_safe(PWNED) == "ok\\x1b]2;PWNED\\x07"
    assert terminal_safe("a\x00b\x9bc\u202ed\u2066") == "a\\x00b\\x9bc\\u202ed\\u2066"
    assert terminal_safe("tab\tand\nnewline") == "tab\tand\nnewline"
    assert terminal_safe("tab\tand\nnewline", one_line=True) == "tab\\x09and\\x0anewline"
    assert terminal_safe("σ ± 3 µT, Ünïcödé ✓") == "σ ± 3 µT, Ünïcödé ✓"
    assert is_safe("plain") and not is_safe(OSC52)


@pytest.fixture
def hostile_mission(tmp_path):
    m = tmp_path / "mission"
    shutil.copytree(MISSION, m)
    toml = m / "mission.toml"
    text = toml.read_text().replace('name = "nominal-sunpoint"', 'name = "ok\\u001b]2;PWNED\\u0007\\u202e"', 1)
    toml.write_text(text)
    return m


def test_gcs_import_prints_a_hostile_name_escaped(hostile_mission, capsys):
    assert cli.main(["--progress", "plain", "import", str(hostile_mission)]) == 0
    out, err = capsys.readouterr()
    assert "ok\\x1b]2;PWNED\\x07\\u202e" in out
    assert not RAW.search(out) and not RAW.search(err)


def test_progress_lines_escape_in_plain_and_bar_mode():
    stream = io.StringIO()
    prog = Progress(stream, mode="plain")
    with prog.task(f"fitting {PWNED}") as task:
        task(text=OSC52)
    prog.message(f"step {PWNED}")
    assert not RAW.search(stream.getvalue()) and "PWNED\\x07" in stream.getvalue()

    from rich.console import Console

    screen = io.StringIO()
    bar = Progress(mode="auto", console=Console(file=screen, force_terminal=True, width=100))
    with bar.task(f"fitting {PWNED} [red]x[/]") as task:
        task(1, 2, OSC52)
        bar.message(PWNED)
    shown = screen.getvalue()
    assert "\x1b]" not in shown and "\x07" not in shown  # rich's own CSI colours only
    assert "[red]x[/]" in shown  # markup from a file is text


def test_error_lines_escape_nul_and_bidi(tmp_path, capsys):
    cfg = tmp_path / "c.toml"
    cfg.write_text('[analysis]\nmission = "m"\n"\\u202eevil\\u0000" = 1\n', encoding="utf-8")
    assert cli.main(["-q", "batch", str(cfg)]) == 2
    err = capsys.readouterr().err
    assert err.count("\n") == 1 and not RAW.search(err)
    assert "\\u202e" in err


def test_the_tui_status_line_and_title_are_escaped():
    from gcs_tui.tui.app import GcsApp

    wb = SimpleNamespace(
        ready=True,
        mission=SimpleNamespace(name=PWNED),
        result=None,
        filtr=None,
        stale=False,
        current=SimpleNamespace(steps=[]),
    )
    fake = SimpleNamespace(workbench=wb, last_notice=OSC52)
    text = GcsApp.status_text(fake)
    assert not RAW.search(text) and "PWNED\\x07" in text
