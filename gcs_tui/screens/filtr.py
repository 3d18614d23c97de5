"""FILTR: the estimator block by block — step one block, run to the end, cancel —
with a progress bar, the live state and σ, and the NIS of each block against its χ²
band (a consistent filter keeps 95 % of blocks inside).
"""

from __future__ import annotations

from rich.text import Text
from textual.app import ComposeResult
from textual.containers import Horizontal, Vertical
from textual.widgets import DataTable, Label, ProgressBar, Static

from gcs_tui import format as fmt
from gcs_tui import jobs
from gcs_tui.keys import SCREENS, bindings
from gcs_tui.messages import FiltrBlock
from gcs_tui.screens.base import GcsScreen
from gcs_tui.theme import rgb
from gcs_tui.widgets.plots import GcsPlot

EMPTY = "FILTR not started — n processes one block, r runs to the end, x cancels, z resets."


class FiltrScreen(GcsScreen):
    """Block-by-block estimation with live state and NIS."""

    VIEW = "filtr"
    CSS_PATH = "filtr.tcss"
    BINDINGS = bindings(SCREENS["filtr"])

    def compose_body(self) -> ComposeResult:
        yield Static("", id="filtr-info", markup=False)
        yield ProgressBar(id="filtr-progress", show_eta=False)
        with Horizontal(id="filtr-split"):
            with Vertical(id="filtr-state-box"):
                yield Label("State and σ", classes="panel-title")
                yield DataTable(id="filtr-state", cursor_type="row", zebra_stripes=True)
            yield GcsPlot(id="filtr-nis", title="NIS per block")

    def refresh_view(self) -> None:
        run = self.wb.filtr
        info = self.query_one("#filtr-info", Static)
        bar = self.query_one("#filtr-progress", ProgressBar)
        table = self.query_one("#filtr-state", DataTable)
        plot = self.query_one("#filtr-nis", GcsPlot)
        if run is None or not run.reports:
            info.update(EMPTY if jobs.available("gcs_core.filtr.stepping", "Filtr")
                        else "FILTR stepping is not available in this installation (gcs_core.filtr.stepping).")
            bar.update(total=run.n_blocks if run else 1, progress=0)
            table.clear(columns=True)
            plot.paint(None, empty="no blocks yet")
            return
        view = run.view()
        bar.update(total=view.n_blocks, progress=view.done)
        info.update(Text.assemble(
            (f" block {view.done}/{view.n_blocks}", "bold"), f" · t {fmt.span(view.t0, view.t1)}",
            f" · NIS {fmt.sig(view.nis[-1], 3)} on {view.dof[-1]} dof" if view.nis else "",
            f" · {view.inside}/{len(view.nis)} blocks inside the 95 % band" if view.nis else "",
            " · finished" if view.finished else ""))
        table.clear(columns=True)
        table.add_column("element")
        table.add_column(Text("estimate ± σ", justify="right"))
        for name, (value, sigma, unit) in view.state.items():
            table.add_row(name, Text(fmt.estimate(value, sigma, unit), justify="right"), key=name)
        plot.paint(lambda plt: self._nis(plt, view))

    @staticmethod
    def _nis(plt, view) -> None:
        x = list(range(1, len(view.nis) + 1))
        lo = [b[0] for b in view.band]
        hi = [b[1] for b in view.band]
        plt.plot(x, hi, color=rgb("gcs-band"), label="χ² 97.5 %")
        plt.plot(x, lo, color=rgb("gcs-band"), label="χ² 2.5 %")
        plt.scatter(x, list(view.nis), color=rgb("gcs-used"), marker="dot", label="NIS")
        plt.title("NIS per block (χ² band)")
        plt.xlabel("block")

    # ------------------------------------------------------------------ actions
    def _run(self, blocks: int | None) -> None:
        label = "FILTR step" if blocks == 1 else "FILTR run"
        self.app.run_job("filtr", label, lambda p, c: jobs.filtr_advance(
            self.wb, blocks, p, c, on_block=lambda rep: self.app.post_message(FiltrBlock(rep))))

    def action_step_block(self) -> None:
        self._run(1)

    def action_run_to_end(self) -> None:
        self._run(None)

    def action_reset(self) -> None:
        if self.app.busy:
            self.app.notify("cancel the running job first (x)", severity="warning")
            return
        self.wb.filtr = None
        self.app.changed()
