"""Small modal dialogs: a form of typed fields, a list to pick from, a yes/no question
and a scrollable list of messages.

A form is described by :class:`Field` rows and returns ``{name: value}`` with every
value parsed (numbers as float) — or None when cancelled. Enter in any field submits,
Tab moves, Escape cancels; errors name the field and keep the dialog open.

Every text shown here is plain text, never Textual markup: labels such as
``value [deg]`` or ``start [s]`` keep their units (markup would read ``[deg]`` as a tag).
"""

from __future__ import annotations

import dataclasses
import math
from collections.abc import Sequence
from dataclasses import dataclass

from rich.text import Text
from textual.app import ComposeResult
from textual.binding import Binding
from textual.containers import Horizontal, Vertical, VerticalScroll
from textual.screen import ModalScreen
from textual.widgets import Button, Input, Label, OptionList, Static
from textual.widgets.option_list import Option


@dataclass(frozen=True)
class Field:
    """One input of a :class:`FormScreen`."""

    name: str
    """Key of the value in the result."""
    label: str
    """Shown left of the input (with the unit)."""
    value: str = ""
    """Initial text."""
    kind: str = "float"
    """``float`` (finite number), ``text`` or one of ``choices``."""
    choices: tuple[str, ...] = ()
    """Allowed values when ``kind == "choice"``."""
    optional: bool = False
    """An empty field gives None instead of an error."""
    positive: bool = False
    """A number must be > 0."""


def key_fields(table, values: dict[str, str], names: Sequence[str] | None = None) -> list[Field]:
    """The inputs of a form over a config dataclass's keys (``table`` the class): label,
    kind and checks from each field's metadata (:mod:`gcs_core.config`), the initial text
    from ``values``; ``names`` picks and orders the keys (default: every key with a label)."""
    meta = {f.name: f.metadata for f in dataclasses.fields(table) if "label" in f.metadata}
    out = []
    for name in names if names is not None else list(meta):
        m = meta[name]
        choices = tuple(m.get("choices", ()))
        out.append(
            Field(
                name,
                m["label"],
                values.get(name, ""),
                kind="choice" if choices else "float",
                choices=choices,
                positive=bool(m.get("positive", False)),
            )
        )
    return out


def parse_field(f: Field, text: str):
    """The value of ``text`` for field ``f``; raises ValueError with a short reason."""
    text = text.strip()
    if not text:
        if f.optional:
            return None
        raise ValueError("is required")
    if f.kind == "text":
        return text
    if f.kind == "choice":
        if text not in f.choices:
            raise ValueError(f"must be one of {', '.join(f.choices)}")
        return text
    try:
        v = float(text)
    except ValueError:
        raise ValueError(f"must be a number, got {text!r}") from None
    if not math.isfinite(v):
        raise ValueError("must be finite")
    if f.positive and not v > 0:
        raise ValueError("must be > 0")
    return v


class FormScreen(ModalScreen[dict | None]):
    """A titled form of :class:`Field` rows (module docstring)."""

    CSS_PATH = "dialogs.tcss"
    BINDINGS = [Binding("escape", "cancel", "Cancel")]

    def __init__(self, title: str, fields: list[Field], *, note: str = "") -> None:
        super().__init__()
        self.form_title = title
        self.fields = list(fields)
        self.note = note

    def compose(self) -> ComposeResult:
        with Vertical(id="dialog"):
            yield Label(self.form_title, id="dialog-title", markup=False)
            if self.note:
                yield Static(self.note, classes="dialog-note", markup=False)
            for f in self.fields:
                with Horizontal(classes="form-row"):
                    yield Label(f.label, classes="form-label", markup=False)
                    placeholder = " | ".join(f.choices) if f.kind == "choice" else ""
                    yield Input(f.value, id=f"field-{f.name}", placeholder=placeholder, select_on_focus=False)
            yield Static("", id="dialog-error", markup=False)
            yield Label("enter: OK   tab: next field   esc: cancel", classes="dialog-help", markup=False)

    def on_mount(self) -> None:
        if self.fields:
            self.query_one(f"#field-{self.fields[0].name}", Input).focus()

    def on_input_submitted(self, event: Input.Submitted) -> None:
        event.stop()
        values = {}
        for f in self.fields:
            text = self.query_one(f"#field-{f.name}", Input).value
            try:
                values[f.name] = parse_field(f, text)
            except ValueError as err:
                self.query_one("#dialog-error", Static).update(f"{f.label.strip()}: {err}")
                self.query_one(f"#field-{f.name}", Input).focus()
                return
        self.dismiss(values)

    def action_cancel(self) -> None:
        self.dismiss(None)


class ChoiceScreen(ModalScreen[str | None]):
    """Pick one of ``options`` (value, label); Enter picks, Escape cancels."""

    CSS_PATH = "dialogs.tcss"
    BINDINGS = [Binding("escape", "cancel", "Cancel")]

    def __init__(self, title: str, options: list[tuple[str, str]], *, note: str = "") -> None:
        super().__init__()
        self.choice_title = title
        self.options = options
        self.note = note

    def compose(self) -> ComposeResult:
        with Vertical(id="dialog"):
            yield Label(self.choice_title, id="dialog-title", markup=False)
            if self.note:
                yield Static(self.note, classes="dialog-note", markup=False)
            if self.options:
                yield OptionList(*[Option(Text(label), id=value) for value, label in self.options], id="choices")
            else:
                yield Static("(nothing to choose)", classes="dialog-note")
            yield Label("enter: choose   esc: cancel", classes="dialog-help", markup=False)

    def on_option_list_option_selected(self, event: OptionList.OptionSelected) -> None:
        event.stop()
        self.dismiss(event.option.id)

    def action_cancel(self) -> None:
        self.dismiss(None)


class ConfirmScreen(ModalScreen[bool]):
    """A yes/no question with the reason: ``y``/enter answers yes, ``n``/esc no."""

    CSS_PATH = "dialogs.tcss"
    BINDINGS = [Binding("escape,n", "answer(False)", "No"), Binding("y", "answer(True)", "Yes")]

    def __init__(self, title: str, text: str, *, yes: str = "yes", no: str = "no") -> None:
        super().__init__()
        self.confirm_title, self.text, self.yes, self.no = title, text, yes, no

    def compose(self) -> ComposeResult:
        with Vertical(id="dialog"):
            yield Label(self.confirm_title, id="dialog-title", markup=False)
            yield Static(self.text, classes="dialog-text", markup=False)
            with Horizontal(classes="dialog-buttons"):
                yield Button(f"{self.yes} (y)", id="yes", variant="warning")
                yield Button(f"{self.no} (n, esc)", id="no", variant="primary")

    def on_mount(self) -> None:
        self.query_one("#no", Button).focus()

    def on_button_pressed(self, event: Button.Pressed) -> None:
        event.stop()
        self.dismiss(event.button.id == "yes")

    def action_answer(self, yes: bool) -> None:
        self.dismiss(yes)


class MessagesScreen(ModalScreen[None]):
    """Messages (level, text), each whole and wrapped, in a scrollable box; esc closes."""

    CSS_PATH = "dialogs.tcss"
    BINDINGS = [Binding("escape,q", "close", "Close")]

    def __init__(self, title: str, messages: list[tuple[str, str]]) -> None:
        super().__init__()
        self.box_title, self.messages = title, list(messages)

    def compose(self) -> ComposeResult:
        with Vertical(id="dialog"):
            yield Label(self.box_title, id="dialog-title", markup=False)
            with VerticalScroll(id="messages"):
                if not self.messages:
                    yield Static("(none)", classes="dialog-note", markup=False)
                for level, text in self.messages:
                    yield Static(f"{level}: {text}", classes="dialog-text", markup=False)
            yield Label("esc: close   ↑/↓: scroll", classes="dialog-help", markup=False)

    def on_mount(self) -> None:
        self.query_one("#messages", VerticalScroll).focus()

    def action_close(self) -> None:
        self.dismiss(None)
