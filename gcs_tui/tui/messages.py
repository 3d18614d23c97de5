"""Every message the GCS TUI posts, as dataclasses with one-line docstrings.

Engine work runs in thread workers (:meth:`gcs_tui.tui.app.GcsApp.run_job`); the worker
talks to the UI only through these messages, which Textual delivers on the UI thread.
High-rate progress replaces an unhandled earlier message of the same job
(``can_replace``), so a fast engine never floods the queue.
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import Any

from textual.message import Message


@dataclass
class JobStarted(Message):
    """A background job began (``label`` is what the status line shows)."""

    job: str
    label: str


@dataclass
class JobProgress(Message):
    """A background job advanced to ``done`` of ``total`` (total None: unknown)."""

    job: str
    done: float
    total: float | None
    text: str = ""

    def can_replace(self, message: Message) -> bool:
        return isinstance(message, JobProgress) and message.job == self.job


@dataclass
class JobFinished(Message):
    """A background job ended: ``ok``, failed (``error`` set) or was cancelled."""

    job: str
    label: str
    ok: bool
    cancelled: bool = False
    error: str = ""
    result: Any = None


@dataclass
class FiltrBlock(Message):
    """FILTR finished one block; ``report`` is the engine's BlockReport."""

    report: Any

    def can_replace(self, message: Message) -> bool:
        # the screen redraws from the workbench: only the latest block matters
        return isinstance(message, FiltrBlock)


@dataclass
class EngineLog(Message):
    """The engine logged a warning or error (from any thread); ``text`` is the whole message."""

    level: str
    text: str
