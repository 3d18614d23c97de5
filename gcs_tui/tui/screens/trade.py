"""Trade study: the ranked plans of a results file, σ against the varied keys, and any
plan opened in the Data plan screen (``gcs trade`` writes the file; seed §1.1).

Keys: ``enter`` opens the selected plan in the Data plan screen (its span, gaps and
maneuvers become the config's ``[prediction]`` plan), ``]``/``[`` change the element
plotted, ``escape`` closes the screen.
"""

from __future__ import annotations

import math
from typing import TYPE_CHECKING

from rich.text import Text
from textual import getters
from textual.app import ComposeResult
from textual.binding import Binding
from textual.screen import Screen
from textual.widgets import DataTable, Footer, Static

from gcs_core.config_schema import Maneuver
from gcs_core.errors import GcsError
from gcs_core.trade.report import sigma_display
from gcs_core.trade.run import sigma_grid, varied_keys
from gcs_core.trade.study import ranked
from gcs_tui.tui.theme import series
from gcs_tui.tui.widgets.plots import GcsPlot
from gcs_tui.tui.widgets.tables import cursor_key

if TYPE_CHECKING:
    from gcs_tui.tui.app import GcsApp

#: plan keys the Data plan screen shows; the others (sensors, mountings) are named on open
PLAN_KEYS = ("span_min", "start_min", "passes", "pass_min", "separation_min", "gap_start_min", "gap_min", "maneuvers")


class TradeScreen(Screen):
    """The rows of one trade study (module docstring)."""

    if TYPE_CHECKING:  # for the type checker: the running app is a GcsApp
        app = getters.app(GcsApp)

    CSS_PATH = "trade.tcss"
    BINDINGS = [
        Binding("enter", "open_plan", "Open in Data plan", id="trade.open"),
        Binding("right_square_bracket", "element(1)", "Next element", id="trade.element"),
        Binding("left_square_bracket", "element(-1)", "Prev element", show=False, id="trade.prev"),
        Binding("escape", "app.pop_screen", "Close", id="trade.close"),
    ]

    def __init__(self, rows, *, source: str = "") -> None:
        super().__init__()
        self.rows = list(rows)
        self.ranked = ranked(self.rows)
        self.source = source
        ok = next((r for r in self.rows if r.status == "ok"), None)
        self.elements = list(ok.elements) if ok else []
        self.units = list(ok.units) if ok else []
        self.keys = list(ok.values) if ok else []
        self.plot_keys = list(varied_keys([r for r in self.rows if r.status == "ok"])) or self.keys[:1]
        self.element = 0

    def compose(self) -> ComposeResult:
        yield Static("", id="trade-info", markup=False)
        yield DataTable(id="trade-table", cursor_type="row", zebra_stripes=True)
        yield GcsPlot(id="trade-plot", title="σ against the varied key")
        yield Footer()

    def on_mount(self) -> None:
        table = self.query_one("#trade-table", DataTable)
        table.add_columns(
            "#",
            Text("score", justify="right"),
            *self.keys,
            *(
                Text(f"σ {n.split('.', 1)[-1]} [{sigma_display(1.0, u)[1]}]", justify="right")
                for n, u in zip(self.elements, self.units)
            ),
        )
        for rank, (score, r) in enumerate(self.ranked, start=1):
            cells = [str(rank), Text("failed" if r.status != "ok" else f"{score:.3g}", justify="right")]
            cells += [str(r.values.get(k)) for k in self.keys]
            for i, (v, u) in enumerate(zip(r.sigma, r.units)):
                prior = bool(r.prior_limited) and r.prior_limited[i]
                text = "—" if math.isnan(v) else ("undet." if math.isinf(v) else f"{sigma_display(v, u)[0]:.3g}")
                cells.append(Text(text + ("*" if prior else ""), justify="right", style="dim" if prior else ""))
            table.add_row(*cells, key=str(r.index))
        self._redraw()

    def _redraw(self) -> None:
        n_ok = sum(r.status == "ok" for r in self.rows)
        name = self.elements[self.element] if self.elements else "—"
        self.query_one("#trade-info", Static).update(
            Text.assemble(
                ("trade study ", "bold"),
                f"{self.source}  ·  {len(self.rows)} plans ({n_ok} predicted)  ·  "
                f"varied: {', '.join(self.keys) or '—'}  ·  plotted: {name}  ·  * = set by the a priori",
            )
        )
        self.query_one("#trade-plot", GcsPlot).paint(
            self._plot if self.elements and self.keys else None, empty="no plans to plot"
        )

    def _plot(self, plt) -> None:
        name, unit = self.elements[self.element], self.units[self.element]
        ok = [r for _, r in self.ranked if r.status == "ok"]
        k1 = self.plot_keys[0]
        k2 = self.plot_keys[1] if len(self.plot_keys) > 1 else None
        v1, v2, G = sigma_grid(ok, name, (k1, k2) if k2 else (k1,))
        numeric = all(isinstance(v, (int, float)) and not isinstance(v, bool) for v in v1)
        x = list(v1) if numeric else list(range(len(v1)))
        for j, b in enumerate(v2):
            y = [sigma_display(float(g), unit)[0] for g in G[:, j]]
            pts = [(a, c) for a, c in zip(x, y) if math.isfinite(c) and c > 0]
            if pts:
                plt.plot(
                    [a for a, _ in pts],
                    [c for _, c in pts],
                    marker="dot",
                    color=series(j % 6),
                    label=None if k2 is None else f"{k2}={b}",
                )
        if not numeric:
            plt.xticks(x, [str(v) for v in v1])
        plt.yscale("log")
        plt.xlabel(k1)
        plt.title(f"σ {name} [{sigma_display(1.0, unit)[1]}] (best over the other keys)")

    def action_element(self, step: int) -> None:
        if self.elements:
            self.element = (self.element + step) % len(self.elements)
            self._redraw()

    def selected(self):
        table = self.query_one("#trade-table", DataTable)
        if table.row_count == 0:
            return None
        index = int(cursor_key(table))
        return next(r for r in self.rows if r.index == index)

    def on_data_table_row_selected(self, event: DataTable.RowSelected) -> None:
        self.action_open_plan()

    def action_open_plan(self) -> None:
        row = self.selected()
        wb = self.app.workbench
        if row is None or not row.description:
            return
        if wb is None or not wb.ready:
            self.app.notify("open the study's mission first (o)", severity="warning")
            return
        d = row.description
        mans = tuple(Maneuver(m["start"], m["duration"], m["axis"], m["rate_deg_s"]) for m in d["maneuvers"])
        try:
            wb.set_plan(start=d["start"], end=d["end"], gaps=tuple(tuple(g) for g in d["gaps"]), maneuvers=mans)
        except GcsError as err:
            self.app.notify(str(err), title="plan not opened", severity="error")
            return
        other = [f"{k}={v}" for k, v in row.values.items() if k not in PLAN_KEYS and not k.startswith("maneuver.")]
        if other:
            self.app.notify("not a data-plan setting, not applied: " + ", ".join(other), severity="warning")
        self.app.changed()
        self.app.pop_screen()
        self.app.switch_mode("plan")
