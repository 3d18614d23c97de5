"""Mission: what was imported — sensors, samples, spans, gaps, dropped rows — and a
timeline of when each sensor has data.
"""

from __future__ import annotations

from rich.text import Text
from textual.app import ComposeResult
from textual.containers import Vertical
from textual.widgets import DataTable, Static

from gcs_core import display as fmt
from gcs_tui.tui.keys import SCREENS, bindings
from gcs_tui.tui.screens.base import GcsScreen
from gcs_tui.tui.theme import color, series
from gcs_tui.tui.widgets.plots import GcsPlot


class MissionScreen(GcsScreen):
    """Sensors table and data timeline of the open mission."""

    VIEW = "mission"
    CSS_PATH = "mission.tcss"
    BINDINGS = bindings(SCREENS["mission"])

    def compose_body(self) -> ComposeResult:
        with Vertical(id="mission-top"):
            yield Static("", id="mission-info", markup=False)
            yield DataTable(id="sensors", cursor_type="row", zebra_stripes=True)
        yield GcsPlot(id="timeline", title="data timeline")

    def refresh_view(self) -> None:
        wb = self.wb
        m = wb.mission
        spec = m.spec
        t0, t1 = m.span()
        self.query_one("#mission-info", Static).update(
            Text.assemble(
                (spec.name, "bold"),
                f"  {spec.attitude_mode.replace('_', ' ')}  ·  epoch ",
                spec.epoch.strftime("%Y-%m-%d %H:%M:%S UTC"),
                f"  ·  span {fmt.span(t0, t1)}",
                f"  ·  {len(spec.sensors)} sensors",
            )
        )
        table = self.query_one("#sensors", DataTable)
        table.clear(columns=True)
        table.add_column("sensor", key="sensor")
        table.add_column("type", key="type")
        table.add_column("model", key="model")
        table.add_column(Text("samples", justify="right"), key="n")
        table.add_column("span", key="span")
        table.add_column(Text("cadence", justify="right"), key="cadence")
        table.add_column(Text("gaps", justify="right"), key="gaps")
        table.add_column(Text("dropped", justify="right"), key="dropped")
        rows = wb.sensor_rows()
        for r in rows:
            dropped = r.dropped_nan + r.dropped_duplicates
            table.add_row(
                r.name,
                r.type.replace("_", " "),
                Text(r.model, style=f"bold {color('gcs-bad')}" if r.model == "off" else ""),
                Text(str(r.samples), justify="right"),
                fmt.span(r.t0, r.t1),
                Text(fmt.seconds(r.cadence), justify="right"),
                Text(str(r.gaps), justify="right"),
                Text(f"{r.dropped_nan} NaN, {r.dropped_duplicates} dup" if dropped else "0", justify="right"),
                key=r.name,
            )
        for f in m.report.files:
            if f.what.startswith("telemetry "):
                continue
            table.add_row(
                Text(f.what, style="italic"),
                "file",
                "",
                Text(str(f.rows), justify="right"),
                "",
                "",
                "",
                Text(str(f.dropped_nan + f.dropped_duplicates), justify="right"),
                key=f"file:{f.what}",
            )
        self.query_one("#timeline", GcsPlot).paint(lambda plt: self._timeline(plt, rows))

    @staticmethod
    def _timeline(plt, rows) -> None:
        n = len(rows)
        for i, r in enumerate(rows):
            y = n - i
            colour = series(i)
            for a, b in r.spans:
                plt.plot([a, b], [y, y], color=colour, marker="sd")
            for (_, b), (a, _) in zip(r.spans[:-1], r.spans[1:]):
                plt.scatter([0.5 * (a + b)], [y], color="red", marker="x")
        plt.yticks(list(range(n, 0, -1)), [r.name for r in rows])
        plt.ylim(0.5, n + 0.5)
        plt.xlabel("t [s]   (x: data gap)")
        plt.title("data timeline")
