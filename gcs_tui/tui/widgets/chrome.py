"""The frame around every screen: the navigation bar on top and the status line below.

Both are drawn from plain data (the current view, the app's job state); neither knows
about the engine.
"""

from __future__ import annotations

import time
from dataclasses import dataclass
from typing import TYPE_CHECKING

from rich.text import Text
from textual import getters
from textual.app import ComposeResult
from textual.containers import Horizontal
from textual.reactive import reactive
from textual.widget import Widget
from textual.widgets import ProgressBar, Static

from gcs_tui.tui.keys import VIEWS

if TYPE_CHECKING:
    from gcs_tui.tui.app import GcsApp


class NavBar(Widget):
    """One line: every screen with its key, the current one highlighted.

    Three densities, the first that fits: full titles, short titles, or only the keys
    with the current screen's title. A click on an entry switches to it.
    """

    if TYPE_CHECKING:  # for the type checker: the running app is a GcsApp
        app = getters.app(GcsApp)

    current: reactive[str] = reactive("mission")
    """Mode id of the screen this bar sits on."""

    def __init__(self, current: str, **kw) -> None:
        super().__init__(**kw)
        self.set_reactive(NavBar.current, current)

    def _layout(self, width: int) -> tuple[bool, int, list[tuple[str, str]]]:
        """``(GCS badge shown, padding each side, [(mode, label)])``: the roomiest form that
        fits ``width`` — full titles, short titles, short titles packed without the badge
        (80 columns), and only as a last resort keys with the current screen's title."""
        full = [(mode, f"{key} {title}") for mode, key, title, _ in VIEWS]
        short = [(mode, f"{key} {s}") for mode, key, _, s in VIEWS]
        for badge, pad, entries in ((True, 1, full), (True, 1, short), (False, 0, short)):
            used = (5 if badge else 0) + sum(len(label) + 2 * pad + (0 if pad else 1) for _, label in entries)
            if used <= width:
                return badge, pad, entries
        return True, 1, [(mode, f"{key} {title}" if mode == self.current else key) for mode, key, title, _ in VIEWS]

    def _spans(self, width: int) -> list[tuple[str, str, int]]:
        """``(mode, label, first column)`` of every entry."""
        badge, pad, entries = self._layout(width)
        pos, out = (5 if badge else 0), []
        for mode, label in entries:
            out.append((mode, label, pos + pad))
            pos += len(label) + 2 * pad + (0 if pad else 1)
        return out

    def render(self) -> Text:
        width = self.size.width or 80
        badge, _, _ = self._layout(width)
        out = Text()
        if badge:
            out.append(" GCS ", style="bold reverse")
        for mode, label, col in self._spans(width):
            out.append(" " * (col - len(out.plain)))
            out.append(label, style="bold reverse" if mode == self.current else "")
        out.truncate(width)
        return out

    def on_click(self, event) -> None:
        for mode, label, col in self._spans(self.size.width or 80):
            if col - 1 <= event.x <= col + len(label):
                self.app.action_view(mode)
                return


@dataclass(frozen=True)
class JobState:
    """What the status line shows about background work."""

    label: str = ""
    done: float = 0.0
    total: float | None = None
    text: str = ""
    started: float | None = None
    """``time.monotonic()`` when the job started (None: not timed)."""

    @property
    def busy(self) -> bool:
        return bool(self.label)

    @property
    def elapsed(self) -> str:
        """``12 s`` since the job started ('' when not timed)."""
        if self.started is None:
            return ""
        return f"{time.monotonic() - self.started:.0f} s"

    def line(self) -> str:
        """``label · 12 s · stage`` (the status line while the job runs; the time first, so
        that a narrow terminal cuts the stage, not the clock)."""
        stage = self.text if self.text != self.label else ""
        return " · ".join(p for p in (self.label, self.elapsed, stage) if p)


class StatusBar(Horizontal):
    """Mission, fit status and the running job with its progress bar."""

    def compose(self) -> ComposeResult:
        yield Static("", id="status-text", markup=False)
        yield ProgressBar(id="status-progress", show_eta=False, show_percentage=True)

    def show(self, text: str, job: JobState) -> None:
        """Update the line: ``text`` on the left, ``job`` on the right when busy."""
        line = job.line() if job.busy else text
        self.query_one("#status-text", Static).update(Text(line))
        self.set_class(job.busy, "-busy")
        bar = self.query_one("#status-progress", ProgressBar)
        if job.busy:
            bar.update(total=job.total, progress=job.done)
