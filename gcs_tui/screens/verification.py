"""Verification (VERIF): onboard against ground attitude — differences per axis over
time, σ per axis against the requirement, the trend and the pass/fail flag.

``r`` runs the comparison (fitting first when there is no fit).
"""

from __future__ import annotations

import math

import numpy as np
from rich.text import Text
from textual.app import ComposeResult
from textual.widgets import DataTable, Static

from gcs_tui import format as fmt
from gcs_tui.keys import SCREENS, bindings
from gcs_tui.screens.base import GcsScreen
from gcs_tui.theme import color, rgb, series
from gcs_tui.widgets.plots import GcsPlot

EMPTY = "No verification yet — press r to compare the onboard attitude with the ground solution."
AXES = ("roll", "pitch", "yaw")


class VerificationScreen(GcsScreen):
    """Onboard − ground differences, per-axis σ against the requirement, the flag."""

    VIEW = "verification"
    CSS_PATH = "verification.tcss"
    BINDINGS = bindings(SCREENS["verification"])

    def compose_body(self) -> ComposeResult:
        yield Static("", id="verif-flag", markup=False)
        yield GcsPlot(id="verif-plot", title="onboard − ground")
        yield DataTable(id="verif-table", cursor_type="row", zebra_stripes=True, show_cursor=False)

    def refresh_view(self) -> None:
        v = self.wb.verification
        flag = self.query_one("#verif-flag", Static)
        plot = self.query_one("#verif-plot", GcsPlot)
        table = self.query_one("#verif-table", DataTable)
        table.clear(columns=True)
        if v is None:
            flag.update(EMPTY)
            plot.paint(None, empty="no verification")
            return
        view = verif_view(v, self.wb.config.requirement_deg)
        ok = view["flag"]
        flag.update(Text.assemble(
            (" PASS " if ok else " FAIL ", f"bold reverse {color('gcs-ok' if ok else 'gcs-bad')}"),
            f"  requirement {fmt.quantity(view['requirement'], 'rad', digits=3, shown='deg')} (1σ per axis)"
            f"  ·  {view['n']} onboard samples" + (f"  ·  {view['message']}" if view["message"] else "")))
        plot.paint(lambda plt: self._plot(plt, view))
        table.add_column("axis")
        table.add_column(Text("mean", justify="right"))
        table.add_column(Text("σ", justify="right"))
        table.add_column(Text("requirement", justify="right"))
        table.add_column(Text("trend", justify="right"))
        table.add_column("")
        for k, axis in enumerate(view["axes"]):
            s = view["sigma"][k]
            good = s <= view["requirement"]
            table.add_row(axis, Text(fmt.quantity(view["mean"][k], "rad", digits=2, shown="arcsec"), justify="right"),
                          Text(fmt.quantity(s, "rad", digits=2, shown="arcsec"), justify="right"),
                          Text(fmt.quantity(view["requirement"], "rad", digits=2, shown="arcsec"), justify="right"),
                          Text(view["trend"][k], justify="right"),
                          Text("ok" if good else "over", style=color("gcs-ok" if good else "gcs-bad")))

    @staticmethod
    def _plot(plt, view) -> None:
        t = view["t"]
        d = view["diff"]
        if t.size:
            for k, axis in enumerate(view["axes"]):
                y = d[:, k] * fmt.to_display(1.0, "rad", "arcsec")
                plt.plot(t.tolist(), y.tolist(), color=series(k), label=axis)
            req = fmt.to_display(view["requirement"], "rad", "arcsec")
            plt.horizontal_line(req, color=rgb("gcs-bad"))
            plt.horizontal_line(-req, color=rgb("gcs-bad"))
        plt.title("onboard − ground attitude [arcsec]  (red: ± requirement)")
        plt.xlabel("t [s]")


def verif_view(v, requirement_deg: float) -> dict:
    """The fields this screen draws, from a VERIF result."""
    t = np.asarray(getattr(v, "t", getattr(v, "times", np.zeros(0))), dtype=float)
    diff = np.asarray(getattr(v, "diff", getattr(v, "differences", np.zeros((0, 3)))), dtype=float)
    sigma = np.asarray(getattr(v, "sigma", np.full(3, math.nan)), dtype=float)
    mean = np.asarray(getattr(v, "mean", np.nanmean(diff, axis=0) if diff.size else np.full(3, math.nan)))
    req = float(getattr(v, "requirement", requirement_deg * math.pi / 180.0))
    trend = getattr(v, "trend", None)
    trend_s = [fmt.sig(x, 2) if isinstance(x, (int, float)) else str(x) for x in
               (trend if isinstance(trend, (list, tuple, np.ndarray)) else [trend] * 3)]
    return {"t": t, "diff": diff, "sigma": sigma, "mean": mean, "requirement": req,
            "axes": tuple(getattr(v, "axes", AXES)), "trend": trend_s, "flag": bool(getattr(v, "flag", False)),
            "n": int(t.size), "message": str(getattr(v, "message", ""))}
