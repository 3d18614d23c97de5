"""``?``: every key of the app and of the screen it was opened from, and what the numbers
on the screens mean (normalized RMS, Δχ², p and p adj, MDB, id?, aliases, NIS ...).

The key rows come from :mod:`gcs_tui.tui.keys`, the same data the bindings are built from;
the terms from :mod:`gcs_tui.tui.glossary`. Tab moves between the keys and the terms; both
scroll.
"""

from __future__ import annotations

from rich.text import Text
from textual.app import ComposeResult
from textual.binding import Binding
from textual.containers import Vertical, VerticalScroll
from textual.screen import ModalScreen
from textual.widgets import DataTable, Label, Static

from gcs_tui.tui.glossary import TERMS
from gcs_tui.tui.keys import VIEWS, help_rows


def terms_text() -> Text:
    out = Text()
    for i, (term, meaning) in enumerate(TERMS):
        if i:
            out.append("\n\n")
        out.append(term, style="bold")
        out.append(" — " + meaning)
    return out


class HelpScreen(ModalScreen[None]):
    """Key help for ``scope`` (a view id): app keys first, then the view's own; then the terms."""

    CSS_PATH = "help.tcss"
    BINDINGS = [Binding("escape,q,question_mark", "close", "Close")]

    def __init__(self, scope: str | None) -> None:
        super().__init__()
        self.scope = scope

    def compose(self) -> ComposeResult:
        title = dict((m, t) for m, _, t, _ in VIEWS).get(self.scope or "", "all screens")
        with Vertical(id="help-box"):
            yield Label(
                f"Keys — {title}   (esc closes · tab: the terms · ctrl+p: command palette)",
                id="help-title",
                markup=False,
            )
            yield DataTable(id="help-table", cursor_type="row", zebra_stripes=True)
            yield Label("What the numbers mean", id="terms-title", markup=False)
            with VerticalScroll(id="terms-box", can_focus=True):
                yield Static(terms_text(), id="terms", markup=False)

    def on_mount(self) -> None:
        table = self.query_one(DataTable)
        table.add_columns("where", "keys", "does")
        for scope, keys, what in help_rows(self.scope):
            table.add_row(scope, keys, what)
        table.focus()

    def action_close(self) -> None:
        self.dismiss(None)
