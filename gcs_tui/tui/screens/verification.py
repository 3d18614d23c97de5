"""Verification (VERIF, seed §4.4): onboard against ground attitude — the differences
per axis over time, the §4.4 σ per axis against the ground accuracy and the
requirement, its trend over windows, and the flag that says the onboard calibration
needs an update (σ above both thresholds on some axis).

``r`` runs the comparison; the screen runs it by itself the first time it is shown.
"""

from __future__ import annotations

import numpy as np
from rich.text import Text
from textual.app import ComposeResult
from textual.containers import Horizontal
from textual.widgets import DataTable, Static

from gcs_core import display as fmt
from gcs_core.display import common_unit
from gcs_tui.tui.keys import SCREENS, bindings
from gcs_tui.tui.screens.base import GcsScreen
from gcs_tui.tui.theme import color, marker, rgb, series
from gcs_tui.tui.widgets.plots import GcsPlot, marked_line, nice_x, nice_y

EMPTY = "No verification yet — press r to compare the onboard attitude with the ground solution."
AXES = ("roll", "pitch", "yaw")


def shown_unit(v) -> str:
    """One unit for the whole screen, from the largest σ or threshold (the display rule)."""
    return common_unit("rad", v.sigma, v.ground_accuracy, v.requirement)


class VerificationScreen(GcsScreen):
    """Onboard − ground differences, per-axis σ against thresholds, trend, the flag."""

    VIEW = "verification"
    CSS_PATH = "verification.tcss"
    BINDINGS = bindings(SCREENS["verification"])
    NEEDS_FIT = True
    AUTO_JOB = "verify"

    def compose_body(self) -> ComposeResult:
        yield Static("", id="verif-flag", markup=False)
        with Horizontal(id="verif-plots"):
            yield GcsPlot(id="verif-diff", title="onboard − ground")
            yield GcsPlot(id="verif-trend", title="σ per window")
        yield DataTable(id="verif-table", cursor_type="row", zebra_stripes=True, show_cursor=False)

    def needs_job(self) -> bool:
        return self.wb.verification is None

    def refresh_view(self) -> None:
        v = self.wb.verification
        flag = self.query_one("#verif-flag", Static)
        diff_plot = self.query_one("#verif-diff", GcsPlot)
        trend_plot = self.query_one("#verif-trend", GcsPlot)
        table = self.query_one("#verif-table", DataTable)
        table.clear(columns=True)
        if v is None:
            flag.update(self.app.job_errors.get("verify", EMPTY))
            diff_plot.paint(None, empty="no verification")
            trend_plot.paint(None, empty="no verification")
            return
        flag.update(
            Text.assemble(
                (" FLAG SET " if v.flag else " no flag ", f"bold reverse {color('gcs-bad' if v.flag else 'gcs-ok')}"),
                f" {v.n} onboard attitudes · {v.angles} angles · ",
                v.reason,
            )
        )
        u = shown_unit(v)
        diff_plot.paint(lambda plt: self._diff(plt, v, u))
        trend_plot.paint(lambda plt: self._trend(plt, v, u))
        table.add_column(Text(f"axis [{u}]"))
        table.add_column(Text("mean", justify="right"))
        table.add_column(Text("§4.4 σ (RMS)", justify="right"))
        table.add_column(Text("ground σ", justify="right"))
        table.add_column(Text("requirement", justify="right"))
        table.add_column("flag")
        for k, axis in enumerate(AXES):
            q = lambda x: Text(fmt.quantity(float(x), "rad", digits=3, shown=u, with_unit=False), justify="right")
            flagged = bool(v.flag_axes[k])
            table.add_row(
                axis,
                q(v.mean[k]),
                q(v.sigma[k]),
                q(v.ground_accuracy[k]),
                q(v.requirement[k]),
                Text("set" if flagged else "—", style=color("gcs-bad") if flagged else ""),
            )

    @staticmethod
    def _legend() -> str:
        return " ".join(f"{marker(k)} {axis}" for k, axis in enumerate(AXES))

    @staticmethod
    def _diff(plt, v, u) -> None:
        k_u = fmt.scale("rad", u)
        if v.n:
            t = v.t.tolist()
            for k in range(len(AXES)):
                marked_line(plt, t, (v.diff[:, k] * k_u).tolist(), series(k), marker(k), line=False)
            req = float(np.max(v.requirement)) * k_u
            plt.horizontal_line(req, color=rgb("gcs-bad"))
            plt.horizontal_line(-req, color=rgb("gcs-bad"))
            vals = np.concatenate([v.diff.ravel() * k_u, [req, -req]])
            nice_y(plt, float(np.nanmin(vals)), float(np.nanmax(vals)))
            nice_x(plt, float(v.t[0]), float(v.t[-1]))
        plt.title(f"onboard − ground [{u}] {VerificationScreen._legend()} ── ±req.")
        plt.xlabel("t [s]")

    @staticmethod
    def _trend(plt, v, u) -> None:
        k_u = fmt.scale("rad", u)
        if len(v.trend_t):
            t = v.trend_t.tolist()
            for k in range(len(AXES)):
                marked_line(plt, t, (v.trend_sigma[:, k] * k_u).tolist(), series(k), marker(k))
            req = float(np.max(v.requirement)) * k_u
            plt.horizontal_line(req, color=rgb("gcs-bad"))
            vals = np.concatenate([v.trend_sigma.ravel() * k_u, [req, 0.0]])
            nice_y(plt, float(np.nanmin(vals)), float(np.nanmax(vals)))
            nice_x(plt, float(v.trend_t[0]), float(v.trend_t[-1]), 4)
        plt.title(f"σ per window [{u}] {VerificationScreen._legend()}")
        plt.xlabel("t [s]")
