"""``ctrl+s``: save the analysis config without losing anything.

The dialog is pre-filled with :meth:`~gcs_tui.tui.workbench.Workbench.default_save_path`
(``--out`` honoured, never a bundled or git-tracked file) as a full path. A file that
exists is never replaced without asking; when it holds comments (which the writer cannot
keep: it writes the config's values) the question offers a new file beside it instead.
The notice names the full path written.
"""

from __future__ import annotations

from pathlib import Path
from typing import TYPE_CHECKING

from gcs_core.errors import GcsError
from gcs_tui.tui import paths
from gcs_tui.tui.screens.dialogs import ConfirmScreen, Field, FormScreen

if TYPE_CHECKING:
    from gcs_tui.tui.app import GcsApp


def open_dialog(app: GcsApp) -> None:
    """The save dialog, pre-filled with the default target (its full path)."""
    wb = app.workbench
    if not wb.ready:
        return
    default = str(wb.default_save_path())

    def chosen(values: dict | None) -> None:
        if values and values.get("path"):
            ask_then_save(app, Path(values["path"]).expanduser())

    app.push_screen(
        FormScreen(
            "Save the analysis config",
            [Field("path", "File", default, kind="text")],
            note="Paths inside are written relative to the file. An existing file is not replaced without asking.",
        ),
        chosen,
    )


def ask_then_save(app: GcsApp, path: Path) -> None:
    """Save to ``path``; when it exists (and is not the file this session last wrote),
    ask first — and with comments in it, offer a new file beside it instead."""
    path = path.resolve()
    wb = app.workbench
    if not path.exists() or (wb.save_path is not None and path == Path(wb.save_path).resolve()):
        save_to(app, path)
        return
    comments = paths.comment_lines(path)
    if comments or paths.protected(path):
        other = paths.free_name(path)
        why = (
            f"{path} exists"
            + (f" and holds {comments} comment line(s) that a save cannot keep" if comments else "")
            + (" (a file bundled with GCS or tracked by git)" if paths.protected(path) else "")
            + f". Save to the new file {other} instead? It stays as it is."
        )
        app.push_screen(
            ConfirmScreen("Keep the existing file?", why, yes=f"save as {other.name}", no="cancel"),
            lambda ok: _answer(app, ok, other, path),
        )
        return
    app.push_screen(
        ConfirmScreen(
            f"Replace {path.name}?", f"{path} exists. Replace it with this config?", yes="replace", no="cancel"
        ),
        lambda ok: _answer(app, ok, path, path),
    )


def _answer(app: GcsApp, ok: bool | None, target: Path, existing: Path) -> None:
    if ok:
        save_to(app, target)
    else:
        _kept(app, existing)


def _kept(app: GcsApp, path: Path) -> None:
    app.last_notice = f"not saved; {path} kept"
    app.notify(app.last_notice, severity="warning")
    app.changed()


def save_to(app: GcsApp, path: Path) -> Path | None:
    """Write the config to ``path`` (its folder is created) and say where, in full."""
    try:
        out = app.workbench.save_config(path)
    except (GcsError, OSError) as err:
        app.notify(str(err), title="config not saved", severity="error")
        return None
    app.last_notice = f"config saved to {out}"
    app.notify(str(out), title="config saved", timeout=15)
    app.changed()
    return out
