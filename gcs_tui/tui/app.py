"""The GCS analyst's terminal UI (replaces the seed study's GESS graphics terminal).

:class:`GcsApp` shows one :class:`~gcs_tui.tui.workbench.Workbench` through ten screens
(Textual *modes*, keys 1…9, 0). Everything slow — importing a mission, fitting,
adding an effect, FILTR blocks, prediction, verification — runs in a thread worker
(:meth:`GcsApp.run_job`) that reports through :mod:`gcs_tui.tui.messages`; the UI keeps
responding and ``esc`` cancels.

Entry point for the CLI: :func:`run_tui`.
"""

from __future__ import annotations

import logging
import time
from collections.abc import Callable
from dataclasses import replace
from pathlib import Path
from typing import Any

from textual import work
from textual.app import App
from textual.screen import Screen
from textual.worker import get_current_worker

from gcs_core.cancel import Cancelled, cancellable
from gcs_core.errors import GcsError
from gcs_core.fileperm import make_usual
from gcs_core.textsafe import terminal_safe
from gcs_tui.tui import jobs
from gcs_tui.tui.app_logging import LOGGERS, AppLogHandler, detached_terminal_logging
from gcs_tui.tui.commands import GcsCommands
from gcs_tui.tui.derive import poor_choice
from gcs_tui.tui.keys import APP, VIEWS, bindings
from gcs_tui.tui.messages import EngineLog, FiltrBlock, JobFinished, JobProgress, JobStarted
from gcs_tui.tui.screens.diagnosis import DiagnosisScreen
from gcs_tui.tui.screens.dialogs import ChoiceScreen, ConfirmScreen, Field, FormScreen, MessagesScreen
from gcs_tui.tui.screens.filtr import FiltrScreen
from gcs_tui.tui.screens.help import HelpScreen
from gcs_tui.tui.screens.history import HistoryScreen
from gcs_tui.tui.screens.mission import MissionScreen
from gcs_tui.tui.screens.models import ModelsScreen
from gcs_tui.tui.screens.plan import PlanScreen
from gcs_tui.tui.screens.predictor import PredictorScreen
from gcs_tui.tui.screens.residuals import ResidualsScreen
from gcs_tui.tui.screens.state import StateScreen
from gcs_tui.tui.screens.verification import VerificationScreen
from gcs_tui.tui.theme import VARIABLES
from gcs_tui.tui.widgets.chrome import JobState
from gcs_tui.tui.workbench import Workbench

log = logging.getLogger(__name__)

SCREENS_BY_VIEW: dict[str, str | Callable[[], Screen]] = {
    "mission": MissionScreen,
    "models": ModelsScreen,
    "state": StateScreen,
    "plan": PlanScreen,
    "filtr": FiltrScreen,
    "residuals": ResidualsScreen,
    "diagnosis": DiagnosisScreen,
    "predictor": PredictorScreen,
    "verification": VerificationScreen,
    "history": HistoryScreen,
}

JobFn = Callable[[Callable[..., None], Callable[[], bool]], Any]
"""``fn(progress, cancelled)``: the work of a job; ``progress(done, total, text)``."""


class GcsApp(App):
    """The GCS terminal UI.

    Parameters
    ----------
    source : a mission directory or analysis config to open on start (optional).
    workbench : an already-loaded workbench to show (tests, embedding); wins over ``source``.
    save_path : default file for ``config: save``.
    start_view : the screen shown first (a mode id of :data:`gcs_tui.tui.keys.VIEWS`).
    """

    TITLE = "GCS"
    CSS_PATH = "theme.tcss"
    BINDINGS = bindings(APP)
    COMMANDS = App.COMMANDS | {GcsCommands}
    MODES = SCREENS_BY_VIEW
    HORIZONTAL_BREAKPOINTS = [(0, "-compact"), (120, "-wide"), (150, "-xwide")]
    VERTICAL_BREAKPOINTS = [(0, "-short"), (40, "-tall")]

    def __init__(
        self,
        source: str | Path | None = None,
        *,
        workbench: Workbench | None = None,
        save_path: str | Path | None = None,
        start_view: str = "mission",
    ) -> None:
        super().__init__()
        self.source = source
        self.workbench = workbench if workbench is not None else Workbench(save_path=save_path)
        if save_path is not None:
            self.workbench.save_path = Path(save_path)
        self.start_view = start_view
        self.generation = 0
        """Counts workbench changes; a screen redraws when it differs from what it drew."""
        self.job = JobState()
        self._done: dict[str, Callable[[Any], None]] = {}
        self.last_notice = ""
        self.selected_candidate: str | None = None
        """The candidate highlighted on the Diagnosis screen (the Residuals screen draws its line)."""
        self.job_errors: dict[str, str] = {}
        """Job id -> the error of its latest failed run (views show why they are empty)."""
        self.messages: list[tuple[str, str]] = []
        """Every warning the engine logged while the app ran, ``(level, text)``, whole (palette:
        "app: messages")."""
        self._log_handler: AppLogHandler | None = None
        self.crash_line = ""
        """One line naming an unhandled error and the log holding its traceback ('' if none)."""

    def notify(
        self,
        message: str,
        *,
        title: str = "",
        severity: Any = "information",
        timeout: float | None = None,
        markup: bool = False,
    ) -> None:
        """A toast, its text made safe: messages carry paths and errors from files others wrote,
        so control and bidi characters are shown escaped (:func:`gcs_core.textsafe.terminal_safe`)
        and brackets are text, not markup (a file named ``[red]x`` is shown as it is named)."""
        super().notify(
            terminal_safe(message),
            title=terminal_safe(title, one_line=True),
            severity=severity,
            timeout=timeout,
            markup=markup,
        )

    def _handle_exception(self, error: Exception) -> None:
        """An unhandled error: its traceback to a log file, one line for the CLI, exit 4
        (:mod:`gcs_tui.tui.crash`) — never a traceback on the terminal."""
        from gcs_tui.tui import crash

        if not self.crash_line:
            self.crash_line = crash.record(error)
        self._return_code = crash.EXIT_INTERNAL
        if self._exception is None:  # Pilot re-raises it, so tests see the error
            self._exception = error
            self._exception_event.set()
        self._close_messages_no_wait()

    # ------------------------------------------------------------------ theme
    def get_theme_variable_defaults(self) -> dict[str, str]:
        return dict(VARIABLES)

    # ------------------------------------------------------------------ start
    def on_mount(self) -> None:
        self._log_handler = AppLogHandler(self)
        for name in LOGGERS:
            logging.getLogger(name).addHandler(self._log_handler)
        self.set_interval(1.0, self._tick)  # a running job's elapsed time, every second
        self.switch_mode(self.start_view)
        if self.source is not None and not self.workbench.ready:
            self.open_path(self.source)

    def on_unmount(self) -> None:
        if self._log_handler is not None:
            for name in LOGGERS:
                logging.getLogger(name).removeHandler(self._log_handler)
            self._log_handler = None

    def on_engine_log(self, message: EngineLog) -> None:
        """A warning from the engine: kept in :attr:`messages` and shown whole in a notification —
        the first time; a repeat (every refit gives the same one) only counts in the status line."""
        seen = (message.level, message.text) in self.messages
        self.messages.append((message.level, message.text))
        if seen:
            self.last_notice = f"{message.level} repeated (w shows all {len(self.messages)})"
            self._update_status()
            return
        self.notify(
            message.text,
            title=f"{message.level} (w lists every one)",
            severity="error" if message.level == "error" else "warning",
            timeout=20,
        )

    def open_path(self, path: str | Path) -> None:
        """Import a mission (directory or config) in the background."""
        self.run_job("open", f"opening {Path(path).name}", lambda progress, cancelled: self.workbench.load(path))

    # ------------------------------------------------------------------ jobs
    @property
    def busy(self) -> bool:
        return self.job.busy

    def run_job(self, job: str, label: str, fn: JobFn, *, on_done: Callable[[Any], None] | None = None) -> bool:
        """Run ``fn`` in the engine worker; False (and a notice) if a job is running."""
        if self.busy:
            self.notify(f"busy: {self.job.label} — esc cancels", severity="warning")
            return False
        self.job = JobState(label, 0.0, None, "", started=time.monotonic())
        if on_done is not None:
            self._done[job] = on_done
        self.post_message(JobStarted(job, label))
        self._engine(job, label, fn)
        return True

    @work(thread=True, exclusive=True, group="engine", exit_on_error=False)
    def _engine(self, job: str, label: str, fn: JobFn) -> None:
        worker = get_current_worker()

        def progress(done: float, total: float | None = None, text: str = "") -> None:
            self.post_message(JobProgress(job, done, total, text))

        def cancelled() -> bool:
            return worker.is_cancelled

        try:
            with cancellable(cancelled):  # the engine's checkpoints stop it within a second
                result = fn(progress, cancelled)
        except Cancelled:
            self.post_message(JobFinished(job, label, False, cancelled=True))
        except GcsError as err:
            self.post_message(JobFinished(job, label, False, error=str(err)))
        except Exception as err:  # the UI must survive an engine bug; the log keeps the traceback
            log.exception("job %s failed", job)
            self.post_message(JobFinished(job, label, False, error=f"{type(err).__name__}: {err}"))
        else:
            self.post_message(
                JobFinished(job, label, not worker.is_cancelled, cancelled=worker.is_cancelled, result=result)
            )

    def _tick(self) -> None:
        if self.busy:
            self._update_status()

    def on_job_started(self, message: JobStarted) -> None:
        self._update_status()

    def on_job_progress(self, message: JobProgress) -> None:
        if self.job.busy:
            self.job = replace(self.job, done=message.done, total=message.total, text=message.text)
            self._update_status()

    def on_job_finished(self, message: JobFinished) -> None:
        self.job = JobState()
        callback = self._done.pop(message.job, None)
        if message.cancelled:
            self.last_notice = f"{message.label}: cancelled"
            self.notify(self.last_notice, severity="warning")
        elif not message.ok:
            self.job_errors[message.job] = message.error
            self.last_notice = f"{message.label} failed: {message.error}"
            self.notify(message.error, title=f"{message.label} failed", severity="error", timeout=10)
        else:
            self.job_errors.pop(message.job, None)
            self.last_notice = ""
            if callback is not None:
                callback(message.result)
        self.changed()

    def on_filtr_block(self, message: FiltrBlock) -> None:
        self.generation += 1
        screen = self.screen
        if isinstance(screen, FiltrScreen):
            screen.update_view()

    def changed(self) -> None:
        """The workbench changed: bump the generation and redraw the visible screen."""
        self.generation += 1
        self._update_status()
        refresh = getattr(self.screen, "update_view", None)
        if refresh is not None:
            refresh()

    def _update_status(self) -> None:
        update = getattr(self.screen, "update_status", None)
        if update is not None:
            update()

    def status_text(self) -> str:
        """The status line: mission, fit state, last notice."""
        wb = self.workbench
        if not wb.ready:
            return "no mission open (o)"
        parts = [wb.mission.name]
        res = wb.result
        run = wb.filtr
        if res is None and run is not None and run.reports:  # FILTR stepped without a fit
            v = run.view()
            parts.append(f"FILTR {'finished' if v.finished else f'at block {v.done}/{v.total}'} (no batch fit: f)")
        elif res is None:
            parts.append("not fitted (f)")
        else:
            red = res.chi2 / res.dof if res.dof > 0 else float("nan")
            parts.append(f"fit {res.status}, χ²/dof {red:.3f}")
            if wb.stale:
                parts.append("config changed — f refits")
        added: list[str] = []
        for step in wb.current.steps:
            if step.action == "add" and step.effect is not None:
                added.append(step.effect)
            elif step.action == "remove" and step.effect in added:
                added.remove(step.effect)
        if added:
            parts.append(f"added: {', '.join(added)}")
        if self.last_notice:
            parts.append(self.last_notice)
        return terminal_safe(" · ".join(parts), one_line=True)  # names and notices come from files

    # ------------------------------------------------------------------ actions
    def action_view(self, mode: str) -> None:
        if mode in SCREENS_BY_VIEW:
            self.switch_mode(mode)

    def action_open_mission(self) -> None:
        start = str(self.source or "")
        self.push_screen(
            FormScreen("Open a mission directory or analysis config", [Field("path", "Path", start, kind="text")]),
            self._open_chosen,
        )

    def _open_chosen(self, v: dict | None) -> None:
        if v:
            self.open_path(v["path"])

    def action_fit(self) -> None:
        if not self.workbench.ready:
            self.notify("open a mission first (o)", severity="warning")
            return
        self.run_job("fit", "fitting", lambda progress, cancelled: self.workbench.fit(progress, cancelled))

    def action_cancel_job(self) -> None:
        if not self.busy:
            return
        self.workers.cancel_group(self, "engine")
        self.job = replace(self.job, text="cancelling…")
        self._update_status()

    def action_noise(self) -> None:
        """Each sensor's Allan deviation from its own telemetry (gcs noise), in a dialog."""
        if not self.workbench.ready:
            self.notify("open a mission first (o)", severity="warning")
            return
        from gcs_core.noise.measured import mission_noise
        from gcs_tui.tui.screens.allan import AllanScreen

        try:
            results = mission_noise(self.workbench.mission)
        except GcsError as err:
            self.notify(str(err), severity="error")
            return
        from gcs_core.noise.correlated import lines as correlation_lines

        an = getattr(self.workbench, "analysis", None)
        carried = an is not None and an.config.filter.noise_weighting == "correlated"
        title = f"Allan deviation · {terminal_safe(self.workbench.mission.spec.name, one_line=True)}"
        self.push_screen(AllanScreen(results, title, correlation_lines(getattr(an, "correlation", {}), carried)))

    def action_help(self) -> None:
        self.push_screen(HelpScreen(self.current_mode))

    def action_messages(self) -> None:
        self.push_screen(MessagesScreen("Warnings from the engine", self.messages))

    async def action_quit(self) -> None:
        """Quit; with unsaved config edits, ask first (saving is ctrl+s). A running job is
        cancelled first (it stops at its next checkpoint, within a second)."""
        if not self.workbench.unsaved:
            self._quit_now()
            return
        self.push_screen(
            ConfirmScreen(
                "Quit with unsaved edits?",
                "The analysis config has changes not saved to a file (models, roles, σ, the data plan). "
                "Quitting loses them; esc stays, ctrl+s saves.",
                yes="quit",
                no="stay",
            ),
            self._quit_if,
        )

    def _quit_if(self, ok: bool | None) -> None:
        if ok:
            self._quit_now()

    def _quit_now(self) -> None:
        if self.busy:
            self.workers.cancel_group(self, "engine")
        self.exit()

    def work_dir(self) -> Path:
        """Where the app writes what the user did not name: beside the analysis config the
        user opened or saved, else beside the mission directory (never the working directory
        by accident)."""
        return self.workbench.work_dir()

    def deliver_screenshot(
        self, filename: str | None = None, path: str | None = None, time_format: str | None = None
    ) -> str | None:
        """Save an SVG screenshot in the work directory (:meth:`work_dir`) and say where."""
        folder = Path(path) if path else self.work_dir()
        if not filename:
            filename = f"gcs-{self.current_mode}-{time.strftime('%Y%m%dT%H%M%S')}.svg"
        try:
            folder.mkdir(parents=True, exist_ok=True)
            out = Path(self.save_screenshot(filename, str(folder)))
            make_usual(out)
        except OSError as err:
            self.notify(
                f"cannot write {folder / filename}: {err.strerror or err}",
                title="screenshot not saved",
                severity="error",
                timeout=15,
            )
            return None
        self.last_notice = f"screenshot saved to {out}"
        self.notify(str(out), title="screenshot saved", timeout=15)
        self._update_status()
        return str(out)

    def action_save_config(self) -> None:
        """ctrl+s: the save dialog (:mod:`gcs_tui.tui.saving`: asks before replacing a file)."""
        from gcs_tui.tui import saving

        saving.open_dialog(self)

    def save_config_to(self, path: str | Path) -> Path | None:
        """Save the config to ``path`` now, without asking (tests, embedding)."""
        from gcs_tui.tui import saving

        return saving.save_to(self, Path(path))

    def change_effect(self, effect_id: str, add: bool) -> None:
        verb = "adding" if add else "removing"
        self.run_job(
            "effect",
            f"{verb} {effect_id}",
            lambda progress, cancelled: self.workbench.change_effect(effect_id, add, progress, cancelled),
        )

    def action_add_top_candidate(self) -> None:
        wb = self.workbench
        if not wb.ready or not wb.current.candidates:
            self.notify("no ranked candidates — fit first (f)", severity="warning")
            return
        ok = [c for c in wb.current.candidates if c.identifiable]
        self.add_candidate(ok[0] if ok else wb.current.candidates[0])

    def add_candidate(self, c) -> None:
        """Add candidate ``c`` and refit; ask first when it is a poor choice (not significant
        at the family-wise α or not identifiable), saying why."""
        why = poor_choice(c, self.workbench.config.diagnosis.significance)
        if not why:
            self.change_effect(c.id, True)
            return

        def add_if(ok: bool | None) -> None:
            if ok:
                self.change_effect(c.id, True)

        self.push_screen(ConfirmScreen(f"Add {c.id}?", why + " Add it anyway?", yes="add", no="cancel"), add_if)

    def action_remove_effect(self) -> None:
        wb = self.workbench
        if not wb.ready:
            return
        options = [(e, e) for e in wb.removable_effects()]

        def remove(eid: str | None) -> None:
            if eid:
                self.change_effect(eid, False)

        self.push_screen(ChoiceScreen("Remove an effect from the state (then refit)", options), remove)

    def action_predict(self) -> None:
        if self.workbench.ready:
            self.run_job("predict", "predicting", lambda p, c: jobs.predict(self.workbench, p, c))

    def action_verify(self) -> None:
        if self.workbench.ready:
            self.run_job("verify", "verifying", lambda p, c: jobs.verify(self.workbench, p, c))

    def action_save_calibration(self) -> None:
        wb = self.workbench
        if not wb.ready or wb.result is None:
            self.notify("fit first (f)", severity="warning")
            return
        fields = [
            Field("path", "SCDS file", str(jobs.scds_path(wb)), kind="text"),
            Field("note", "note", "", kind="text", optional=True),
        ]

        def done(values) -> None:
            if not values:
                return
            self.run_job(
                "calibration",
                "saving calibration",
                lambda p, c: jobs.save_calibration(wb, values["path"], values["note"] or "", p, c),
                on_done=lambda v: self.notify(f"calibration saved as version {v}"),
            )

        self.push_screen(
            FormScreen(
                "Append the fitted calibration to the SCDS",
                fields,
                note="Every element not held, with σ and covariance (append-only).",
            ),
            done,
        )

    def open_trade(self, path: str | Path) -> bool:
        """Show a trade study's results file (``gcs trade --output``) in the Trade screen."""
        from gcs_core.trade.run import read_study
        from gcs_tui.tui.screens.trade import TradeScreen

        try:
            _, rows = read_study(path)
        except GcsError as err:
            self.notify(str(err), title="trade study not opened", severity="error")
            return False
        self.push_screen(TradeScreen(rows, source=Path(path).name))
        return True

    def action_trade_results(self) -> None:
        cfg = self.workbench.config if self.workbench.ready else None
        start = ""
        if cfg is not None and cfg.trade.get("output") and cfg.path is not None:
            start = str(Path(cfg.path).parent / cfg.trade["output"])
        self.push_screen(
            FormScreen(
                "Open a trade study's results (gcs trade --output)", [Field("path", "HDF5 file", start, kind="text")]
            ),
            self._trade_chosen,
        )

    def _trade_chosen(self, v: dict | None) -> None:
        if v:
            self.open_trade(v["path"])

    def action_filtr_step(self) -> None:
        self.switch_mode("filtr")
        self.call_later(lambda: self.screen.run_action("step_block"))

    def action_filtr_run(self) -> None:
        self.switch_mode("filtr")
        self.call_later(lambda: self.screen.run_action("run_to_end"))


def run_tui(path: str | Path | None = None, *, work_dir: str | Path | None = None) -> GcsApp:
    """Run the TUI on a mission directory or analysis config (the CLI's ``gcs tui``);
    files it writes unasked go to ``work_dir`` (default: beside the config or mission).
    Returns the app: its ``crash_line`` is set when it stopped on an unhandled error."""
    app = GcsApp(path)
    if work_dir is not None:
        app.workbench.out_dir = Path(work_dir)
    with detached_terminal_logging():
        app.run()
    return app


__all__ = ["GcsApp", "run_tui", "VIEWS"]
