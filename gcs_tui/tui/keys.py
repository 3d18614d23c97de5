"""Keybindings as data.

Each binding has a dotted id (``diagnosis.add``), the keys, the Textual action it runs
and a label. Screens and the app turn these rows into ``BINDINGS`` with
:func:`bindings`; the help screen (``?``) lists the same rows, so what the help says
is what the keys do.

========================  =========  ===============================================
scope                     keys       what
========================  =========  ===============================================
app                       1…9, 0     switch screen (Mission … Calibration history)
app                       o          open a mission directory or config
app                       f          fit (from the config, in the background)
app                       ctrl+s     save the analysis config
app                       escape     cancel the running job
app                       w          every warning the engine gave, whole
app                       ?          help: every key
app                       q          quit
========================  =========  ===============================================
"""

from __future__ import annotations

from dataclasses import dataclass

from textual.binding import Binding, BindingType


@dataclass(frozen=True)
class Key:
    """One keybinding (module docstring)."""

    id: str
    """Dotted id: ``<scope>.<name>``."""
    keys: str
    """Comma-separated Textual key names (``"a"``, ``"ctrl+s"``, ``"question_mark"``)."""
    action: str
    """The Textual action string, e.g. ``"add_selected"`` or ``"app.view('residuals')"``."""
    description: str
    """Label in the footer and the help screen."""
    show: bool = True
    """Shown in the footer (the help screen lists every key)."""
    priority: bool = False
    """Checked before the focused widget's own bindings."""

    @property
    def display_keys(self) -> str:
        names = {
            "question_mark": "?",
            "escape": "esc",
            "left_square_bracket": "[",
            "right_square_bracket": "]",
            "space": "space",
            "enter": "enter",
            "delete": "del",
        }
        return ", ".join(names.get(k, k) for k in self.keys.split(","))


#: The screens in navigation order: (mode id, key, full title, short title).
VIEWS: tuple[tuple[str, str, str, str], ...] = (
    ("mission", "1", "Mission", "Mission"),
    ("models", "2", "Models", "Models"),
    ("state", "3", "State & covariance", "State"),
    ("plan", "4", "Data plan", "Plan"),
    ("filtr", "5", "FILTR", "FILTR"),
    ("residuals", "6", "Residuals", "Resid"),
    ("diagnosis", "7", "Diagnosis", "Diag"),
    ("predictor", "8", "Predictor", "Pred"),
    ("verification", "9", "Verification", "Verif"),
    ("history", "0", "Calibration history", "Hist"),
)

APP: tuple[Key, ...] = tuple(
    Key(f"view.{mode}", key, f"app.view('{mode}')", title, show=False) for mode, key, title, _ in VIEWS
) + (
    Key("mission.open", "o", "app.open_mission", "Open", show=False),
    Key("fit.run", "f", "app.fit", "Fit"),
    Key("config.save", "ctrl+s", "app.save_config", "Save", show=False),
    Key("job.cancel", "escape", "app.cancel_job", "Cancel job", show=False),
    Key("app.help", "question_mark", "app.help", "Help"),
    Key("app.messages", "w", "app.messages", "Warnings", show=False),
    Key("app.quit", "q", "app.quit", "Quit", show=False),
)

SCREENS: dict[str, tuple[Key, ...]] = {
    "mission": (),
    "models": (Key("models.cycle", "enter,space", "cycle_model", "Change model"),),
    "state": (
        Key("state.edit", "e,enter", "edit_element", "Edit"),
        Key("state.solve", "s", "set_role('solve-for')", "Solve-for"),
        Key("state.consider", "c", "set_role('consider')", "Consider"),
        Key("state.hold", "h", "set_role('held')", "Held"),
        Key("state.show_held", "v", "toggle_held", "Show held", show=False),
        Key("state.details", "i", "toggle_details", "Details"),
    ),
    "plan": (
        Key("plan.span", "e", "edit_span", "Span/step"),
        Key("plan.add_gap", "g", "add_gap", "Add gap"),
        Key("plan.add_maneuver", "m", "add_maneuver", "Add maneuver"),
        Key("plan.delete", "d,delete", "delete_item", "Delete"),
        Key("plan.predict", "p", "app.predict", "Predict", show=False),
    ),
    "filtr": (
        Key("filtr.step", "n", "step_block", "Step block"),
        Key("filtr.run", "r", "run_to_end", "Run to end"),
        Key("filtr.cancel", "x", "app.cancel_job", "Cancel"),
        Key("filtr.reset", "z", "reset", "Reset"),
    ),
    "residuals": (
        Key("residuals.prev_sensor", "left_square_bracket", "sensor(-1)", "Prev sensor", show=False),
        Key("residuals.next_sensor", "right_square_bracket", "sensor(1)", "Next sensor"),
        Key("residuals.component", "c", "component", "Component"),
        Key("residuals.xaxis", "x", "xaxis", "X axis"),
        Key("residuals.view", "v", "view_kind", "Plot kind"),
    ),
    "diagnosis": (
        Key("diagnosis.add", "a", "add_selected", "Add effect"),
        Key("diagnosis.remove", "r", "remove_effect", "Remove effect"),
        Key("diagnosis.charts", "g", "toggle_charts", "Charts/text"),
    ),
    "predictor": (
        Key("predictor.run", "p", "app.predict", "Predict"),
        Key("predictor.element", "right_square_bracket", "element(1)", "Next element"),
        Key("predictor.prev_element", "left_square_bracket", "element(-1)", "Prev element", show=False),
    ),
    "verification": (Key("verification.run", "r", "app.verify", "Verify"),),
    "history": (
        Key("history.mark_a", "a", "mark('a')", "Mark A"),
        Key("history.mark_b", "b", "mark('b')", "Mark B"),
        Key("history.save", "k", "app.save_calibration", "Save calibration"),
    ),
}


def bindings(keys: tuple[Key, ...]) -> list[BindingType]:
    """Textual bindings of a tuple of :class:`Key` rows."""
    return [Binding(k.keys, k.action, k.description, show=k.show, priority=k.priority, id=k.id) for k in keys]


def help_rows(scope: str | None = None) -> list[tuple[str, str, str]]:
    """``(scope, keys, description)`` rows for the help screen: app keys, then one screen's
    (or every screen's when ``scope`` is None)."""
    rows = [("app", k.display_keys, k.description) for k in APP]
    for name, keys in SCREENS.items():
        if scope is None or name == scope:
            rows += [(name, k.display_keys, k.description) for k in keys]
    return rows
