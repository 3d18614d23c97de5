"""Progress of the headless commands: a live line on a terminal, plain log lines elsewhere.

Long runs (fits, discovery, prediction) report through one :class:`Progress`. Each piece
of work is a :meth:`Progress.task`:

* on a terminal (stderr is a TTY, ``TERM`` is not ``dumb``) a rich progress line shows a
  spinner, the task, a bar (pulsing while the length of the run is unknown), ``done/total``
  and the elapsed time; when the task ends the line becomes ``✓ task  2.1 s``. Messages and
  log records print above the live line without breaking it;
* elsewhere (CI logs, pipes, files) every task and message is one line ``gcs: ...`` and
  nothing is redrawn; the run ends with ``gcs: finished in 5.3 s``;
* ``mode="off"`` (``gcs -q``) prints nothing but warnings and errors.

Results go to stdout and are printed between tasks, never while a live line is drawn, so
``gcs batch M > out.txt`` keeps the file clean and the terminal tidy.

The callbacks take the engine's shapes: ``progress.message(text)`` is the message callback
of :meth:`gcs_core.session.Analysis.discover`, and a task handle is a ``(done, total, text)``
callback as the TUI's jobs (:mod:`gcs_tui.tui.jobs`) take.
"""

from __future__ import annotations

import logging
import os
import sys
import time
from collections.abc import Iterator
from contextlib import contextmanager
from typing import IO, Any

from gcs_core.textsafe import terminal_safe

MODES = ("auto", "bar", "plain", "off")


class Task:
    """Handle of one running task: ``task(done, total, text)`` updates it."""

    def __init__(self, owner: Progress, task_id, text: str):
        self._owner, self._id, self.text, self.last = owner, task_id, terminal_safe(text, one_line=True), ""

    def __call__(self, done: float | None = None, total: float | None = None, text: str = "") -> None:
        self._owner._update(self, done, total, text)


class Progress:
    """Progress display of one ``gcs`` run (module docstring).

    Parameters
    ----------
    stream : where progress goes (default: ``sys.stderr`` at construction).
    mode : ``auto`` (bar on a terminal, plain otherwise), ``bar``, ``plain`` or ``off``.
    console : a rich Console to draw on (tests pass one with ``force_terminal``).
    """

    def __init__(self, stream: IO[str] | None = None, *, mode: str = "auto", console=None):
        if mode not in MODES:
            raise ValueError(f"mode must be one of {', '.join(MODES)}")
        self.stream = stream if stream is not None else sys.stderr
        self._console = console
        if mode == "auto":
            mode = "bar" if (console is not None or _is_terminal(self.stream)) else "plain"
        self.mode = mode
        self._live: Any = None  # rich.progress.Progress while a task runs (bar mode)
        self._t0 = time.monotonic()

    # ------------------------------------------------------------------ output
    def echo(self, line: str) -> None:
        """One line of progress or log output (above the live line when there is one);
        control characters from file names and mission names are shown escaped."""
        line = terminal_safe(line)
        if self._live is not None:
            self._live.console.print(line, markup=False, highlight=False, soft_wrap=True)
        else:
            self.stream.write(line + "\n")
            self.stream.flush()

    def message(self, text: str) -> None:
        """A message worth keeping (e.g. a discovery step); also the live task's text."""
        if self.mode == "off":
            return
        self.echo(f"gcs: {text}")
        if self._live is not None and self._live.tasks:
            self._live.update(self._live.tasks[-1].id, description=_short(text))

    # ------------------------------------------------------------------ tasks
    @contextmanager
    def task(self, text: str, total: float | None = None) -> Iterator[Task]:
        """Run a piece of work under a progress line; yields its :class:`Task` handle."""
        start = time.monotonic()
        if self.mode != "bar":
            if self.mode == "plain":
                self.echo(f"gcs: {text}")
            yield Task(self, None, text)
            return
        live = self._start_live()
        task_id = live.add_task(_short(text), total=total, count=_count(0, total))
        handle = Task(self, task_id, text)
        ok = False
        try:
            yield handle
            ok = True
        finally:
            live.stop()
            self._live = None
            mark = "✓" if ok else "✗"
            from rich.markup import escape

            shown = escape(handle.text)  # a name holding "[red]" is text, not markup
            live.console.print(
                f"[green]{mark}[/] {shown} [dim]{time.monotonic() - start:.1f} s[/]"
                if ok
                else f"[red]{mark}[/] {shown}",
                highlight=False,
            )

    def _update(self, task: Task, done, total, text) -> None:
        if text and text != task.last:
            task.last = text
            if self.mode == "plain":
                self.echo(f"gcs: {task.text}: {text}")
        if self._live is None or task._id is None:
            return
        kw = {}
        if total is not None:
            kw["total"] = total
        if done is not None:
            kw["completed"] = done
        current = self._live.tasks[-1] if self._live.tasks else None
        if current is not None and (done is not None or total is not None):
            kw["count"] = _count(current.completed if done is None else done, current.total if total is None else total)
        if text:
            kw["description"] = _short(text)
        self._live.update(task._id, **kw)

    def _start_live(self):
        from rich.console import Console
        from rich.progress import BarColumn, SpinnerColumn, TextColumn, TimeElapsedColumn
        from rich.progress import Progress as RichProgress

        console = self._console or Console(file=self.stream, highlight=False)
        # "done/total" only when the total is known; the bar pulses otherwise
        count = TextColumn("{task.fields[count]}", style="progress.download")
        live = RichProgress(
            SpinnerColumn(),
            TextColumn("{task.description}"),
            BarColumn(bar_width=20),
            count,
            TimeElapsedColumn(),
            console=console,
            transient=True,
            redirect_stdout=False,
            redirect_stderr=False,
        )
        live.start()
        self._live = live
        return live

    # ------------------------------------------------------------------ end
    def finish(self) -> None:
        """The closing line of a run (plain mode): the total time."""
        if self.mode == "plain":
            self.echo(f"gcs: finished in {time.monotonic() - self._t0:.1f} s")

    def close(self) -> None:
        """Stop a live line left running (an error or interrupt inside a task)."""
        if self._live is not None:
            self._live.stop()
            self._live = None


class LogHandler(logging.Handler):
    """Log records as ``gcs: message`` lines (``gcs: warning: ...`` for warnings and worse)
    through a :class:`Progress`, so that they never tear the live line."""

    def __init__(self, progress: Progress, level: int = logging.NOTSET):
        super().__init__(level)
        self.progress = progress

    def emit(self, record: logging.LogRecord) -> None:
        try:
            text = record.getMessage()
            if record.levelno >= logging.WARNING:
                text = f"{record.levelname.lower()}: {text}"
            self.progress.echo(f"gcs: {text}")
        except Exception:  # noqa: BLE001 — logging must never raise into the run
            self.handleError(record)


def _is_terminal(stream) -> bool:
    try:
        tty = stream.isatty()
    except (AttributeError, ValueError, OSError):
        return False
    return bool(tty) and os.environ.get("TERM", "") != "dumb"


def _count(done, total) -> str:
    return "" if total is None else f"{int(done)}/{int(total)}"


def _short(text: str, width: int = 50) -> str:
    text = terminal_safe(text, one_line=True)
    return text if len(text) <= width else text[: width - 1] + "…"


_log = logging.getLogger("gcs")


def warning_line(message, category, filename, lineno, file=None, line=None) -> None:
    """A Python warning as one log line: numpy's RuntimeWarnings (an all-NaN slice, an
    overflow the code then handles) at debug level (``-v``), others as warnings."""
    if issubclass(category, RuntimeWarning):
        _log.debug("%s:%s: %s: %s", filename, lineno, category.__name__, message)
    else:
        _log.warning("%s", message)
