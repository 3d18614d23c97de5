"""Calibration history: the versions of the Sensor Calibration Data Set (SCDS) and
what changed between two of them (Δ and Δ in units of the combined σ).

``a``/``b`` mark the selected version as A or B; ``k`` appends the current fit as a
new version. The SCDS is read through :mod:`gcs_core.io.scds`.
"""

from __future__ import annotations

import math

from rich.text import Text
from textual.app import ComposeResult
from textual.containers import Horizontal, Vertical
from textual.widgets import DataTable, Label, Static

from gcs_core import display as fmt
from gcs_core.errors import GcsError
from gcs_tui.tui import jobs
from gcs_tui.tui.keys import SCREENS, bindings
from gcs_tui.tui.screens.base import GcsScreen
from gcs_tui.tui.theme import color
from gcs_tui.tui.widgets.tables import cursor_key


class HistoryScreen(GcsScreen):
    """SCDS versions and the diff between two of them."""

    VIEW = "history"
    CSS_PATH = "history.tcss"
    BINDINGS = bindings(SCREENS["history"])

    def __init__(self) -> None:
        super().__init__()
        self.marks: dict[str, int] = {}

    def compose_body(self) -> ComposeResult:
        yield Static("", id="hist-info", markup=False)
        with Horizontal(id="hist-split"):
            with Vertical(id="hist-versions-box"):
                yield Label("Versions  (a/b: mark for the diff · k: save the fit)", classes="panel-title")
                yield DataTable(id="versions", cursor_type="row", zebra_stripes=True)
            with Vertical(id="hist-diff-box"):
                yield Label("Diff", id="diff-title", classes="panel-title")
                yield DataTable(id="diff", cursor_type="row", zebra_stripes=True)

    def _path(self):
        return jobs.scds_path(self.wb)

    def refresh_view(self) -> None:
        path = self._path()
        info = self.query_one("#hist-info", Static)
        versions_t = self.query_one("#versions", DataTable)
        diff_t = self.query_one("#diff", DataTable)
        versions_t.clear(columns=True)
        diff_t.clear(columns=True)
        try:
            versions = jobs.scds_versions(path)
        except GcsError as err:
            info.update(f" SCDS {path.name}: {err}")
            return
        if not versions:
            info.update(f" SCDS {path.name}: no calibration saved yet — fit (f), then k appends a version.")
            return
        info.update(f" SCDS {path.name} · {len(versions)} version{'s' if len(versions) != 1 else ''}")
        numbers = [v.version for v in versions]
        if getattr(self, "_seen", None) != numbers:  # a new version: diff the latest two again
            self._seen = numbers
            self.marks = {}
        if self.marks.get("b") not in numbers:
            self.marks["b"] = numbers[-1]
        if self.marks.get("a") not in numbers:
            self.marks["a"] = numbers[-2] if len(numbers) > 1 else numbers[-1]
        versions_t.add_column(Text("ver", justify="right"))
        versions_t.add_column("mark")
        versions_t.add_column("created (UTC)")
        versions_t.add_column(Text("params", justify="right"))
        versions_t.add_column("data span")
        versions_t.add_column("note")
        for v in versions:
            mark = "".join(k.upper() for k in ("a", "b") if self.marks.get(k) == v.version)
            cells = [
                Text(str(v.version), justify="right"),
                Text(mark, style="bold"),
                v.created_utc[:19],
                Text(str(v.n_params), justify="right"),
            ]
            cells += [fmt.span(v.data_t0, v.data_t1) if math.isfinite(v.data_t0) else "—", v.note]
            versions_t.add_row(*cells, key=str(v.version))
        self._diff(path, diff_t)

    def _diff(self, path, table: DataTable) -> None:
        a, b = self.marks["a"], self.marks["b"]
        self.query_one("#diff-title", Label).update(f"Diff: version {a} → {b}  (Δ/σ: change in combined σ)")
        rows = jobs.scds_diff(path, a, b)
        vb = jobs.scds_version(path, b)
        va = jobs.scds_version(path, a)
        table.add_column("element")
        table.add_column("unit")
        # the newer version and the change first (what fits in 80 columns), the older after
        table.add_column(Text(f"v{b}", justify="right"))
        table.add_column(Text(f"Δ (v{b} − v{a})", justify="right"))
        table.add_column(Text("Δ/σ", justify="right"))
        table.add_column(Text(f"v{a}", justify="right"))
        for name, xa, xb, delta, z in rows:
            unit = (vb.params.get(name) or va.params.get(name))[2]
            sa = va.params[name][1] if name in va.params else math.nan
            sb = vb.params[name][1] if name in vb.params else math.nan
            ref_v, ref_s = (xb, sb) if math.isfinite(xb) else (xa, sa)
            shown = fmt.shown_unit(unit, ref_v, ref_s)
            big = math.isfinite(z) and abs(z) > 3

            def est(x, s, unit=unit, shown=shown):  # this row's units, bound
                return fmt.estimate(x, s, unit, shown=shown, with_unit=False) if math.isfinite(x) else "—"

            # Δ at the decimal place of the combined σ, like the estimates
            s_comb = math.hypot(sa, sb) if math.isfinite(sa) and math.isfinite(sb) else ref_s
            k = fmt.scale(unit, shown)
            d_text = (
                fmt.value_sigma(delta * k, s_comb * k)[0]
                if math.isfinite(delta)
                else "new"
                if math.isfinite(xb)
                else "gone"
            )
            cells = [
                name,
                Text(fmt.unit_column(shown)),
                Text(est(xb, sb), justify="right"),
                Text(d_text, justify="right"),
                Text(fmt.fixed(z, 1), justify="right", style=color("gcs-warn") if big else ""),
                Text(est(xa, sa), justify="right"),
            ]
            table.add_row(*cells, key=name)

    def action_mark(self, which: str) -> None:
        table = self.query_one("#versions", DataTable)
        if table.row_count == 0:
            return
        self.marks[which] = int(cursor_key(table))
        row = table.cursor_row
        self.refresh_view()
        table.move_cursor(row=row)
