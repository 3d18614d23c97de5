"""What every GCS screen shares: the frame, the empty state and when to redraw.

A screen is a view of the app's :class:`~gcs_tui.tui.workbench.Workbench`. It redraws
(:meth:`GcsScreen.refresh_view`) when it becomes visible and the workbench changed
since it last drew (the app counts changes in ``generation``), or when the app tells
the visible screen that something changed.
"""

from __future__ import annotations

from typing import TYPE_CHECKING, ClassVar

from textual import getters
from textual.app import ComposeResult
from textual.containers import Container
from textual.css.query import NoMatches
from textual.screen import Screen
from textual.widgets import Footer, Static

from gcs_tui.tui.widgets.chrome import NavBar, StatusBar

if TYPE_CHECKING:
    from gcs_tui.tui.app import GcsApp

EMPTY_NOTE = "No mission open — press o to open a mission directory or an analysis config (.toml)."


class GcsScreen(Screen):
    """Base of the ten views: navigation bar, body, status line, footer."""

    VIEW: ClassVar[str] = ""
    """Mode id (see :data:`gcs_tui.tui.keys.VIEWS`)."""

    NEEDS_FIT: ClassVar[bool] = False
    """True when the view shows fit results (it says so until there is a fit)."""

    AUTO_JOB: ClassVar[str] = ""
    """App action run when the screen is shown and :meth:`needs_job` says its result is missing."""

    def __init__(self) -> None:
        super().__init__()
        self._drawn = -1

    if TYPE_CHECKING:  # for the type checker: the running app is a GcsApp
        app = getters.app(GcsApp)

    # ------------------------------------------------------------------ frame
    def compose(self) -> ComposeResult:
        yield NavBar(self.VIEW)
        with Container(id="body"):
            yield Static(EMPTY_NOTE, id="empty", classes="empty-note")
            with Container(id="content"):
                yield from self.compose_body()
        yield StatusBar()
        yield Footer(compact=True)

    def compose_body(self) -> ComposeResult:
        """The screen's own widgets."""
        yield from ()

    @property
    def wb(self):
        return self.app.workbench

    # ------------------------------------------------------------------ redraw
    def on_mount(self) -> None:
        self.update_view(force=True)

    def on_screen_resume(self) -> None:
        self.update_view()
        self.maybe_start_job()

    def needs_job(self) -> bool:
        """True when the view's own result (prediction, verification) is missing."""
        return False

    def maybe_start_job(self) -> None:
        """Start :attr:`AUTO_JOB` once, when the view is shown without its result."""
        wb = self.wb
        if not self.AUTO_JOB or wb is None or not wb.ready or self.app.busy:
            return
        if self.NEEDS_FIT and wb.result is None:
            return
        if self.needs_job() and getattr(self, "_auto_for", None) is not wb.analysis:
            self._auto_for = wb.analysis  # once per analysis: a failure is not retried
            getattr(self.app, f"action_{self.AUTO_JOB}")()

    def update_view(self, *, force: bool = False) -> None:
        """Redraw if the workbench changed since the last drawing (or ``force``)."""
        try:
            self.update_status()
            empty = self.query_one("#empty", Static)
            content = self.query_one("#content", Container)
        except NoMatches:
            return
        ready = self.wb is not None and self.wb.ready
        if ready and self.NEEDS_FIT and self.wb.result is None:
            empty.update("No fit yet — press f to fit the current configuration.")
            ready_for_view = False
        else:
            empty.update(EMPTY_NOTE)
            ready_for_view = ready
        empty.display = not ready_for_view
        content.display = ready_for_view
        gen = self.app.generation
        if not ready_for_view or (not force and gen == self._drawn):
            return
        self._drawn = gen
        self.refresh_view()

    def refresh_view(self) -> None:
        """Draw everything from the workbench (called on the UI thread)."""

    def update_status(self) -> None:
        try:
            bar = self.query_one(StatusBar)
        except NoMatches:
            return
        bar.show(self.app.status_text(), self.app.job)

    @property
    def compact(self) -> bool:
        """True at narrow sizes (< 120 columns; the app's ``-compact`` breakpoint)."""
        return self.app.size.width < 120

    def on_resize(self, event) -> None:
        # views whose columns depend on the width redraw when the breakpoint is crossed
        if getattr(self, "_drawn_compact", None) not in (None, self.compact):
            self.update_view(force=True)
        self._drawn_compact = self.compact
