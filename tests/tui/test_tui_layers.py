"""The layering rules of STYLE.md §1, checked on the source: the TUI has no storage code,
its model side has no Textual, and the engine has no UI imports."""

from __future__ import annotations

import ast
from pathlib import Path

from repo_paths import ROOT

#: gcs_tui modules that must stay free of Textual and Rich (plain Python over the engine)
PLAIN = ("workbench.py", "derive.py", "jobs.py", "filtr_run.py", "theme.py")


def imported_roots(path: Path) -> set[str]:
    tree = ast.parse(path.read_text(encoding="utf-8"))
    roots = set()
    for node in ast.walk(tree):
        if isinstance(node, ast.Import):
            roots |= {a.name.split(".")[0] for a in node.names}
        elif isinstance(node, ast.ImportFrom) and node.module and node.level == 0:
            roots.add(node.module.split(".")[0])
    return roots


def test_tui_never_imports_h5py():
    offenders = [p.name for p in (ROOT / "gcs_tui").rglob("*.py") if "h5py" in imported_roots(p)]
    assert offenders == []


def test_tui_model_side_has_no_textual():
    offenders = [name for name in PLAIN if imported_roots(ROOT / "gcs_tui" / "tui" / name) & {"textual", "rich"}]
    assert offenders == []


def test_engine_has_no_ui_imports():
    offenders = [
        str(p.relative_to(ROOT))
        for p in (ROOT / "gcs_core").rglob("*.py")
        if imported_roots(p) & {"textual", "rich", "textual_plotext", "gcs_tui"}
    ]
    assert offenders == []


def imported_modules(path: Path) -> set[str]:
    tree = ast.parse(path.read_text(encoding="utf-8"))
    mods = set()
    for node in ast.walk(tree):
        if isinstance(node, ast.Import):
            mods |= {a.name for a in node.names}
        elif isinstance(node, ast.ImportFrom) and node.module and node.level == 0:
            mods.add(node.module)
    return mods


def test_the_two_faces_are_separate_packages():
    """The TUI (gcs_tui/tui) never imports the headless face (gcs_tui/cli); the headless face
    reaches the TUI only to start it (the ``gcs tui`` command), and draws no Textual."""
    tui = [
        str(p.relative_to(ROOT))
        for p in (ROOT / "gcs_tui" / "tui").rglob("*.py")
        if any(m.startswith("gcs_tui.cli") for m in imported_modules(p))
    ]
    assert tui == []
    cli = {
        str(p.relative_to(ROOT)): {m for m in imported_modules(p) if m.startswith("gcs_tui.tui")}
        for p in (ROOT / "gcs_tui" / "cli").rglob("*.py")
    }
    assert {k: v for k, v in cli.items() if v} == {"gcs_tui/cli/commands.py": {"gcs_tui.tui.app"}}
    assert not any(imported_roots(p) & {"textual"} for p in (ROOT / "gcs_tui" / "cli").rglob("*.py"))
