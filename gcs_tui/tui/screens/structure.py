"""Residual structure: what the sensors' residuals follow (issue 26), opened from Diagnosis
with ``y``.

A list of the dependencies the residual-structure search found (significant ones first,
then each searched sensor's strongest tests); selecting one plots that residual component
against the channel: the samples (thinned) and the bin means the F test compared. Escape
closes. The search is the session's latest (:meth:`Analysis.structure`), run here if none.
"""

from __future__ import annotations

import numpy as np
from rich.text import Text
from textual.app import ComposeResult
from textual.binding import Binding
from textual.containers import Vertical
from textual.screen import ModalScreen
from textual.widgets import DataTable, Static

from gcs_core import display as fmt
from gcs_core.diagnosis import search as search_session
from gcs_core.diagnosis.structure_text import dependency_line, label
from gcs_core.units import DEG
from gcs_tui.tui.theme import color, series
from gcs_tui.tui.widgets.plots import GcsPlot, nice_y
from gcs_tui.tui.widgets.tables import cursor_key, fill

#: samples drawn at most in the scatter
MAX_POINTS = 3000


def _channel_scale(unit: str) -> tuple[float, str]:
    """Factor and label of a channel's axis (degrees for angles, hours for time)."""
    return {"rad": (1.0 / DEG, "deg"), "s": (1.0 / 3600.0, "h"), "rad/s": (3600.0 / DEG, "deg/h")}.get(
        unit, (1.0, unit)
    )


class StructureScreen(ModalScreen[None]):
    """Dependencies (a table) and the residual against the selected one's channel."""

    CSS = """
    StructureScreen { align: center middle; }
    #structure { width: 96%; height: 94%; border: round $accent; background: $surface; }
    #deps { height: 40%; }
    #dep-line { height: auto; max-height: 4; }
    #dep-plot { height: 1fr; }
    """
    BINDINGS = [Binding("escape,y", "close", "Close")]

    def __init__(self, analysis) -> None:
        super().__init__()
        self.analysis = analysis
        self.deps: list = []

    def compose(self) -> ComposeResult:
        with Vertical(id="structure"):
            yield DataTable(id="deps", cursor_type="row", zebra_stripes=True)
            yield Static("", id="dep-line", markup=False)
            yield GcsPlot(id="dep-plot", title="residual against the channel")

    def on_mount(self) -> None:
        a = self.analysis
        rep = a.structure_report or a.structure()
        found = list(rep.found)
        rest = [d for ds in rep.best.values() for d in ds if d not in found]
        self.deps = found + rest
        alpha = rep.alpha
        labels = ["sensor", "comp", "follows", Text("F", justify="right"), Text("p adj", justify="right"), "aliases"]
        rows = []
        for i, d in enumerate(self.deps):
            style = f"bold {color('gcs-warn')}" if d.p_adjusted < alpha else ""
            rows.append(
                (
                    [
                        Text(d.sensor, style=style),
                        d.component,
                        Text(label(d.channel), style=style),
                        Text(fmt.sig(d.F, 3), justify="right"),
                        Text(fmt.pvalue(d.p_adjusted), justify="right"),
                        ", ".join(label(x) for x in d.aliases) or "—",
                    ],
                    str(i),
                )
            )
        table = self.query_one("#deps", DataTable)
        table.border_title = f"residual structure · {rep.tests} tests, α = {alpha:g} · Esc closes"
        fill(table, labels, rows)
        if table.row_count:
            table.move_cursor(row=0)
        self._show()

    def on_data_table_row_highlighted(self, event: DataTable.RowHighlighted) -> None:
        self._show()

    def _selected(self):
        table = self.query_one("#deps", DataTable)
        if not table.row_count:
            return None
        key = cursor_key(table)
        return self.deps[int(key)] if key is not None and key.isdigit() else None

    def _show(self) -> None:
        d = self._selected()
        plot = self.query_one("#dep-plot", GcsPlot)
        line = self.query_one("#dep-line", Static)
        if d is None:
            line.update("The search found nothing to show (no sensor searched).")
            plot.paint(None, empty="nothing searched")
            return
        line.update(dependency_line(d, tuple(self.analysis.offered.get(d.sensor, ()))))
        res = self.analysis.result.residuals[d.sensor]
        ch = next((c for c in search_session.channels_of(self.analysis, d.sensor) if c.name == d.channel), None)
        if ch is None:
            plot.paint(None, empty="channel not available")
            return
        ci = list(res.components).index(d.component)
        r = np.asarray(res.residual, float)[:, ci]
        ok = np.asarray(res.used, bool) & np.isfinite(r) & np.isfinite(ch.values)
        x, y = np.asarray(ch.values, float)[ok], r[ok]
        step = max(1, x.size // MAX_POINTS)
        shown = fmt.common_unit(res.unit, y[::step])
        ys = fmt.scale(res.unit, shown)
        xs, xlab = _channel_scale(ch.unit)
        xb = np.asarray(d.centers, float) * xs
        yb = np.asarray(d.means, float) * ys

        def paint(plt) -> None:
            pts = y[::step] * ys
            plt.scatter((x[::step] * xs).tolist(), pts.tolist(), color=series(0), marker="dot")
            order = np.argsort(xb)
            plt.plot(xb[order].tolist(), yb[order].tolist(), color=series(1), marker="braille")
            plt.scatter(xb.tolist(), yb.tolist(), color=series(1), marker="o")
            lo, hi = float(np.percentile(pts, 1)), float(np.percentile(pts, 99))
            nice_y(plt, min(lo, float(yb.min())), max(hi, float(yb.max())), 5)
            plt.title(f"{d.sensor} {d.component} [{fmt.unit_label(shown)}] against {label(d.channel)}")
            plt.xlabel(f"{label(d.channel)} [{xlab}]")

        plot.paint(paint)

    def action_close(self) -> None:
        self.dismiss(None)
