"""The TUI's logging: engine warnings shown in the app, and no handler writing to the
terminal behind it while it runs (:mod:`gcs_tui.tui.app`)."""

from __future__ import annotations

import logging
from collections.abc import Iterator
from contextlib import contextmanager
from typing import TYPE_CHECKING

from gcs_tui.tui.messages import EngineLog

if TYPE_CHECKING:
    from gcs_tui.tui.app import GcsApp

#: loggers whose warnings the app shows (and whose CLI handlers it detaches while it runs)
LOGGERS = ("gcs", "gcs_core", "gcs_tui", "py.warnings")


class AppLogHandler(logging.Handler):
    """Engine warnings into the app (from any thread): each becomes an :class:`EngineLog`."""

    def __init__(self, app: GcsApp) -> None:
        super().__init__(logging.WARNING)
        self.app = app

    def emit(self, record: logging.LogRecord) -> None:
        try:
            self.app.post_message(EngineLog(record.levelname.lower(), record.getMessage()))
        except Exception:  # noqa: BLE001 — logging must never raise into the engine
            self.handleError(record)


@contextmanager
def detached_terminal_logging() -> Iterator[None]:
    """While the TUI runs, no log handler may write to the terminal behind it: detach every
    handler of the GCS loggers (the CLI's stderr line printer among them) and the root
    logger's stream handlers, and send Python warnings to logging; restore them after."""
    import warnings

    saved = []
    for name in LOGGERS + ("",):
        lg = logging.getLogger(name)
        for h in list(lg.handlers):
            if name or isinstance(h, logging.StreamHandler):
                lg.removeHandler(h)
                saved.append((lg, h))
    for name in LOGGERS:  # warnings still reach the app's own handler
        lg = logging.getLogger(name)
        if lg.level > logging.WARNING or lg.level == logging.NOTSET:
            lg.setLevel(logging.WARNING)
    captured = logging.captureWarnings
    captured(True)
    try:
        with warnings.catch_warnings():
            warnings.simplefilter("default")
            yield
    finally:
        captured(False)
        for lg, h in saved:
            lg.addHandler(h)
