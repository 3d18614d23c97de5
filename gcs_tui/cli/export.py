"""Residual plots exported for reports: plain text (plotext) or one self-contained HTML page.

Each sensor and component gets one plot of its residuals against time (and, in the HTML
page, one against each auxiliary channel with its binned means), in the display
unit chosen from σ (:mod:`gcs_core.display`), with the ±3σ band; edited frames are drawn
apart (red ×). The HTML page holds inline SVG only — no script, no external file — so a
colleague can open it anywhere: every plot has a title, axes with round ticks, axis
labels with units, the shaded ±3σ band and a legend outside the data. The text plots are
plain characters (no terminal colour codes).
"""

from __future__ import annotations

import html
import re
from pathlib import Path

import numpy as np
import plotext as plt

from gcs_core import display
from gcs_core.fileperm import write_atomic_set
from gcs_tui.binning import Binned, binned_means, envelope

#: at most this many used (and as many edited) points are drawn in one SVG plot
MAX_SVG_POINTS = 1500

#: terminal escape sequences (plotext adds colour resets even with the "clear" theme)
_ANSI = re.compile(r"\x1b\[[0-9;?]*[A-Za-z]")


def text_plot(t, y, edited, sigma: float, title: str, unit: str, width: int = 100, height: int = 25) -> str:
    """A plain-text residual plot (no ANSI codes) with the ±3σ lines; ``y`` and ``sigma``
    in the display unit ``unit``."""
    plt.clear_figure()
    plt.plotsize(width, height)
    plt.theme("clear")
    used = ~edited
    plt.scatter(list(t[used]), list(y[used]), marker="dot")
    if np.any(edited):
        plt.scatter(list(t[edited]), list(np.clip(y[edited], -10 * sigma, 10 * sigma)), marker="x")
    if t.size:
        plt.hline(3.0 * sigma)
        plt.hline(-3.0 * sigma)
    plt.title(f"{title}   (· used, x edited, lines ±3σ)")
    plt.xlabel("t [s]")
    plt.ylabel(f"residual [{unit}]" if unit else "residual")
    return _ANSI.sub("", plt.build()).rstrip() + "\n"


def svg_plot(
    t,
    y,
    edited,
    sigma: float,
    title: str,
    unit: str,
    *,
    width: int = 900,
    height: int = 300,
    xlabel: str = "mission time t [s]",
    binned: Binned | None = None,
    max_points: int = MAX_SVG_POINTS,
) -> str:
    """One residual plot as inline SVG: title, axes, round ticks, labels with units, the
    shaded ±3σ band and a legend to the right of the data. ``y``, ``sigma`` in ``unit``;
    ``t`` the x values (time, or a channel named by ``xlabel``); ``binned``: the binned
    means with their standard errors, drawn over the points. At most ``max_points`` used
    and ``max_points`` edited points are drawn (their envelope, :func:`gcs_tui.binning.envelope`),
    which bounds the plot's size; the statistics in the title use every point."""
    esc = html.escape
    if t.size == 0:
        return f"<h2>{esc(title)}</h2><p>no data</p>"
    t, y, edited = np.asarray(t, dtype=float), np.asarray(y, dtype=float), np.asarray(edited, dtype=bool)
    for mask in (~edited, edited):  # decimate for display only
        idx = np.nonzero(mask)[0]
        drop = np.setdiff1d(idx, idx[envelope(idx.size, y[idx], max_points)])
        if drop.size:
            keep = np.ones(t.size, bool)
            keep[drop] = False
            t, y, edited = t[keep], y[keep], edited[keep]
    left, right, top, bottom = 80, 170, 20, 50  # margins: ticks left, legend right
    pw, ph = width - left - right, height - top - bottom
    finite = np.isfinite(y)
    spread = float(np.max(np.abs(y[finite & ~edited]))) if np.any(finite & ~edited) else 0.0
    lim = max(4.0 * sigma, 1.05 * spread, 1e-300)
    x0, x1 = float(np.nanmin(t)), float(np.nanmax(t))
    if x1 <= x0:
        x1 = x0 + 1.0
    sx = lambda v: left + (v - x0) / (x1 - x0) * pw
    sy = lambda v: top + (lim - v) / (2 * lim) * ph
    parts = [
        f'<svg xmlns="http://www.w3.org/2000/svg" width="{width}" height="{height}" '
        f'viewBox="0 0 {width} {height}" font-family="sans-serif" font-size="12">',
        f'<rect width="{width}" height="{height}" fill="white"/>',
        f'<rect x="{left}" y="{sy(3 * sigma):.1f}" width="{pw}" height="{sy(-3 * sigma) - sy(3 * sigma):.1f}" '
        'fill="#f5d5a0" fill-opacity="0.6"/>',
    ]
    for v in (3 * sigma, -3 * sigma):
        parts.append(
            f'<line x1="{left}" x2="{left + pw}" y1="{sy(v):.1f}" y2="{sy(v):.1f}" stroke="#d35400" '
            'stroke-dasharray="6 3"/>'
        )
    parts.append(f'<line x1="{left}" x2="{left + pw}" y1="{sy(0):.1f}" y2="{sy(0):.1f}" stroke="#999"/>')
    finite = np.isfinite(y) & np.isfinite(t)
    yc = np.clip(y, -lim, lim)
    for ti, yi in zip(t[~edited & finite], yc[~edited & finite]):
        parts.append(f'<circle cx="{sx(ti):.1f}" cy="{sy(yi):.1f}" r="1.3" fill="#1f4e79"/>')
    for ti, yi in zip(t[edited & finite], yc[edited & finite]):
        a, b = sx(ti), sy(yi)
        parts.append(
            f'<path d="M{a - 3:.1f},{b - 3:.1f}L{a + 3:.1f},{b + 3:.1f}M{a - 3:.1f},{b + 3:.1f}'
            f'L{a + 3:.1f},{b - 3:.1f}" stroke="#c0392b" stroke-width="1.5"/>'
        )
    if binned is not None:
        for c, m, e in zip(binned.centers, np.clip(binned.mean, -lim, lim), binned.err):
            parts.append(
                f'<line x1="{sx(c):.1f}" x2="{sx(c):.1f}" y1="{sy(min(m + e, lim)):.1f}" '
                f'y2="{sy(max(m - e, -lim)):.1f}" stroke="#117a65" stroke-width="2"/>'
                f'<circle cx="{sx(c):.1f}" cy="{sy(m):.1f}" r="4" fill="#117a65"/>'
            )
    # axes, ticks and labels
    parts.append(
        f'<rect x="{left}" y="{top}" width="{pw}" height="{ph}" fill="none" stroke="#222" '
        'shape-rendering="crispEdges"/>'
    )
    xt = display.nice_ticks(x0, x1, 7)
    for v, lab in zip(xt, display.tick_labels(xt)):
        parts.append(
            f'<line x1="{sx(v):.1f}" x2="{sx(v):.1f}" y1="{top + ph}" y2="{top + ph + 5}" stroke="#333"/>'
            f'<text x="{sx(v):.1f}" y="{top + ph + 18}" text-anchor="middle">{esc(lab)}</text>'
        )
    yt = display.nice_ticks(-lim, lim, 7)
    for v, lab in zip(yt, display.tick_labels(yt)):
        parts.append(
            f'<line x1="{left - 5}" x2="{left}" y1="{sy(v):.1f}" y2="{sy(v):.1f}" stroke="#333"/>'
            f'<text x="{left - 8}" y="{sy(v) + 4:.1f}" text-anchor="end">{esc(lab)}</text>'
        )
    parts.append(f'<text x="{left + pw / 2}" y="{height - 10}" text-anchor="middle">{esc(xlabel)}</text>')
    ylab = f"residual [{unit}]" if unit else "residual"
    parts.append(f'<text transform="translate(18,{top + ph / 2}) rotate(-90)" text-anchor="middle">{esc(ylab)}</text>')
    # legend, outside the data (right margin)
    lx, ly = left + pw + 15, top + 10
    parts.append(
        f'<circle cx="{lx + 6}" cy="{ly}" r="3" fill="#1f4e79"/>'
        f'<text x="{lx + 16}" y="{ly + 4}">used</text>'
        f'<path d="M{lx + 3},{ly + 17}L{lx + 9},{ly + 23}M{lx + 3},{ly + 23}L{lx + 9},{ly + 17}" '
        f'stroke="#c0392b" stroke-width="1.5"/><text x="{lx + 16}" y="{ly + 24}">edited</text>'
        f'<rect x="{lx}" y="{ly + 33}" width="12" height="10" fill="#f5d5a0" stroke="#d35400" '
        f'stroke-dasharray="3 2"/><text x="{lx + 16}" y="{ly + 42}">±3σ band</text>'
        f'<text x="{lx}" y="{ly + 62}">σ = {esc(display.sig(sigma, 2))} {esc(unit)}</text>'
    )
    if binned is not None:
        parts.append(
            f'<circle cx="{lx + 6}" cy="{ly + 80}" r="4" fill="#117a65"/>'
            f'<text x="{lx + 16}" y="{ly + 84}">bin mean ± s.e.</text>'
        )
    parts.append("</svg>")
    return f"<h2>{esc(title)}</h2>\n<figure>{''.join(parts)}</figure>"


def channel_plots(analysis, name: str, comp: str, sel, y, edited, sigma: float, unit: str) -> list[str]:
    """The residual of ``name`` ``comp`` against each auxiliary channel, with its binned means
    (a dependence hidden under the scatter shows as a trend of the means)."""
    try:
        aux = analysis.problem.sensor(name).geom.aux
    except (AttributeError, KeyError):
        return []
    out = []
    for channel, values in sorted(aux.items()):
        x = np.asarray(values, dtype=float)
        if x.shape[0] != np.asarray(sel).shape[0]:
            continue
        x = x[sel]
        ok = ~edited & np.isfinite(x) & np.isfinite(y)
        binned = binned_means(x[ok], y[ok], sigma)
        cu = display.aux_unit(channel)
        title = f"{name} {comp}: residual against {channel} (binned means ± standard error)"
        xlabel = f"{channel} [{cu}]" if cu else f"{channel} (unit as in aux.csv)"
        out.append(svg_plot(x, y, edited, sigma, title, unit, xlabel=xlabel, binned=binned))
    return out


def export_residual_plots(analysis, folder: Path, *, fmt: str = "txt") -> list[Path]:
    """Write one plot per sensor component (txt) or one HTML page (html); returns paths.
    The plots are written as a set (:func:`gcs_core.fileperm.write_atomic_set`)."""
    folder = Path(folder)
    folder.mkdir(parents=True, exist_ok=True)
    files: list[tuple[Path, str]] = []
    sections = []
    for name, r in analysis.result.residuals.items():
        sel = r.valid
        sig_all = np.atleast_1d(np.asarray(r.sigma, dtype=float))
        finite = sig_all[np.isfinite(sig_all)]
        shown = display.display_unit(r.unit, float(np.max(finite)) if finite.size else float("nan"))
        k = display.scale(r.unit, shown)
        unit = display.unit_label(shown)
        for j, comp in enumerate(r.components):
            t, ed = r.t[sel], r.edited[sel]
            y = r.residual[sel, j] * k
            sigma = float(sig_all[j if sig_all.size > 1 else 0]) * k
            title = (
                f"{name} {comp}: residual against time (normalized RMS {r.rms_normalized:.3f}, "
                f"n {int(np.count_nonzero(~ed))}, edited {int(np.count_nonzero(ed))})"
            )
            if fmt == "txt":
                files.append((folder / f"residuals_{name}_{comp}.txt", text_plot(t, y, ed, sigma, title, unit)))
            else:
                sections.append(svg_plot(t, y, ed, sigma, title, unit))
                sections += channel_plots(analysis, name, comp, sel, y, ed, sigma, unit)
    if fmt == "html":
        p = folder / "residuals.html"
        name = html.escape(analysis.mission.spec.name)
        page = (
            "<!doctype html>\n<html lang='en'><head><meta charset='utf-8'>"
            f"<title>GCS residuals — {name}</title>"
            "<style>body{font-family:sans-serif;margin:2em;max-width:960px}h2{font-size:1.05em;"
            "margin:1.5em 0 .3em}figure{margin:0}</style></head><body>"
            f"<h1>Residuals: {name}</h1><p>Post-fit residual (measured − modelled) of every sensor "
            "component against mission time, in the unit chosen from its σ; the shaded band is ±3σ "
            "of the sensor's noise; red × marks frames edited out of the fit.</p>\n"
            + "\n".join(sections)
            + "\n</body></html>\n"
        )
        files.append((p, page))
    return write_atomic_set(files)  # all or none: a full disk leaves no partial set
