"""Residuals: per sensor and component against time, orbit angle, a measured
component (position in the field of view) or an auxiliary channel, with the ±3σ band;
histogram and autocorrelation of the normalized residuals; normalized RMS per sensor
(1.0 = the noise floor). Edited frames are drawn apart (orange ×) and never hidden.

Against anything but time the plot adds the binned mean with its standard error
(a dependence hidden under the scatter shows as a trend of the means), and, when the
candidate selected on the Diagnosis screen is linear in the plotted channel, its
first-order fitted line (slope = the candidate's estimate). Legends sit in the title
line, outside the data.
"""

from __future__ import annotations

import math

import numpy as np
from rich.text import Text
from textual.app import ComposeResult
from textual.containers import Horizontal, Vertical, VerticalScroll
from textual.widgets import DataTable, Static

from gcs_core import display as fmt
from gcs_tui.tui import derive
from gcs_tui.tui.keys import SCREENS, bindings
from gcs_tui.tui.screens.base import GcsScreen
from gcs_tui.tui.theme import color, rgb
from gcs_tui.tui.widgets.plots import GcsPlot, marked_line

KINDS = ("residual", "histogram", "autocorrelation")
#: normalized RMS above this is flagged (5 % above the noise floor)
RMS_LIMIT = 1.05
#: at most this many used points are drawn per plot (every edited point is drawn)
MAX_POINTS = 4000


def x_axes(sd, shown_unit: str, unit: str, orbit=None) -> list[tuple[str, str, np.ndarray]]:
    """``(name, axis label, values (N,))`` a sensor's residuals can be plotted against.

    ``orbit`` (``t -> (r_I, v_I)``) gives the spacecraft state when the prepared geometry
    does not keep it (it does not, to save memory on long spans).
    """
    g = sd.geom
    out = [("time", "t [s]", sd.t)]
    r_I, v_I = g.r_I, g.v_I
    if (r_I is None or v_I is None) and orbit is not None:
        r_I, v_I = orbit(sd.t)
    if r_I is not None and v_I is not None:
        out.append(("orbit angle", "argument of latitude [deg]", derive.argument_of_latitude(r_I, v_I)))
    k = fmt.scale(unit, shown_unit)
    for j, comp in enumerate(sd.model.components):
        vals = sd.y[:, j] * k
        label = fmt.unit_label(shown_unit)
        out.append((f"measured {comp}", f"measured {comp}" + (f" [{label}]" if label else ""), vals))
    for name, values in sorted(g.aux.items()):
        u = derive.aux_unit(name)
        out.append(
            (f"aux {name}", f"{name} [{u}]" if u else f"{name} (unit as in aux.csv)", np.asarray(values, dtype=float))
        )
    return out


def candidate_line(cand, sensor: str, comp: str, xname: str, unit: str, shown: str):
    """``(slope in display units per channel unit, label)`` of a candidate linear in the
    plotted auxiliary channel (a contamination ``k·channel``), else None."""
    if cand is None or not xname.startswith("aux "):
        return None
    channel = xname[4:]
    # the elements are named by axis (``_x``), the components may carry a prefix (``bx``)
    name = next(
        (
            n
            for n in (f"{sensor}.contam_{channel}_{comp}", f"{sensor}.contam_{channel}_{comp[-1:]}")
            if n in cand.estimate
        ),
        None,
    )
    if name is None:
        return None
    return fmt.scale(unit, shown) * float(cand.estimate[name]), f"{cand.id} (its estimate × {channel})"


class ResidualsScreen(GcsScreen):
    """Residual plots and the normalized RMS table."""

    VIEW = "residuals"
    CSS_PATH = "residuals.tcss"
    BINDINGS = bindings(SCREENS["residuals"])
    NEEDS_FIT = True

    def __init__(self) -> None:
        super().__init__()
        self.sensor_i = 0
        self.comp_i = 0
        self.x_i = 0
        self.kind_i = 0

    def compose_body(self) -> ComposeResult:
        yield Static("", id="res-info", markup=False)
        with Horizontal(id="res-top"):
            yield GcsPlot(id="res-main", title="residuals")
            with VerticalScroll(id="res-bins-box"):
                yield Static("", id="res-bins", markup=False)
        with Horizontal(id="res-lower"):
            yield GcsPlot(id="res-hist", title="histogram")
            yield GcsPlot(id="res-acf", title="autocorrelation")
            with Vertical(id="res-table-box"):
                yield DataTable(id="rms", cursor_type="row", zebra_stripes=True, show_cursor=False)

    # ------------------------------------------------------------------ data
    def _sensors(self) -> list[str]:
        return list(self.wb.result.residuals)

    def _current(self):
        names = self._sensors()
        self.sensor_i %= max(len(names), 1)
        name = names[self.sensor_i]
        r = self.wb.result.residuals[name]
        self.comp_i %= max(len(r.components), 1)
        return name, r, self.wb.analysis.problem.sensor(name)

    def on_screen_resume(self) -> None:
        # the candidate selected on Diagnosis changes what the channel plot draws
        if getattr(self, "_drawn_for", None) != self.app.selected_candidate and self.wb.result is not None:
            self.update_view(force=True)
        super().on_screen_resume()

    # ------------------------------------------------------------------ drawing
    def refresh_view(self) -> None:
        self._drawn_for = self.app.selected_candidate
        name, r, sd = self._current()
        j = self.comp_i
        shown = fmt.display_unit(r.unit, float(np.nanmax(np.abs(r.sigma))) if r.sigma.size else 0.0)
        axes = x_axes(sd, shown, r.unit, orbit=self.wb.analysis.problem.builder.orbit)
        self.x_i %= len(axes)
        xname, xlabel, xvals = axes[self.x_i]
        kind = KINDS[self.kind_i]
        res = self.wb.result
        n_edit = int(np.count_nonzero(r.edited))
        ho = self.wb.analysis.holdout_rms.get(name, float("nan"))
        self.query_one("#res-info", Static).update(
            Text.assemble(
                (f" {name}", "bold"),
                f" ({self.sensor_i + 1}/{len(self._sensors())}) · ",
                (r.components[j], "bold"),
                f" · {kind}" + (f" vs {xname}" if kind == "residual" else ""),
                " · normalized RMS ",
                (
                    fmt.fixed(r.rms_normalized, 3),
                    f"bold {color('gcs-bad' if r.rms_normalized > RMS_LIMIT else 'gcs-ok')}",
                ),
                f" · held-out {fmt.fixed(ho, 3)} · n {r.n} · edited {n_edit}",
                *self._verdict(res),
            )
        )
        z = r.normalized[:, j]
        resid = r.residual[:, j] * fmt.scale(r.unit, shown)
        sigma = fmt.to_display(float(r.sigma[j]), r.unit, shown)
        lab = fmt.unit_label(shown)
        title = f"{name} {r.components[j]}" + (f" [{lab}]" if lab else "")
        main = self.query_one("#res-main", GcsPlot)
        self._bins(kind == "residual" and xname != "time", xvals, resid, sigma, r.used, xlabel, lab)
        if kind == "residual":
            cands = {c.id: c for c in self.wb.analysis.candidates}
            line = candidate_line(cands.get(self.app.selected_candidate), name, r.components[j], xname, r.unit, shown)
            binned = xname != "time"
            main.paint(
                lambda plt: self._scatter(
                    plt,
                    xvals,
                    resid,
                    sigma,
                    r.used,
                    r.edited,
                    title,
                    xlabel,
                    binned=binned,
                    line=line,
                    orbit=xname == "orbit angle",
                )
            )
        elif kind == "histogram":
            main.paint(lambda plt: self._hist(plt, z[r.used], f"{title}: normalized"))
        else:
            main.paint(lambda plt: self._acf(plt, z[r.used], f"{title}: normalized"))
        self.query_one("#res-hist", GcsPlot).paint(lambda plt: self._hist(plt, z[r.used], "histogram (z)"))
        self.query_one("#res-acf", GcsPlot).paint(lambda plt: self._acf(plt, z[r.used], "autocorrelation (z)"))
        self._table()

    def _bins(self, show: bool, x, y, sigma: float, used, xlabel: str, unit: str) -> None:
        """The binned means as numbers beside the plot (a step of a few units on a wide
        axis is one row of the plot; the numbers show it whatever the size)."""
        box = self.query_one("#res-bins-box", VerticalScroll)
        box.display = show
        if not show:
            return
        ok = used & np.isfinite(y) & np.isfinite(x)
        b = derive.binned_means(x[ok], y[ok], sigma)
        channel = xlabel.split(" [")[0]
        lines = [f"mean ± s.e. [{unit}]" if unit else "mean ± s.e.", f"per bin of {channel}:"]
        for c, m, e in zip(b.centers, b.mean, b.err):
            vs, ss = fmt.value_sigma(float(m), float(e))  # digits from the standard error
            lines.append(f"{fmt.sig(float(c), 3):>7} {vs:>6} ± {ss}")
        self.query_one("#res-bins", Static).update("\n".join(lines))

    def _verdict(self, res) -> tuple:
        """The fit's χ² per dof and its goodness-of-fit verdict, short (gcs_core.diagnosis.goodness)."""
        g = self.wb.goodness()
        if g is None:
            return (f" · χ²/dof {res.chi2 / max(res.dof, 1):.3f}",)
        p = g.fit.p_value
        head = f" · χ²/dof {g.fit.reduced:.3f} (p {p:.2g}) · " if math.isfinite(p) else " · "
        if g.adequate:
            return (head, ("consistent with noise", color("gcs-ok")))
        worst = g.failing()[0][1].label
        return (head, (f"model inadequate (worst {worst})", f"bold {color('gcs-bad')}"))

    def _table(self) -> None:
        wb = self.wb
        table = self.query_one("#rms", DataTable)
        table.clear(columns=True)
        table.add_column("sensor")
        table.add_column(Text("norm RMS", justify="right"))
        table.add_column(Text("held-out", justify="right"))
        table.add_column(Text("n", justify="right"))
        table.add_column(Text("edited", justify="right"))
        table.add_column(Text("RMS", justify="right"))
        for name, r in wb.result.residuals.items():
            bad = r.rms_normalized > RMS_LIMIT
            cells = [
                Text(name, style="bold" if self._sensors().index(name) == self.sensor_i else ""),
                Text(fmt.fixed(r.rms_normalized, 3), justify="right", style=color("gcs-bad" if bad else "gcs-ok")),
                Text(fmt.fixed(wb.analysis.holdout_rms.get(name, float("nan")), 3), justify="right"),
                Text(str(r.n), justify="right"),
                Text(
                    str(int(np.count_nonzero(r.edited))),
                    justify="right",
                    style=color("gcs-edited") if np.any(r.edited) else "",
                ),
            ]
            rms = np.atleast_1d(r.rms)
            shown = fmt.display_unit(r.unit, float(np.nanmax(rms)) if rms.size else 0.0)
            vals = "/".join(fmt.sig(fmt.to_display(v, r.unit, shown), 2) for v in rms)
            cells.append(Text(f"{vals} {fmt.unit_label(shown)}".rstrip(), justify="right"))
            table.add_row(*cells, key=name)

    @staticmethod
    def _scatter(plt, x, y, sigma, used, edited, title, xlabel, *, binned=False, line=None, orbit=False) -> None:
        ok = used & np.isfinite(y) & np.isfinite(x)
        all_used = np.nonzero(ok)[0]
        idx = all_used[derive.thin(all_used.size, MAX_POINTS)]
        plt.scatter(x[idx].tolist(), y[idx].tolist(), marker="braille", color=rgb("gcs-used"))
        ed = np.nonzero(edited & np.isfinite(y) & np.isfinite(x))[0]
        lim = 4.0 * sigma
        if idx.size:
            lim = max(lim, 1.1 * derive.spread(y[idx]))
        legend = ["⠿ used"]
        if ed.size:
            plt.scatter(x[ed].tolist(), np.clip(y[ed], -lim, lim).tolist(), marker="x", color=rgb("gcs-edited"))
            legend.append("x edited")
        if line is not None and all_used.size:
            slope, label = line
            x0, x1 = float(np.min(x[all_used])), float(np.max(x[all_used]))
            xs = np.linspace(x0, x1, 41)
            marked_line(plt, xs.tolist(), (slope * xs).tolist(), rgb("gcs-warn"), "■", marks=6)
            xlabel = f"{xlabel} · ■ {label}"
        if binned and all_used.size:
            b = derive.binned_means(x[all_used], y[all_used], sigma)
            plt.error(b.centers.tolist(), b.mean.tolist(), yerr=b.err.tolist(), color=rgb("gcs-holdout"))
            plt.scatter(b.centers.tolist(), b.mean.tolist(), marker="●", color=rgb("gcs-holdout"))
            legend.append("● mean ± s.e.")
        if idx.size or ed.size:
            plt.horizontal_line(3 * sigma, color=rgb("gcs-band"))
            plt.horizontal_line(-3 * sigma, color=rgb("gcs-band"))
            plt.ylim(-lim, lim)
            ticks = fmt.nice_ticks(-lim, lim, 5)
            plt.yticks(ticks, fmt.tick_labels(ticks))
        if orbit:
            plt.xlim(0, 360)
            plt.xticks([0, 90, 180, 270, 360], ["0", "90", "180", "270", "360"])
        elif idx.size:
            lo, hi = float(np.min(x[idx])), float(np.max(x[idx]))
            ticks = fmt.nice_ticks(lo, hi, 6)
            if len(ticks) >= 2:
                plt.xticks(ticks, fmt.tick_labels(ticks))
        plt.title(f"{title} · ── ±3σ · " + " · ".join(legend))
        plt.xlabel(xlabel)

    @staticmethod
    def _hist(plt, z, title) -> None:
        h = derive.histogram(z)
        plt.bar(h.centers.tolist(), h.counts.tolist(), color=rgb("gcs-used"), width=0.8)
        plt.plot(h.centers.tolist(), h.expected.tolist(), color=rgb("gcs-band"), marker="●")
        plt.xticks([-4, -2, 0, 2, 4], ["-4", "-2", "0", "2", "4"])
        top = float(max(np.max(h.counts), np.max(h.expected))) if h.counts.size else 1.0
        ticks = fmt.nice_ticks(0.0, top, 4)
        plt.ylim(0, max(top, 1.0) * 1.05)
        plt.yticks(ticks, fmt.tick_labels(ticks))
        plt.title(f"{title} · ● N(0,1)")
        plt.xlabel("residual / σ")

    @staticmethod
    def _acf(plt, z, title) -> None:
        lags, acf, band = derive.autocorrelation(z, 40)
        plt.plot(lags.tolist(), acf.tolist(), color=rgb("gcs-used"), marker="dot")
        if np.isfinite(band):
            plt.horizontal_line(band, color=rgb("gcs-band"))
            plt.horizontal_line(-band, color=rgb("gcs-band"))
        plt.ylim(-1.0, 1.0)
        plt.title(title)
        plt.xlabel("lag [samples]")

    # ------------------------------------------------------------------ actions
    def action_sensor(self, step: int) -> None:
        self.sensor_i = (self.sensor_i + step) % max(len(self._sensors()), 1)
        self.comp_i = 0
        self.x_i = min(self.x_i, 1)
        self.refresh_view()

    def action_component(self) -> None:
        self.comp_i += 1
        self.refresh_view()

    def action_xaxis(self) -> None:
        self.x_i += 1
        self.kind_i = 0
        self.refresh_view()

    def action_view_kind(self) -> None:
        self.kind_i = (self.kind_i + 1) % len(KINDS)
        self.refresh_view()
