"""``?``: every key of the app and of the screen it was opened from.

The rows come from :mod:`gcs_tui.keys`, the same data the bindings are built from.
"""

from __future__ import annotations

from textual.app import ComposeResult
from textual.binding import Binding
from textual.containers import Vertical
from textual.screen import ModalScreen
from textual.widgets import DataTable, Label

from gcs_tui.keys import VIEWS, help_rows


class HelpScreen(ModalScreen[None]):
    """Key help for ``scope`` (a view id): app keys first, then the view's own."""

    CSS_PATH = "help.tcss"
    BINDINGS = [Binding("escape,q,question_mark", "close", "Close")]

    def __init__(self, scope: str | None) -> None:
        super().__init__()
        self.scope = scope

    def compose(self) -> ComposeResult:
        title = dict((m, t) for m, _, t, _ in VIEWS).get(self.scope or "", "all screens")
        with Vertical(id="help-box"):
            yield Label(f"Keys — {title}   (esc closes; ctrl+p opens the command palette)", id="help-title")
            yield DataTable(id="help-table", cursor_type="row", zebra_stripes=True)

    def on_mount(self) -> None:
        table = self.query_one(DataTable)
        table.add_columns("where", "keys", "does")
        for scope, keys, what in help_rows(self.scope):
            table.add_row(scope, keys, what)
        table.focus()

    def action_close(self) -> None:
        self.dismiss(None)
