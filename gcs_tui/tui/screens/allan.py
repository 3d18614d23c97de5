"""Allan deviation of each sensor's telemetry, a modal plot (palette ``noise: allan deviation``).

Fed by the list of :class:`~gcs_core.noise.measured.SensorNoise` that
:func:`~gcs_core.noise.measured.mission_noise` returns: one log-log chart per sensor, a line
per component, and under it the white noise the telemetry shows against the data book's
figure and, for gyros, the angle random walk N, rate random walk K and bias instability B
read off the curve (IEEE Std 952-1997 Annex C). After a fit, a block above the charts gives
each sensor's noise correlation in its residuals (correlation time, variance inflation,
declared or measured: :mod:`gcs_core.noise.correlated`). Escape closes it.
"""

from __future__ import annotations

import math

from textual.app import ComposeResult
from textual.binding import Binding
from textual.containers import Vertical, VerticalScroll
from textual.screen import ModalScreen
from textual.widgets import Static

from gcs_tui.tui.widgets.plots import GcsPlot

#: plotext colours of the components, in order
COLOURS = ("cyan", "magenta", "yellow", "green")


def _fmt(v: float) -> str:
    return f"{v:.3g}"


def summary(r) -> str:
    """The lines under one sensor's chart (white noise, data book, gyro terms)."""
    rms = math.sqrt(sum(w * w for w in r.white) / len(r.white))
    line = math.sqrt(sum(w * w for w in r.line) / len(r.line))
    book = (
        "none"
        if r.stated is None
        else f"{_fmt(r.stated)} (spread {rms / r.stated:.2f}, line {line / r.stated:.2f} of it)"
    )
    text = [f"white noise per sample [{r.unit}]: spread {_fmt(rms)}, Allan white line {_fmt(line)}; data book {book}"]
    for c, g in zip(r.components, r.gyro):
        text.append(
            f"{c}: N {_fmt(g.arw)} rad/s^0.5{' (bound)' if g.arw_bound else ''}, "
            f"K {_fmt(g.rrw)} rad/s^1.5{' (bound)' if g.rrw_bound else ''}, "
            f"B {_fmt(g.bias_instability)} rad/s"
        )
    return "\n".join(text)


class AllanScreen(ModalScreen[None]):
    """Each sensor's overlapping Allan deviation at octave τ (module docstring)."""

    CSS_PATH = "allan.tcss"
    BINDINGS = [Binding("escape", "dismiss", "Close")]

    def __init__(self, results, title: str = "Allan deviation", correlation: list[str] | None = None) -> None:
        super().__init__()
        self.results = list(results)
        self.title_text = title
        self.correlation = list(correlation or [])  # lines of noise_correlation.lines()

    def compose(self) -> ComposeResult:
        with Vertical(id="dialog"):
            yield Static(f"{self.title_text} (overlapping, IEEE 952 Annex C) · esc closes", id="dialog-title")
            with VerticalScroll(id="allan-charts"):
                if self.correlation:
                    yield Static("\n".join(self.correlation), classes="dialog-note", markup=False)
                if not self.results:
                    yield Static("no sensor with measured values in this mission", classes="dialog-note")
                for k, r in enumerate(self.results):
                    yield GcsPlot(id=f"allan-{k}", classes="allan-plot")
                    yield Static(summary(r), classes="dialog-note", markup=False)

    def on_mount(self) -> None:
        for k, r in enumerate(self.results):
            self.query_one(f"#allan-{k}", GcsPlot).paint(self._painter(r))

    @staticmethod
    def _painter(r):
        def paint(plt):
            plt.xscale("log")
            plt.yscale("log")
            for i, (c, curve) in enumerate(zip(r.components, r.curves)):
                plt.plot(list(curve.tau), list(curve.adev), label=c, color=COLOURS[i % len(COLOURS)], marker="braille")
            plt.title(f"{r.name} ({r.type}) [{r.unit}] against τ [s]")

        return paint
