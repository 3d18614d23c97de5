"""Diagnosis: the ranked candidate effects (score test, Bonferroni-corrected), the
explanation of the selected one, and the add/refit history — normalized RMS per step
on the fitted span with the held-out span beside it.

``a`` adds the selected candidate and refits in the background; ``r`` removes an
effect already in the state.
"""

from __future__ import annotations

import math

from rich.text import Text
from textual.app import ComposeResult
from textual.containers import Horizontal, Vertical
from textual.widgets import DataTable, Static

from gcs_tui import format as fmt
from gcs_tui.keys import SCREENS, bindings
from gcs_tui.screens.base import GcsScreen
from gcs_tui.theme import color, series
from gcs_tui.widgets.plots import GcsPlot


def step_label(step) -> str:
    return "fit" if step.action == "fit" else ("+" if step.action == "add" else "−") + (step.effect or "")


class DiagnosisScreen(GcsScreen):
    """Candidates, explanation and the RMS-per-step charts."""

    VIEW = "diagnosis"
    CSS_PATH = "diagnosis.tcss"
    BINDINGS = bindings(SCREENS["diagnosis"])
    NEEDS_FIT = True

    def compose_body(self) -> ComposeResult:
        with Horizontal(id="diag-top"):
            with Vertical(id="diag-cands-box"):
                yield DataTable(id="candidates", cursor_type="row", zebra_stripes=True)
            yield Static("", id="explanation", markup=False)
        with Horizontal(id="diag-charts"):
            yield GcsPlot(id="steps-fit", title="normalized RMS per step")
            yield GcsPlot(id="steps-holdout", title="held-out RMS per step")
        yield Static("", id="steps-legend", markup=False)

    # ------------------------------------------------------------------ drawing
    def refresh_view(self) -> None:
        a = self.wb.analysis
        alpha = a.config.significance
        table = self.query_one("#candidates", DataTable)
        table.clear(columns=True)
        table.add_column(Text("#", justify="right"))
        table.add_column("candidate")
        table.add_column(Text("Δχ²", justify="right"))
        table.add_column(Text("dof", justify="right"))
        table.add_column(Text("p", justify="right"))
        if not self.compact:
            table.add_column(Text("p adj", justify="right"))
        table.add_column("id?")
        table.add_column("aliases")
        for i, c in enumerate(a.candidates):
            signif = c.p_adjusted < alpha
            style = f"bold {color('gcs-warn')}" if signif and c.identifiable else ""
            names = list(c.aliases_state) + [x for x, _ in c.aliases_candidates]
            aliases = ", ".join(names[:2]) + (f" +{len(names) - 2}" if len(names) > 2 else "") if names else "—"
            cells = [Text(str(i + 1), justify="right"), Text(c.id, style=style),
                     Text(fmt.sig(c.delta_chi2, 3), justify="right"), Text(str(c.dof), justify="right"),
                     Text(fmt.pvalue(c.p_value), justify="right")]
            if not self.compact:
                cells.append(Text(fmt.pvalue(c.p_adjusted), justify="right"))
            cells += [Text("yes" if c.identifiable else "no",
                           style=color("gcs-ok" if c.identifiable else "gcs-bad")), Text(aliases)]
            table.add_row(*cells, key=c.id)
        if table.row_count:
            table.move_cursor(row=0)
        self._explain()
        self._charts()

    def _selected(self):
        table = self.query_one("#candidates", DataTable)
        cands = self.wb.analysis.candidates
        if table.row_count == 0 or not cands:
            return None
        key = table.coordinate_to_cell_key((table.cursor_row, 0)).row_key.value
        return next((c for c in cands if c.id == key), None)

    def _explain(self) -> None:
        c = self._selected()
        box = self.query_one("#explanation", Static)
        if c is None:
            box.update("No candidate effects: every catalogue effect is in the state.")
            return
        units = {e.name: e.unit for e in self.wb.analysis.problem.state}
        lines = [c.explanation, ""]
        for name, value in c.estimate.items():
            s = c.sigma.get(name, math.nan)
            mdb = c.mdb.get(name, math.nan)
            unit = units.get(name, "1")
            lines.append(f"{name}: {fmt.estimate(value, s, unit)}   (MDB {fmt.quantity(mdb, unit, digits=2)})")
        box.update("\n".join(lines))

    def on_data_table_row_highlighted(self, event: DataTable.RowHighlighted) -> None:
        self._explain()

    def _charts(self) -> None:
        steps = list(self.wb.analysis.steps)
        sensors = list(self.wb.result.residuals)
        fit_plot = self.query_one("#steps-fit", GcsPlot)
        ho_plot = self.query_one("#steps-holdout", GcsPlot)
        if not steps:
            fit_plot.paint(None, empty="no steps yet")
            ho_plot.paint(None, empty="no steps yet")
        else:
            fit_plot.paint(lambda plt: self._chart(plt, steps, sensors, "rms_after", "normalized RMS (fitted span)"))
            if any(s.holdout_after for s in steps):
                ho_plot.paint(lambda plt: self._chart(plt, steps, sensors, "holdout_after", "held-out RMS"))
            else:
                ho_plot.paint(None, empty="no held-out score (diagnosis.holdout_fraction)")
        # the sensors' colours here, not in the charts: plotext draws its legend over the
        # top-left corner, where step 0 (the highest RMS) is
        legend = Text(" ")
        for k, name in enumerate(sensors if steps else ()):
            legend.append("● " + name, style="rgb({},{},{})".format(*series(k)))
            legend.append("  ")
        if steps:
            legend.append("· steps — " + "  ".join(f"{i}: {step_label(s)}" for i, s in enumerate(steps)))
        self.query_one("#steps-legend", Static).update(legend if steps else "")

    @staticmethod
    def _chart(plt, steps, sensors, attr, title) -> None:
        x = list(range(len(steps)))
        top = 1.1
        for k, name in enumerate(sensors):
            y = [getattr(s, attr).get(name, math.nan) for s in steps]
            finite = [v for v in y if math.isfinite(v)]
            if not finite:
                continue
            top = max(top, max(finite) * 1.02)
            plt.plot(x, [v if math.isfinite(v) else 0.0 for v in y], color=series(k), marker="dot")
        plt.horizontal_line(1.0, color="gray")
        plt.horizontal_line(1.05, color="red")
        plt.ylim(0.9, top)
        plt.xticks(x, [str(i) for i in x])
        if len(x) == 1:
            plt.xlim(-0.5, 0.5)
        plt.title(title)
        plt.xlabel("step")

    # ------------------------------------------------------------------ actions
    def action_add_selected(self) -> None:
        c = self._selected()
        if c is None:
            self.app.notify("no candidate selected", severity="warning")
            return
        if not c.identifiable:
            self.app.notify(f"{c.id} is not identifiable with these data; adding it anyway", severity="warning")
        self.app.change_effect(c.id, True)

    def action_remove_effect(self) -> None:
        self.app.action_remove_effect()
