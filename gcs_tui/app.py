"""The GCS analyst's terminal UI (replaces the seed study's GESS graphics terminal).

:class:`GcsApp` shows one :class:`~gcs_tui.workbench.Workbench` through ten screens
(Textual *modes*, keys 1…9, 0). Everything slow — importing a mission, fitting,
adding an effect, FILTR blocks, prediction, verification — runs in a thread worker
(:meth:`GcsApp.run_job`) that reports through :mod:`gcs_tui.messages`; the UI keeps
responding and ``esc`` cancels.

Entry point for the CLI: :func:`run_tui`.
"""

from __future__ import annotations

import logging
from pathlib import Path
from typing import Any, Callable

from textual import work
from textual.app import App
from textual.worker import get_current_worker

from gcs_core.errors import GcsError
from gcs_tui import jobs
from gcs_tui.commands import GcsCommands
from gcs_tui.keys import APP, VIEWS, bindings
from gcs_tui.messages import FiltrBlock, JobFinished, JobProgress, JobStarted
from gcs_tui.screens.diagnosis import DiagnosisScreen
from gcs_tui.screens.dialogs import ChoiceScreen, Field, FormScreen
from gcs_tui.screens.filtr import FiltrScreen
from gcs_tui.screens.help import HelpScreen
from gcs_tui.screens.history import HistoryScreen
from gcs_tui.screens.mission import MissionScreen
from gcs_tui.screens.models import ModelsScreen
from gcs_tui.screens.plan import PlanScreen
from gcs_tui.screens.predictor import PredictorScreen
from gcs_tui.screens.residuals import ResidualsScreen
from gcs_tui.screens.state import StateScreen
from gcs_tui.screens.verification import VerificationScreen
from gcs_tui.theme import VARIABLES
from gcs_tui.widgets.chrome import JobState
from gcs_tui.workbench import Workbench

log = logging.getLogger(__name__)

SCREENS_BY_VIEW = {
    "mission": MissionScreen, "models": ModelsScreen, "state": StateScreen, "plan": PlanScreen,
    "filtr": FiltrScreen, "residuals": ResidualsScreen, "diagnosis": DiagnosisScreen,
    "predictor": PredictorScreen, "verification": VerificationScreen, "history": HistoryScreen,
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
    start_view : the screen shown first (a mode id of :data:`gcs_tui.keys.VIEWS`).
    """

    TITLE = "GCS"
    CSS_PATH = "theme.tcss"
    BINDINGS = bindings(APP)
    COMMANDS = App.COMMANDS | {GcsCommands}
    MODES = SCREENS_BY_VIEW
    HORIZONTAL_BREAKPOINTS = [(0, "-compact"), (120, "-wide"), (150, "-xwide")]
    VERTICAL_BREAKPOINTS = [(0, "-short"), (40, "-tall")]

    def __init__(self, source: str | Path | None = None, *, workbench: Workbench | None = None,
                 save_path: str | Path | None = None, start_view: str = "mission") -> None:
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
        self.job_errors: dict[str, str] = {}
        """Job id -> the error of its latest failed run (views show why they are empty)."""

    # ------------------------------------------------------------------ theme
    def get_theme_variable_defaults(self) -> dict[str, str]:
        return dict(VARIABLES)

    # ------------------------------------------------------------------ start
    def on_mount(self) -> None:
        self.switch_mode(self.start_view)
        if self.source is not None and not self.workbench.ready:
            self.open_path(self.source)

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
        self.job = JobState(label, 0.0, None, "")
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
            result = fn(progress, cancelled)
        except GcsError as err:
            self.post_message(JobFinished(job, label, False, error=str(err)))
        except Exception as err:  # the UI must survive an engine bug; the log keeps the traceback
            log.exception("job %s failed", job)
            self.post_message(JobFinished(job, label, False, error=f"{type(err).__name__}: {err}"))
        else:
            self.post_message(JobFinished(job, label, not worker.is_cancelled,
                                          cancelled=worker.is_cancelled, result=result))

    def on_job_started(self, message: JobStarted) -> None:
        self._update_status()

    def on_job_progress(self, message: JobProgress) -> None:
        if self.job.busy:
            self.job = JobState(self.job.label, message.done, message.total, message.text)
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
        if res is None:
            parts.append("not fitted (f)")
        else:
            red = res.chi2 / res.dof if res.dof > 0 else float("nan")
            parts.append(f"fit {res.status}, χ²/dof {red:.3f}")
            if wb.stale:
                parts.append("config changed — f refits")
        added: list[str] = []
        for step in wb.analysis.steps:
            if step.action == "add":
                added.append(step.effect)
            elif step.action == "remove" and step.effect in added:
                added.remove(step.effect)
        if added:
            parts.append(f"added: {', '.join(added)}")
        if self.last_notice:
            parts.append(self.last_notice)
        return " · ".join(parts)

    # ------------------------------------------------------------------ actions
    def action_view(self, mode: str) -> None:
        if mode in SCREENS_BY_VIEW:
            self.switch_mode(mode)

    def action_open_mission(self) -> None:
        start = str(self.source or "")
        self.push_screen(FormScreen("Open a mission directory or analysis config",
                                    [Field("path", "Path", start, kind="text")]),
                         lambda v: v and self.open_path(v["path"]))

    def action_fit(self) -> None:
        if not self.workbench.ready:
            self.notify("open a mission first (o)", severity="warning")
            return
        self.run_job("fit", "fitting", lambda progress, cancelled: self.workbench.fit(progress, cancelled))

    def action_cancel_job(self) -> None:
        if not self.busy:
            return
        self.workers.cancel_group(self, "engine")
        self.job = JobState(self.job.label, self.job.done, self.job.total, "cancelling…")
        self._update_status()

    def action_help(self) -> None:
        self.push_screen(HelpScreen(self.current_mode))

    def action_save_config(self) -> None:
        wb = self.workbench
        if not wb.ready:
            return
        default = str(wb.save_path) if wb.save_path else "gcs.toml"
        self.push_screen(FormScreen("Save the analysis config", [Field("path", "File", default, kind="text")],
                                    note="Paths inside are written relative to the file."),
                         lambda v: v and self.save_config_to(v["path"]))

    def save_config_to(self, path: str | Path) -> Path | None:
        try:
            out = self.workbench.save_config(path)
        except (GcsError, OSError) as err:
            self.notify(str(err), title="config not saved", severity="error")
            return None
        self.last_notice = f"config saved to {out.name}"
        self.notify(self.last_notice)
        self.changed()
        return out

    def change_effect(self, effect_id: str, add: bool) -> None:
        verb = "adding" if add else "removing"
        self.run_job("effect", f"{verb} {effect_id}",
                     lambda progress, cancelled: self.workbench.change_effect(effect_id, add, progress, cancelled))

    def action_add_top_candidate(self) -> None:
        wb = self.workbench
        if not wb.ready or not wb.analysis.candidates:
            self.notify("no ranked candidates — fit first (f)", severity="warning")
            return
        ok = [c for c in wb.analysis.candidates if c.identifiable]
        if not ok:
            self.notify("no identifiable candidate", severity="warning")
            return
        self.change_effect(ok[0].id, True)

    def action_remove_effect(self) -> None:
        wb = self.workbench
        if not wb.ready:
            return
        options = [(e, e) for e in wb.removable_effects()]
        self.push_screen(ChoiceScreen("Remove an effect from the state (then refit)", options),
                         lambda eid: eid and self.change_effect(eid, False))

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
        fields = [Field("path", "SCDS file", str(jobs.scds_path(wb)), kind="text"),
                  Field("note", "note", "", kind="text", optional=True)]

        def done(values) -> None:
            if not values:
                return
            self.run_job("calibration", "saving calibration",
                         lambda p, c: jobs.save_calibration(wb, values["path"], values["note"] or "", p, c),
                         on_done=lambda v: self.notify(f"calibration saved as version {v}"))

        self.push_screen(FormScreen("Append the fitted calibration to the SCDS", fields,
                                    note="Every element not held, with σ and covariance (append-only)."), done)

    def open_trade(self, path: str | Path) -> bool:
        """Show a trade study's results file (``gcs trade --output``) in the Trade screen."""
        from gcs_core.trade.run import read_study
        from gcs_tui.screens.trade import TradeScreen

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
        self.push_screen(FormScreen("Open a trade study's results (gcs trade --output)",
                                    [Field("path", "HDF5 file", start, kind="text")]),
                         lambda v: v and self.open_trade(v["path"]))

    def action_filtr_step(self) -> None:
        self.switch_mode("filtr")
        self.call_later(lambda: self.screen.run_action("step_block"))

    def action_filtr_run(self) -> None:
        self.switch_mode("filtr")
        self.call_later(lambda: self.screen.run_action("run_to_end"))


def run_tui(path: str | Path | None = None) -> None:
    """Run the TUI on a mission directory or analysis config (the CLI's ``gcs tui``)."""
    GcsApp(path).run()


__all__ = ["GcsApp", "run_tui", "VIEWS"]
