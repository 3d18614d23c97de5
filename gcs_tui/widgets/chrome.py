"""The frame around every screen: the navigation bar on top and the status line below.

Both are drawn from plain data (the current view, the app's job state); neither knows
about the engine.
"""

from __future__ import annotations

from dataclasses import dataclass

from rich.text import Text
from textual.app import ComposeResult
from textual.containers import Horizontal
from textual.reactive import reactive
from textual.widget import Widget
from textual.widgets import ProgressBar, Static

from gcs_tui.keys import VIEWS


class NavBar(Widget):
    """One line: every screen with its key, the current one highlighted.

    Wide terminals get full titles, narrow ones the short titles; a click switches.
    """

    current: reactive[str] = reactive("mission")
    """Mode id of the screen this bar sits on."""

    def __init__(self, current: str, **kw) -> None:
        super().__init__(**kw)
        self.set_reactive(NavBar.current, current)

    def render(self) -> Text:
        width = self.size.width or 80
        long = sum(len(t) + len(k) + 3 for _, k, t, _ in VIEWS) + 5 <= width
        out = Text(" GCS ", style="bold reverse")
        for mode, key, title, short in VIEWS:
            label = title if long else short
            out.append(" ")
            seg = Text.assemble((key, "bold"), " ", label)
            if mode == self.current:
                seg.stylize("bold reverse")
            out.append_text(seg)
            out.append(" ")
        out.truncate(width)
        return out

    def on_click(self, event) -> None:
        x = event.x - 5
        pos = 0
        width = self.size.width or 80
        long = sum(len(t) + len(k) + 3 for _, k, t, _ in VIEWS) + 5 <= width
        for mode, key, title, short in VIEWS:
            n = len(key) + len(title if long else short) + 3
            if pos <= x < pos + n:
                self.app.action_view(mode)
                return
            pos += n


@dataclass(frozen=True)
class JobState:
    """What the status line shows about background work."""

    label: str = ""
    done: float = 0.0
    total: float | None = None
    text: str = ""

    @property
    def busy(self) -> bool:
        return bool(self.label)


class StatusBar(Horizontal):
    """Mission, fit status and the running job with its progress bar."""

    def compose(self) -> ComposeResult:
        yield Static("", id="status-text", markup=False)
        yield ProgressBar(id="status-progress", show_eta=False, show_percentage=True)

    def show(self, text: str, job: JobState) -> None:
        """Update the line: ``text`` on the left, ``job`` on the right when busy."""
        line = f"{job.label}: {job.text}" if job.busy and job.text else (job.label or text)
        self.query_one("#status-text", Static).update(Text(line))
        self.set_class(job.busy, "-busy")
        bar = self.query_one("#status-progress", ProgressBar)
        if job.busy:
            bar.update(total=job.total, progress=job.done)
