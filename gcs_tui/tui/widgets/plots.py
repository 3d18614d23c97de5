"""A plotext plot that repaints itself from a stored painter at every render.

Screens hand :meth:`GcsPlot.paint` a function ``painter(plt)`` that draws with the
plotext API; the widget clears the figure, calls it and builds the text at the
widget's current size, so a resize redraws the same data at the new resolution.

A plot never brings the app down: a plot that is hidden (``display: none``) or smaller
than :data:`MIN_WIDTH` × :data:`MIN_HEIGHT` is not built, and an error while painting or
building (plotext fails on some tiny or degenerate data) is logged with its traceback and
shown as one line in the plot's frame. The title (which carries the legend) is drawn
above the plot, wrapped to its width.
"""

from __future__ import annotations

import logging
import textwrap
from collections.abc import Callable
from typing import Any

from rich.text import Text
from textual_plotext import PlotextPlot

log = logging.getLogger(__name__)

Painter = Callable[[object], None]

#: below this many columns or rows a plot is not drawn (axes and title leave no room for data)
MIN_WIDTH, MIN_HEIGHT = 16, 5


class GcsPlot(PlotextPlot):
    """A :class:`textual_plotext.PlotextPlot` driven by a painter function."""

    def __init__(self, *, title: str = "", **kw) -> None:
        super().__init__(**kw)
        self._painter: Painter | None = None
        self._empty_title = title

    def paint(self, painter: Painter | None, *, empty: str = "") -> None:
        """Draw with ``painter`` from now on (None: an empty frame titled ``empty``)."""
        self._painter = painter
        if empty:
            self._empty_title = empty
        self.refresh()

    def render(self):
        # hidden (``display: none``): not built. A plot inside a hidden parent has no size,
        # which the size check below catches; its own flag is the one to ask, as a parent's
        # may still read hidden at the first render after it is shown (nothing would redraw).
        if not self.display:
            return Text("")
        w, h = self.size.width, self.size.height
        if w < MIN_WIDTH or h < MIN_HEIGHT:
            return Text(self._empty_title[: max(w, 0)] if h else "", no_wrap=True, overflow="ellipsis")
        plt = self.plt
        try:
            plt.clear_figure()
            if self._painter is not None:
                self._painter(plt)
            else:
                plt.title(self._empty_title)
                plt.xticks([])
                plt.yticks([])
            return self._build(w, h)
        except Exception as err:
            log.debug("plot %s not drawn", self.id, exc_info=True)
            return Text(f"plot not drawn ({type(err).__name__}: {err})", no_wrap=True, overflow="ellipsis")

    def _build(self, w: int, h: int) -> Text:
        """The plot with its title (and the legend it carries) above it, wrapped to the
        width on at most :data:`TITLE_LINES` lines: plotext drops a title that does not fit
        on one line, which at 80×24 was every title and every legend."""
        fig: Any = self._plot  # plotext's figure (its monitor holds the title)
        monitor = fig.monitor
        title = monitor.title or ""
        monitor.title = None
        lines = textwrap.wrap(title, w, break_on_hyphens=False)[:TITLE_LINES] if title else []
        if lines and len(textwrap.wrap(title, w, break_on_hyphens=False)) > TITLE_LINES:
            lines[-1] = lines[-1][: max(w - 1, 0)] + "…"
        rows = max(h - len(lines), 1)
        fig.plotsize(w, rows)
        fig._set_size(w, rows)  # as textual_plotext's render does (its issue 5)
        fig.theme(self._get_plotext_theme_name(self.app.theme))
        body = Text.from_ansi(fig.build())
        if not lines:
            return body
        head = Text("\n".join(lines), style="bold", no_wrap=True)
        return Text("\n").join([head, body])


#: a plot's title and legend take at most this many lines above it
TITLE_LINES = 2


def nice_y(plt, lo: float, hi: float, n: int = 5) -> None:
    """Round y ticks (1, 2, 2.5, 5 × 10^k) over [lo, hi], a little margin around the data."""
    from gcs_core import display as fmt

    if not (lo < hi):
        return
    pad = 0.05 * (hi - lo)
    lo, hi = lo - pad, hi + pad
    ticks = fmt.nice_ticks(lo, hi, n)
    plt.ylim(lo, hi)
    if len(ticks) >= 2:
        plt.yticks(ticks, fmt.tick_labels(ticks))


def nice_x(plt, lo: float, hi: float, n: int = 6) -> None:
    """Round x ticks over [lo, hi] (see :func:`nice_y`)."""
    from gcs_core import display as fmt

    if not (lo < hi):
        return
    ticks = fmt.nice_ticks(lo, hi, n)
    if len(ticks) >= 2:
        plt.xticks(ticks, fmt.tick_labels(ticks))


def marked_line(plt, x, y, colour, mark: str, *, marks: int = 12, line: bool = True) -> None:
    """A series drawn thin (braille) with its marker at about ``marks`` evenly spaced points,
    so that series differ by shape as well as colour without the markers hiding the data."""
    x, y = list(x), list(y)
    if line:
        plt.plot(x, y, color=colour, marker="braille")
    else:
        plt.scatter(x, y, color=colour, marker="braille")
    if x:
        step = max(1, len(x) // marks)
        plt.scatter(x[step // 2 :: step], y[step // 2 :: step], color=colour, marker=mark)
