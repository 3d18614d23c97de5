"""Command-palette commands (ctrl+p), namespaced ``<area>: <verb>``.

Each command is a row ``(name, help, action)``; the action string is run on the app
(``app.run_action``), so a command and its key do exactly the same thing.
"""

from __future__ import annotations

from functools import partial

from textual.command import DiscoveryHit, Hit, Hits, Provider

from gcs_tui.tui.keys import VIEWS

#: (palette name, one-line help, app action)
COMMANDS: tuple[tuple[str, str, str], ...] = tuple(
    (f"view: {title.lower()}", f"Show the {title} screen (key {key})", f"view('{mode}')")
    for mode, key, title, _ in VIEWS
) + (
    ("mission: open", "Open a mission directory or an analysis config (key o)", "open_mission"),
    ("fit: run", "Fit the current configuration in the background (key f)", "fit"),
    ("fit: cancel", "Cancel the running job (key esc)", "cancel_job"),
    ("diagnosis: add top candidate", "Add the most significant identifiable candidate and refit", "add_top_candidate"),
    ("diagnosis: remove effect", "Remove an effect from the state and refit", "remove_effect"),
    ("filtr: step block", "Process the next FILTR block", "filtr_step"),
    ("filtr: run to end", "Process every remaining FILTR block", "filtr_run"),
    ("predictor: run", "Predict σ of every element along the data plan (key p on Plan/Predictor)", "predict"),
    ("trade: open results", "Show a trade study's ranked plans and open one in the Data plan screen", "trade_results"),
    ("verification: run", "Compare onboard and ground attitude (key r on Verification)", "verify"),
    ("calibration: save", "Append the fitted calibration to the SCDS", "save_calibration"),
    ("config: save", "Save the analysis config (key ctrl+s)", "save_config"),
    ("noise: allan deviation", "Each sensor's noise and Allan deviation from its telemetry", "noise"),
    ("app: help", "Every key and what the numbers mean (key ?)", "help"),
    ("app: messages", "Every warning the engine gave, whole (key w)", "messages"),
    ("app: quit", "Quit GCS (key q)", "quit"),
)


class GcsCommands(Provider):
    """The GCS commands for Textual's command palette."""

    def _run(self, action: str):
        return partial(self.app.run_action, action)

    async def discover(self) -> Hits:
        for name, help_text, action in COMMANDS:
            yield DiscoveryHit(name, self._run(action), help=help_text)

    async def search(self, query: str) -> Hits:
        matcher = self.matcher(query)
        for name, help_text, action in COMMANDS:
            score = matcher.match(name)
            if score > 0:
                yield Hit(score, matcher.highlight(name), self._run(action), help=help_text)
