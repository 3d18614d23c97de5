"""Diagnosis: the ranked candidate effects (score test, Bonferroni-corrected), the
explanation of the selected one, and the add/refit history — normalized RMS per step
on the fitted span with the held-out span beside it.

``a`` adds the selected candidate and refits in the background (asking first when it
is not significant or not identifiable); ``r`` removes an effect already in the state;
``y`` opens what the residuals follow (the residual-structure search, :mod:`.structure`).
Every width keeps every column (the table scrolls sideways); the explanation pane
scrolls and holds the whole paragraph, the full aliases and the estimates. Below 120
columns the charts share the lower pane with the explanation (``g`` switches).
"""

from __future__ import annotations

import math

from rich.text import Text
from textual.app import ComposeResult
from textual.binding import Binding
from textual.containers import Horizontal, Vertical, VerticalScroll
from textual.widgets import DataTable, Static

from gcs_core import display as fmt
from gcs_core.diagnosis.ranking import RULE
from gcs_tui.tui.keys import SCREENS, bindings
from gcs_tui.tui.screens.base import GcsScreen
from gcs_tui.tui.theme import color, marker, series
from gcs_tui.tui.theme import rgb as color_rgb
from gcs_tui.tui.widgets.plots import GcsPlot, nice_y
from gcs_tui.tui.widgets.tables import cursor_key, fill


def step_label(step) -> str:
    return "fit" if step.action == "fit" else ("+" if step.action == "add" else "−") + (step.effect or "")


class DiagnosisScreen(GcsScreen):
    """Candidates, explanation and the RMS-per-step charts."""

    VIEW = "diagnosis"
    CSS_PATH = "diagnosis.tcss"
    # y: what the residuals follow (issue 26), hidden from the footer
    BINDINGS = [*bindings(SCREENS["diagnosis"]), Binding("y", "structure", "Residual structure", show=False)]
    NEEDS_FIT = True

    def compose_body(self) -> ComposeResult:
        with Horizontal(id="diag-top"):
            with Vertical(id="diag-cands-box"):
                yield DataTable(id="candidates", cursor_type="row", zebra_stripes=True)
            with VerticalScroll(id="explanation-box", can_focus=True):
                yield Static("", id="explanation", markup=False)
        with Horizontal(id="diag-charts"):
            yield GcsPlot(id="steps-fit", title="normalized RMS per step")
            yield GcsPlot(id="steps-holdout", title="held-out RMS per step")
        yield Static("", id="steps-legend", markup=False)

    # ------------------------------------------------------------------ drawing
    def refresh_view(self) -> None:
        a = self.wb.analysis
        table = self.query_one("#candidates", DataTable)
        labels = [
            Text("#", justify="right"),
            "candidate",
            Text("Δχ²", justify="right"),
            Text("dof", justify="right"),
            Text("p", justify="right"),
            Text("p adj", justify="right"),
            "id?",
            "aliases",
        ]
        rows = []
        for i, c in enumerate(a.candidates):
            style = f"bold {color('gcs-warn')}" if c.passes else ""
            names = list(c.aliases_state) + [x for x, _ in c.aliases_candidates]
            aliases = ", ".join(names) if names else "—"
            cells = [
                Text(str(i + 1), justify="right"),
                Text(c.id, style=style),
                Text(fmt.sig(c.delta_chi2, 3), justify="right"),
                Text(str(c.dof), justify="right"),
                Text(fmt.pvalue(c.p_value), justify="right"),
                Text(fmt.pvalue(c.p_adjusted), justify="right"),
            ]
            cells += [
                Text("yes" if c.identifiable else "no", style=color("gcs-ok" if c.identifiable else "gcs-bad")),
                Text(aliases),
            ]
            rows.append((cells, c.id))
        fill(table, labels, rows)
        if table.row_count:
            table.move_cursor(row=0)
        self._explain()
        self._charts()

    def _selected(self):
        table = self.query_one("#candidates", DataTable)
        cands = self.wb.analysis.candidates
        if table.row_count == 0 or not cands:
            return None
        key = cursor_key(table)
        return next((c for c in cands if c.id == key), None)

    def _explain(self) -> None:
        c = self._selected()
        box = self.query_one("#explanation", Static)
        if c is None:
            box.update("No candidate effects: every catalogue effect is in the state.")
            return
        self.app.selected_candidate = c.id
        units = {e.name: e.unit for e in self.wb.analysis.problem.state}
        alpha = self.wb.analysis.config.diagnosis.significance
        verdict = (
            "significant and identifiable: a good candidate to add (a)"
            if c.passes
            else "not significant"
            if c.identifiable
            else "not identifiable" + ("" if c.significant else ", not significant")
        )
        lines = [
            f"{c.id} — {verdict}",
            f"Δχ² {fmt.sig(c.delta_chi2, 3)} on {c.dof} dof · {fmt.p_text(c.p_value)} · "
            f"{fmt.p_text(c.p_adjusted, 'p adj')} (α = {alpha:g})",
            "",
            c.explanation,
            "",
        ]
        lines.append(
            "If added (one linearization, first order), with MDB = the smallest value this test "
            "detects 80 % of the time:"
        )
        for name, value in c.estimate.items():
            s = c.sigma.get(name, math.nan)
            mdb = c.mdb.get(name, math.nan)
            unit = units.get(name, "1")
            shown = fmt.shown_unit(unit, value, s)
            lines.append(
                f"  {name}: {fmt.estimate(value, s, unit, shown=shown)}   "
                f"(MDB {fmt.quantity(mdb, unit, digits=2, shown=shown)})"
            )
        state_al = ", ".join(c.aliases_state) or "none"
        cand_al = ", ".join(f"{a} (ρ {rho:.3f})" for a, rho in c.aliases_candidates) or "none"
        lines += ["", f"Aliases in the state: {state_al}", f"Aliases among the candidates: {cand_al}", "", RULE]
        box.update("\n".join(lines))
        pane = self.query_one("#explanation-box", VerticalScroll)
        pane.border_title = "explanation · tab here, ↑/↓ scroll"
        pane.scroll_home(animate=False)

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
            legend.append(f"{marker(k)} {name}", style="rgb({},{},{})".format(*series(k)))
            legend.append("  ")
        if steps:
            legend.append("┄ 1.0 noise floor", style="grey62")
            legend.append("  ")
            legend.append("── 1.05 limit", style=color("gcs-bad"))
            legend.append("  ")
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
            yy = [v if math.isfinite(v) else 0.0 for v in y]
            plt.plot(x, yy, color=series(k), marker="braille")  # the line thin,
            plt.scatter(x, yy, color=series(k), marker=marker(k))  # the steps by shape
        plt.horizontal_line(1.0, color=(158, 158, 158))
        plt.horizontal_line(1.05, color=color_rgb("gcs-bad"))
        nice_y(plt, 0.9, top, 4)
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
        self.app.add_candidate(c)

    def action_toggle_charts(self) -> None:
        """Below 120 columns: the lower pane shows the charts instead of the explanation."""
        self.toggle_class("-charts")

    def action_remove_effect(self) -> None:
        self.app.action_remove_effect()

    def action_structure(self) -> None:
        """The residual-structure search's dependencies; one selected, its residual against
        the channel (:mod:`gcs_tui.tui.screens.structure`)."""
        from gcs_tui.tui.screens.structure import StructureScreen

        if self.wb is None or self.wb.analysis.result is None:
            self.app.notify("no fit yet", severity="warning")
            return
        self.app.push_screen(StructureScreen(self.wb.analysis))
