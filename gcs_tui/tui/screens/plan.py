"""Data plan: the predictor's span and output step, its data gaps and maneuvers
(seed §4.3, Eq 4-35/4-36). Edits go straight into the config's ``[prediction]`` table;
``p`` runs the predictor on the plan.
"""

from __future__ import annotations

from rich.text import Text
from textual.app import ComposeResult
from textual.containers import Horizontal, Vertical
from textual.widgets import DataTable, Label, Static

from gcs_core import display as fmt
from gcs_core.config_checks import AXES
from gcs_core.config_schema import Maneuver, PredictionConfig
from gcs_core.errors import GcsError
from gcs_tui.tui.keys import SCREENS, bindings
from gcs_tui.tui.screens.base import GcsScreen
from gcs_tui.tui.screens.dialogs import FormScreen, key_fields
from gcs_tui.tui.theme import series
from gcs_tui.tui.widgets.plots import GcsPlot
from gcs_tui.tui.widgets.tables import cursor_key


def _num(v: float) -> str:
    """A time [s] or rate as a dialog prefill: to the thousandth, without float noise."""
    return f"{round(float(v), 3):.12g}"


def _count(n: int, noun: str) -> str:
    return f"{n} {noun}{'' if n == 1 else 's'}"


class PlanScreen(GcsScreen):
    """Span, gaps and maneuvers of the prediction data plan."""

    VIEW = "plan"
    CSS_PATH = "plan.tcss"
    BINDINGS = bindings(SCREENS["plan"])

    def compose_body(self) -> ComposeResult:
        yield Static("", id="plan-span", markup=False)
        with Horizontal(id="plan-tables"):
            with Vertical(id="plan-gaps-box"):
                yield Label("Data gaps  (g: add · enter: edit · d: delete)", classes="panel-title")
                yield DataTable(id="gaps", cursor_type="row", zebra_stripes=True)
            with Vertical(id="plan-man-box"):
                yield Label("Maneuvers  (m: add · enter: edit · d: delete)", classes="panel-title")
                yield DataTable(id="maneuvers", cursor_type="row", zebra_stripes=True)
        yield GcsPlot(id="plan-plot", title="plan")

    def refresh_view(self) -> None:
        wb = self.wb
        cfg = wb.config
        t0, t1 = wb.plan_span()
        source = "config" if cfg.prediction.start is not None and cfg.prediction.end is not None else "telemetry span"
        self.query_one("#plan-span", Static).update(
            Text.assemble(
                ("span ", "bold"),
                fmt.span(t0, t1),
                f" ({source})  ·  ",
                ("step ", "bold"),
                fmt.seconds(cfg.prediction.step),
                f"  ·  {_count(len(cfg.prediction.gaps), 'gap')}, {_count(len(cfg.prediction.maneuvers), 'maneuver')}"
                "  ·  e: edit span/step  ·  p: predict",
            )
        )
        gaps = self.query_one("#gaps", DataTable)
        gaps.clear(columns=True)
        gaps.add_columns(Text("start", justify="right"), Text("end", justify="right"), Text("length", justify="right"))
        for i, (a, b) in enumerate(cfg.prediction.gaps):
            gaps.add_row(*(Text(fmt.seconds(v), justify="right") for v in (a, b, b - a)), key=str(i))
        man = self.query_one("#maneuvers", DataTable)
        man.clear(columns=True)
        man.add_columns(
            Text("start", justify="right"),
            Text("duration", justify="right"),
            "axis",
            Text("rate", justify="right"),
            Text("angle", justify="right"),
        )
        for i, m in enumerate(cfg.prediction.maneuvers):
            man.add_row(
                Text(fmt.seconds(m.start), justify="right"),
                Text(fmt.seconds(m.duration), justify="right"),
                m.axis,
                Text(f"{fmt.sig(m.rate_deg_s, 3)} deg/s", justify="right"),
                Text(f"{fmt.sig(m.rate_deg_s * m.duration, 3)} deg", justify="right"),
                key=str(i),
            )
        self.query_one("#plan-plot", GcsPlot).paint(lambda plt: self._plot(plt, t0, t1, cfg))

    @staticmethod
    def _plot(plt, t0, t1, cfg) -> None:
        plt.plot([t0, t1], [4, 4], color=series(0), marker="sd")
        for a, b in cfg.prediction.gaps:
            plt.plot([a, b], [4, 4], color="red", marker="sd")
        for m in cfg.prediction.maneuvers:
            y = 3 - AXES.index(m.axis)
            plt.plot([m.start, m.start + m.duration], [y, y], color=series(1 + AXES.index(m.axis)), marker="sd")
        plt.yticks([4, 3, 2, 1], ["data", "roll", "pitch", "yaw"])
        plt.ylim(0.5, 4.5)
        plt.xlim(
            min(t0, *(a for a, _ in cfg.prediction.gaps)) if cfg.prediction.gaps else t0,
            max(t1, *(b for _, b in cfg.prediction.gaps)) if cfg.prediction.gaps else t1,
        )
        plt.xlabel("t [s]   (red: gap)")
        plt.title("data plan")

    # ------------------------------------------------------------------ edits
    def _apply(self, **kw) -> None:
        try:
            self.wb.set_plan(**kw)
        except GcsError as err:
            self.app.notify(str(err), title="plan not changed", severity="error")
            return
        self.app.changed()

    def _row(self, table_id: str) -> int | None:
        table = self.query_one(f"#{table_id}", DataTable)
        if table.row_count == 0:
            return None
        return int(cursor_key(table))

    def action_edit_span(self) -> None:
        cfg = self.wb.config
        t0, t1 = self.wb.plan_span()
        fields = key_fields(
            PredictionConfig,
            {"start": _num(t0), "end": _num(t1), "step": _num(cfg.prediction.step)},
            ("start", "end", "step"),
        )

        def done(v):
            if v:
                self._apply(start=v["start"], end=v["end"], step=v["step"])

        self.app.push_screen(FormScreen("Plan span and output step", fields), done)

    def _gap_form(self, title: str, a: float, b: float, index: int | None) -> None:
        def done(v):
            if not v:
                return
            gaps = list(self.wb.config.prediction.gaps)
            if index is None:
                gaps.append((v["start"], v["end"]))
            else:
                gaps[index] = (v["start"], v["end"])
            self._apply(gaps=tuple(gaps))

        self.app.push_screen(
            FormScreen(title, key_fields(PredictionConfig, {"start": _num(a), "end": _num(b)}, ("start", "end"))), done
        )

    def action_add_gap(self) -> None:
        t0, t1 = self.wb.plan_span()
        mid = 0.5 * (t0 + t1)
        self._gap_form("Add a data gap", mid, mid + 600.0, None)

    def _maneuver_form(self, title: str, m, index: int | None) -> None:
        def done(v):
            if not v:
                return
            mans = list(self.wb.config.prediction.maneuvers)
            new = Maneuver(**v)
            if index is None:
                mans.append(new)
            else:
                mans[index] = new
            self._apply(maneuvers=tuple(mans))

        fields = key_fields(
            Maneuver,
            {"start": _num(m.start), "duration": _num(m.duration), "axis": m.axis, "rate_deg_s": _num(m.rate_deg_s)},
        )
        self.app.push_screen(
            FormScreen(title, fields, note="Constant-rate rotation about one reference axis (Eq 4-35, 4-36)."), done
        )

    def action_add_maneuver(self) -> None:
        t0, t1 = self.wb.plan_span()
        self._maneuver_form("Add a maneuver", Maneuver(0.5 * (t0 + t1), 300.0, "yaw", 0.1), None)

    def action_delete_item(self) -> None:
        focused = self.focused
        if not isinstance(focused, DataTable):
            return
        i = self._row(str(focused.id))
        if i is None:
            return
        if focused.id == "gaps":
            self._apply(gaps=tuple(g for j, g in enumerate(self.wb.config.prediction.gaps) if j != i))
        else:
            self._apply(maneuvers=tuple(m for j, m in enumerate(self.wb.config.prediction.maneuvers) if j != i))

    def on_data_table_row_selected(self, event: DataTable.RowSelected) -> None:
        i = int(str(event.row_key.value))
        if event.data_table.id == "gaps":
            a, b = self.wb.config.prediction.gaps[i]
            self._gap_form("Edit the data gap", a, b, i)
        else:
            self._maneuver_form("Edit the maneuver", self.wb.config.prediction.maneuvers[i], i)
