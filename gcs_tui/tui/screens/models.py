"""Models: per sensor the observation (or, for the gyro, transition) model or ``off``,
the physics of the reference vectors and the estimation method — and, live, the state
vector those choices define (names, units, roles; seed §3.2.2, Table 3-1).
"""

from __future__ import annotations

from rich.text import Text
from textual.app import ComposeResult
from textual.containers import Horizontal, Vertical
from textual.widgets import DataTable, Label

from gcs_core import display as fmt
from gcs_tui.tui.keys import SCREENS, bindings
from gcs_tui.tui.screens.base import GcsScreen
from gcs_tui.tui.theme import color
from gcs_tui.tui.widgets.tables import cursor_key

ROLE_STYLE = {"solve-for": "gcs-ok", "consider": "gcs-warn", "held": "gcs-muted"}


def role_text(role: str) -> Text:
    """A role coloured as everywhere else (solve-for green, consider amber, held grey)."""
    return Text(role, style=color(ROLE_STYLE.get(role, "gcs-muted")))


class ModelsScreen(GcsScreen):
    """Model choice per sensor and the state vector it defines."""

    VIEW = "models"
    CSS_PATH = "models.tcss"
    BINDINGS = bindings(SCREENS["models"])

    def compose_body(self) -> ComposeResult:
        with Horizontal(id="models-split"):
            with Vertical(id="models-left"):
                yield Label("Models  (enter/space: change)", classes="panel-title")
                yield DataTable(id="models-table", cursor_type="row", zebra_stripes=True)
            with Vertical(id="models-right"):
                yield Label("State vector", id="state-title", classes="panel-title")
                yield DataTable(id="models-state", cursor_type="row", zebra_stripes=True)

    def refresh_view(self) -> None:
        wb = self.wb
        table = self.query_one("#models-table", DataTable)
        keep = table.cursor_row
        table.clear(columns=True)
        table.add_columns("sensor / option", "kind", "model")
        gyro = {s.name for s in wb.mission.spec.sensors if s.type == "gyro"}
        for r in wb.model_rows():
            kind = {"sensor": "transition" if r.key in gyro else "observation"}.get(r.kind, r.kind)
            style = f"bold {color('gcs-bad')}" if r.value in ("off", "dipole") else "bold"
            table.add_row(r.label, Text(kind, style=color("gcs-muted")), Text(r.value, style=style), key=r.key)
        if keep is not None and 0 <= keep < table.row_count:
            table.move_cursor(row=keep)
        state = wb.analysis.problem.state
        st = self.query_one("#models-state", DataTable)
        st.clear(columns=True)
        st.add_columns("element", "unit", "role", Text("a-priori σ", justify="right"))
        counts = {"solve-for": 0, "consider": 0, "held": 0}
        for e in state:
            counts[e.role] += 1
            shown = fmt.display_unit(e.unit, e.sigma0)
            st.add_row(
                e.name,
                fmt.unit_column(shown),
                role_text(e.role),
                Text(fmt.quantity(e.sigma0, e.unit, digits=2, shown=shown), justify="right"),
                key=e.name,
            )
        self.query_one("#state-title", Label).update(
            f"State vector: {len(state)} elements — {counts['solve-for']} solve-for, "
            f"{counts['consider']} consider, {counts['held']} held"
        )

    def action_cycle_model(self) -> None:
        table = self.query_one("#models-table", DataTable)
        if table.row_count == 0:
            return
        key = cursor_key(table)
        self.app.run_job("models", f"model {key}", lambda p, c: self.wb.cycle_model(key))

    def on_data_table_row_selected(self, event: DataTable.RowSelected) -> None:
        if event.data_table.id == "models-table":
            self.action_cycle_model()
