"""State & covariance: every element's role, a-priori value and σ, editable, with the
latest estimate ± σ and, for the selected element, its strongest correlations.

Edits go into the analysis config (``[state.elements."<name>"]``) and rebuild the
state; press ``f`` to refit.
"""

from __future__ import annotations

import math
import textwrap

import numpy as np
from rich.text import Text
from textual.app import ComposeResult
from textual.containers import Horizontal, Vertical
from textual.widgets import DataTable, Label, Static
from textual.widgets.data_table import RowDoesNotExist

from gcs_core import display as fmt
from gcs_core.diagnosis.honest_sigma import flagged
from gcs_tui.tui.keys import SCREENS, bindings
from gcs_tui.tui.screens.base import GcsScreen
from gcs_tui.tui.screens.dialogs import Field, FormScreen
from gcs_tui.tui.screens.models import role_text
from gcs_tui.tui.widgets.tables import cursor_key, fill


class StateScreen(GcsScreen):
    """Element table (role, a priori, estimate) and the selected element's details."""

    VIEW = "state"
    CSS_PATH = "state.tcss"
    BINDINGS = bindings(SCREENS["state"])

    def __init__(self) -> None:
        super().__init__()
        self.hide_held = False

    def compose_body(self) -> ComposeResult:
        with Horizontal(id="state-split"):
            with Vertical(id="state-left"):
                yield Label(
                    "Elements  (s/c/h: role · e: edit value and σ · v: show/hide held)",
                    id="state-title",
                    classes="panel-title",
                )
                yield DataTable(id="elements", cursor_type="row", zebra_stripes=True)
            with Vertical(id="state-right"):
                yield Label("Selected element", classes="panel-title")
                yield Static("", id="element-detail", markup=False)

    # ------------------------------------------------------------------ drawing
    def refresh_view(self) -> None:
        wb = self.wb
        table = self.query_one("#elements", DataTable)
        selected = self._selected()
        # every width keeps every column: the estimate first, the table scrolls sideways
        labels = ["element", Text("estimate ± σ", justify="right"), "role", Text("a priori ± σ₀", justify="right")]
        rows = []
        est = wb.estimates() if not wb.stale else {}
        loose = wb.not_determined()
        prior = wb.set_by_prior()
        overridden = set(wb.config.state.elements)
        for e in wb.analysis.problem.state:
            if self.hide_held and e.role == "held":
                continue
            # dim: an element the fit did not determine (its σ is not to be trusted), or one
            # the a priori set rather than the data
            name = Text(
                e.name + (" *" if e.name in overridden else ""),
                style="dim" if e.name in loose or e.name in prior else "",
            )
            v = est.get(e.name)
            cells = [
                name,
                Text(fmt.estimate(v[0], v[1], e.unit) if v else "", justify="right"),
                role_text(e.role),
                Text(fmt.estimate(e.value, e.sigma0, e.unit), justify="right"),
            ]
            rows.append((cells, e.name))
        fill(table, labels, rows)
        if selected is not None:
            try:
                table.move_cursor(row=table.get_row_index(selected))
            except RowDoesNotExist:  # the element is hidden now (held): keep the cursor where it is
                pass
        held = sum(1 for e in wb.analysis.problem.state if e.role == "held")
        self.query_one("#state-title", Label).update(
            f"Elements{' (held hidden)' if self.hide_held else ''} — {held} held · "
            + (f"{len(loose)} not determined (dim) · " if loose else "")
            + (f"{len(set(prior) - set(loose))} set by the a priori (dim) · " if set(prior) - set(loose) else "")
            + "s/c/h role · e edit · v held · i details · * = set in config"
        )
        self._detail()

    def _selected(self) -> str | None:
        table = self.query_one("#elements", DataTable)
        if table.row_count == 0:
            return None
        return cursor_key(table)

    def _detail(self) -> None:
        name = self._selected()
        box = self.query_one("#element-detail", Static)
        if name is None:
            box.update("")
            return
        wb = self.wb
        e = wb.analysis.problem.state[name]
        lines = [
            name,
            f"  {e.description or e.effect}",
            f"  effect {e.effect or '—'} · internal unit {fmt.unit_column(e.unit)}",
            f"  a priori {fmt.estimate(e.value, e.sigma0, e.unit)}",
        ]
        res = wb.result
        if res is not None and not wb.stale and name in res.solve_for:
            i = res.solve_for.index(name)
            lines.append(f"  estimate {fmt.estimate(res.x[i], res.sigma[name], e.unit)}")
            s = flagged(wb.analysis.sigma_scale()).get(name)
            if s is not None:  # the residuals' correlation clearly inflates this σ
                lines.append(f"  with the residuals' correlation (×{s:.2f}):")
                lines.append(f"    {fmt.estimate(res.x[i], res.sigma[name] * s, e.unit)}")
            why = wb.not_determined().get(name) or wb.set_by_prior().get(name)
            if why:
                lines += textwrap.wrap(why, width=44, initial_indent="  ", subsequent_indent="    ")
            corr = res.correlation()[i]
            order = [j for j in np.argsort(-np.abs(corr)) if j != i][:5]
            lines.append("  strongest correlations:")
            lines += [f"    {res.solve_for[j]:<22s} {corr[j]:+.2f}" for j in order if math.isfinite(corr[j])]
            if why is None and e.name in {u for text in res.unobservable for u in text.replace(",", " ").split()}:
                lines.append("  unobservable: the data fix only a combination; σ here is from the a priori")
            budget = {c: float(v[i]) for c, v in res.consider_budget.items() if v[i] > 0}
            if budget:
                lines.append("  consider contributions:")
                lines += [
                    f"    {c:<22s} {fmt.quantity(v, e.unit, digits=2)}"
                    for c, v in sorted(budget.items(), key=lambda kv: -kv[1])[:4]
                ]
        box.update("\n".join(lines))

    def on_data_table_row_highlighted(self, event: DataTable.RowHighlighted) -> None:
        self._detail()

    # ------------------------------------------------------------------ actions
    def action_set_role(self, role: str) -> None:
        name = self._selected()
        if name is None:
            return
        self.app.run_job("state", f"{name} → {role}", lambda p, c: self.wb.set_element(name, role=role))

    def action_toggle_details(self) -> None:
        """Show or hide the selected element's details (always shown at 150+ columns)."""
        self.toggle_class("-details")

    def action_toggle_held(self) -> None:
        self.hide_held = not self.hide_held
        self.refresh_view()

    def action_edit_element(self) -> None:
        name = self._selected()
        if name is None:
            return
        e = self.wb.analysis.problem.state[name]
        shown = fmt.shown_unit(e.unit, e.value, e.sigma0)
        lab = fmt.unit_label(shown)
        tail = f" [{lab}]" if lab else " (no unit)"
        v0 = fmt.value_text(e.value, e.sigma0, e.unit, shown)
        s0 = fmt.sig(fmt.to_display(e.sigma0, e.unit, shown), 3)
        fields = [Field("value", f"value{tail}", v0), Field("sigma", f"σ{tail}", s0, positive=True)]

        def done(values):
            if not values:
                return
            # only what the user changed goes into the config (the shown text is rounded)
            value = fmt.from_display(values["value"], e.unit, shown) if values["value"] != float(v0) else None
            sigma = fmt.from_display(values["sigma"], e.unit, shown) if values["sigma"] != float(s0) else None
            # σ₀ shown to 3 digits: an untouched field keeps the exact configured value
            if value is None and sigma is None:
                return
            self.app.run_job("state", f"edit {name}", lambda p, c: self.wb.set_element(name, value=value, sigma=sigma))

        self.app.push_screen(FormScreen(f"Edit {name}", fields, note=e.description or ""), done)

    def on_data_table_row_selected(self, event: DataTable.RowSelected) -> None:
        self.action_edit_element()
