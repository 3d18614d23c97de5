"""FILTR: the Kalman filter block by block (seed §3.2.2, Eq 3-3/3-4) — step one block,
run to the end, cancel between blocks — with a progress bar, the live state and σ,
each sensor's innovations in the latest block, and the NIS of every block against its
95 % χ² band (normalized by its degrees of freedom, so the band sits around 1).
"""

from __future__ import annotations

from rich.text import Text
from textual.app import ComposeResult
from textual.containers import Horizontal, Vertical
from textual.widgets import DataTable, Label, ProgressBar, Static

from gcs_core import display as fmt
from gcs_tui.tui import filtr_run
from gcs_tui.tui.keys import SCREENS, bindings
from gcs_tui.tui.messages import FiltrBlock
from gcs_tui.tui.screens.base import GcsScreen
from gcs_tui.tui.theme import color, marker, rgb, series
from gcs_tui.tui.widgets.plots import GcsPlot, nice_y

EMPTY = "FILTR not started — n processes one block, r runs to the end, x cancels, z resets."


class FiltrScreen(GcsScreen):
    """Block-by-block estimation with live state, innovations and NIS."""

    VIEW = "filtr"
    CSS_PATH = "filtr.tcss"
    BINDINGS = bindings(SCREENS["filtr"])

    def compose_body(self) -> ComposeResult:
        yield Static("", id="filtr-info", markup=False)
        yield ProgressBar(id="filtr-progress", show_eta=False)
        with Horizontal(id="filtr-split"):
            with Vertical(id="filtr-state-box"):
                yield Label("State and σ after the block", classes="panel-title")
                yield DataTable(id="filtr-state", cursor_type="row", zebra_stripes=True)
            with Vertical(id="filtr-right"):
                yield GcsPlot(id="filtr-nis", title="NIS per block")
                yield DataTable(id="filtr-sensors", cursor_type="row", zebra_stripes=True, show_cursor=False)

    def refresh_view(self) -> None:
        run = self.wb.filtr
        info = self.query_one("#filtr-info", Static)
        bar = self.query_one("#filtr-progress", ProgressBar)
        state = self.query_one("#filtr-state", DataTable)
        sensors = self.query_one("#filtr-sensors", DataTable)
        plot = self.query_one("#filtr-nis", GcsPlot)
        state.clear(columns=True)
        sensors.clear(columns=True)
        if run is None or not run.reports:
            info.update(self.app.job_errors.get("filtr", EMPTY))
            bar.update(total=1, progress=0)
            plot.paint(None, empty="no blocks yet")
            return
        v = run.view()
        bar.update(total=v.done if v.finished else v.total, progress=v.done)
        last = v.blocks[-1]
        inside = f" · {v.inside}/{len(v.blocks)} blocks inside the band"
        if v.finished:
            post = ", ".join(f"{n} {fmt.fixed(x, 3)}" for n, x in v.post_fit.items())
            info.update(
                Text.assemble(
                    (" finished ", f"bold reverse {color('gcs-ok')}"),
                    f" {v.status}{inside}",
                    f" · post-fit normalized RMS: {post}",
                )
            )
        else:
            info.update(
                Text.assemble(
                    (f" pass {v.pass_index + 1}/{v.n_passes} · block {v.block}/{v.n_blocks}", "bold"),
                    f" · t {fmt.span(v.t0, v.t1)} · NIS/dof {fmt.fixed(last[2], 3)}"
                    f" (band {fmt.fixed(last[3], 3)}–{fmt.fixed(last[4], 3)}){inside}",
                )
            )
        state.add_column("element")
        state.add_column(Text("estimate ± σ", justify="right"))
        for name, (x, s, unit) in v.state.items():
            state.add_row(name, Text(fmt.estimate(x, s, unit), justify="right"), key=name)
        sensors.add_column("sensor")
        sensors.add_column(Text("used", justify="right"))
        sensors.add_column(Text("gated", justify="right"))
        sensors.add_column(Text("NIS/dof", justify="right"))
        sensors.add_column(Text("p", justify="right"))
        for name, (used, gated, z, p) in v.sensors.items():
            sensors.add_row(
                name,
                Text(str(used), justify="right"),
                Text(str(gated), justify="right", style=color("gcs-edited") if gated else ""),
                Text(fmt.fixed(z, 3), justify="right"),
                Text(fmt.pvalue(p), justify="right"),
            )
        plot.paint(lambda plt: self._nis(plt, v))

    @staticmethod
    def _nis(plt, v) -> None:
        for p in range(v.pass_index + 1):
            rows = [b for b in v.blocks if b[0] == p]
            x = [b[1] + 1 for b in rows]
            plt.plot(x, [b[2] for b in rows], color=series(p), marker="braille")
            plt.scatter(x, [b[2] for b in rows], color=series(p), marker=marker(p))
        rows = [b for b in v.blocks if b[0] == v.pass_index]
        x = [b[1] + 1 for b in rows]
        plt.plot(x, [b[3] for b in rows], color=rgb("gcs-band"), marker="braille")
        plt.plot(x, [b[4] for b in rows], color=rgb("gcs-band"), marker="braille")
        vals = [b[k] for b in v.blocks for k in (2, 3, 4) if b[k] == b[k]]
        if vals:
            nice_y(plt, min(vals), max(vals), 4)
        plt.xlim(0.5, v.n_blocks + 0.5)
        every = max(1, -(-v.n_blocks // 8))
        ticks = list(range(1, v.n_blocks + 1, every))
        plt.xticks(ticks, [str(k) for k in ticks])
        passes = " ".join(f"{marker(p)} pass {p + 1}" for p in range(v.pass_index + 1))
        plt.title(f"NIS/dof per block · {passes} · ⠒ 95 % χ² band")
        plt.xlabel("block")

    # ------------------------------------------------------------------ actions
    def _run(self, blocks: int | None) -> None:
        label = "FILTR step" if blocks == 1 else "FILTR run"
        post = self.app.post_message
        self.app.run_job(
            "filtr",
            label,
            lambda p, c: filtr_run.advance(self.wb, blocks, p, c, on_block=lambda rep: post(FiltrBlock(rep))),
        )

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
