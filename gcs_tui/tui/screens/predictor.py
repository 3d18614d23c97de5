"""Predictor: the σ each element would reach along the data plan, without data
(seed §3.1, §4.3), and the error budget (noise-only and each consider element's share).

``p`` runs the prediction; ``[``/``]`` pick what the plot shows (the attitude about the
body axes, then each solve-for element).
"""

from __future__ import annotations

import numpy as np
from rich.text import Text
from textual.app import ComposeResult
from textual.widgets import DataTable, Static

from gcs_core import display as fmt
from gcs_tui.tui.keys import SCREENS, bindings
from gcs_tui.tui.screens.base import GcsScreen
from gcs_tui.tui.theme import marker, series
from gcs_tui.tui.widgets.plots import GcsPlot, marked_line, nice_x, nice_y

EMPTY = "No prediction yet — p predicts σ along the data plan (screen 4 edits the plan)."


class PredictorScreen(GcsScreen):
    """σ against time and the error budget table."""

    VIEW = "predictor"
    CSS_PATH = "predictor.tcss"
    BINDINGS = bindings(SCREENS["predictor"])
    AUTO_JOB = "predict"

    def __init__(self) -> None:
        super().__init__()
        self.element_i = 0

    def compose_body(self) -> ComposeResult:
        yield Static("", id="pred-info", markup=False)
        yield GcsPlot(id="pred-plot", title="predicted σ")
        yield DataTable(id="budget", cursor_type="row", zebra_stripes=True)

    def needs_job(self) -> bool:
        return self.wb.prediction is None

    def refresh_view(self) -> None:
        p = self.wb.prediction
        info = self.query_one("#pred-info", Static)
        plot = self.query_one("#pred-plot", GcsPlot)
        table = self.query_one("#budget", DataTable)
        if p is None:
            info.update(self.app.job_errors.get("predict", EMPTY))
            plot.paint(None, empty="no prediction")
            table.clear(columns=True)
            return
        att = p.attitude_sigma[-1] if p.attitude_sigma.size else np.full(3, np.nan)
        avail = ", ".join(f"{k} {100 * v:.0f}%" for k, v in p.availability.items())
        info.update(
            Text.assemble(
                (" method ", "bold"),
                p.method,
                f" · {fmt.span(float(p.times[0]), float(p.times[-1]))}",
                " · attitude σ at the plan's end (body x / y / z) ",
                (
                    " / ".join(
                        fmt.quantity(v, "rad", digits=2, shown=fmt.display_unit("rad", float(np.nanmax(att))))
                        for v in att
                    ),
                    "bold",
                ),
                f" · data: {avail}"
                + (
                    f" · {len(p.unobservable)} unobservable combinations (the plan fixes only "
                    "combinations of those elements; their σ is the a priori)"
                    if p.unobservable
                    else ""
                )
                + (
                    f" · {len(p.undetermined)} not determined by the plan (σ = a priori, dim)" if p.undetermined else ""
                ),
            )
        )
        choices = ["attitude"] + list(p.names)
        self.element_i %= len(choices)
        what = choices[self.element_i]
        plot.paint(lambda plt: self._plot(plt, p, what))
        self._budget(table, p, what)

    @staticmethod
    def _plot(plt, p, what) -> None:
        t = p.times.tolist()
        if what == "attitude":
            u = fmt.display_unit("rad", float(np.nanmax(p.attitude_sigma)) if p.attitude_sigma.size else 0.0)
            for k in range(3):
                y = p.attitude_sigma[:, k] * fmt.scale("rad", u)
                marked_line(plt, t, y.tolist(), series(k), marker(k))
            if p.attitude_sigma.size:
                nice_y(plt, 0.0, float(np.nanmax(p.attitude_sigma)) * fmt.scale("rad", u))
            plt.title(
                f"attitude σ about the body axes [{u}] · " + " ".join(f"{marker(k)} {a}" for k, a in enumerate("xyz"))
            )
        else:
            i = p.index(what)
            unit = p.units[i]
            shown = fmt.display_unit(unit, float(np.nanmax(p.sigma[:, i])))
            y = (p.sigma[:, i] * fmt.scale(unit, shown)).tolist()
            yn = (p.sigma_noise[:, i] * fmt.scale(unit, shown)).tolist()
            marked_line(plt, t, y, series(0), marker(0))
            nice_y(plt, 0.0, max(y) if y else 1.0)
            legend = f"{marker(0)} total"
            if p.consider:
                marked_line(plt, t, yn, series(1), marker(1))
                legend += f" {marker(1)} noise only"
            lab = fmt.unit_label(shown)
            plt.title(f"σ of {what}" + (f" [{lab}]" if lab else "") + f" · {legend} · [ ] other elements")
        if t:
            nice_x(plt, t[0], t[-1])
        plt.xlabel("t [s]")

    def _budget(self, table: DataTable, p, what: str) -> None:
        table.clear(columns=True)
        undetermined = set(p.undetermined)
        table.add_column("element" + (" (dim: not determined by the plan)" if undetermined else ""))
        table.add_column(Text("σ (all data)", justify="right"))
        table.add_column(Text("noise only", justify="right"))
        cons = list(p.consider)
        for c in cons:
            table.add_column(Text(c, justify="right"))
        for row in p.budget_rows():
            unit = row["unit"]
            shown = fmt.display_unit(unit, row["sigma"])
            style = ("bold " if row["name"] == what else "") + ("dim" if row["name"] in undetermined else "")
            cells = [
                Text(row["name"], style=style.strip()),
                Text(fmt.quantity(row["sigma"], unit, digits=2, shown=shown), justify="right"),
                Text(fmt.quantity(row["noise_only"], unit, digits=2, shown=shown), justify="right"),
            ]
            cells += [
                Text(fmt.quantity(row["consider"].get(c, 0.0), unit, digits=2, shown=shown), justify="right")
                for c in cons
            ]
            table.add_row(*cells, key=row["name"])

    def action_element(self, step: int) -> None:
        self.element_i += step
        self.refresh_view()
