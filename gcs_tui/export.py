"""Residual plots exported for reports: plain text (plotext) or a self-contained HTML page.

Each sensor and component gets one plot of normalized residuals against time with the
±3σ band (±3 in normalized units); edited frames are drawn apart.
"""

from __future__ import annotations

import html
import os
import tempfile
from pathlib import Path

import numpy as np
import plotext as plt

from gcs_core.fileperm import make_usual


def _atomic_write(path: Path, text: str) -> None:
    fd, tmp = tempfile.mkstemp(dir=path.parent, prefix=f".{path.name}.", suffix=".tmp")
    with os.fdopen(fd, "w", encoding="utf-8") as fh:
        fh.write(text)
    make_usual(tmp)
    os.replace(tmp, path)


def text_plot(t, z, edited, title: str, width: int = 100, height: int = 25) -> str:
    plt.clear_figure()
    plt.plotsize(width, height)
    plt.theme("clear")
    used = ~edited
    plt.scatter(list(t[used]), list(z[used]), marker="dot", label="used")
    if np.any(edited):
        plt.scatter(list(t[edited]), list(np.clip(z[edited], -10, 10)), marker="x", label="edited")
    if t.size:
        plt.hline(3.0)
        plt.hline(-3.0)
    plt.title(title)
    plt.xlabel("t [s]")
    plt.ylabel("residual / σ")
    return plt.build()


def svg_plot(t, z, edited, title: str, width: int = 900, height: int = 260) -> str:
    if t.size == 0:
        return f"<p>{html.escape(title)}: no data</p>"
    lim = max(4.0, float(np.nanmax(np.abs(np.clip(z, -10, 10)))) * 1.05)
    x0, x1 = float(t.min()), float(t.max()) or 1.0
    sx = lambda v: 40 + (v - x0) / max(x1 - x0, 1e-9) * (width - 60)
    sy = lambda v: height / 2 - v / lim * (height / 2 - 20)
    pts = []
    for ti, zi, ei in zip(t, np.clip(z, -lim, lim), edited):
        colour = "#c0392b" if ei else "#2c3e50"
        pts.append(f'<circle cx="{sx(ti):.1f}" cy="{sy(zi):.1f}" r="1.2" fill="{colour}"/>')
    band = "".join(f'<line x1="40" x2="{width - 20}" y1="{sy(v):.1f}" y2="{sy(v):.1f}" '
                   f'stroke="#e67e22" stroke-dasharray="4"/>' for v in (3.0, -3.0))
    return (f'<h3>{html.escape(title)}</h3><svg xmlns="http://www.w3.org/2000/svg" width="{width}" '
            f'height="{height}"><rect width="100%" height="100%" fill="white" stroke="#ccc"/>'
            f'<line x1="40" x2="{width - 20}" y1="{sy(0):.1f}" y2="{sy(0):.1f}" stroke="#999"/>'
            f'{band}{"".join(pts)}</svg>')


def export_residual_plots(analysis, folder: Path, *, fmt: str = "txt") -> list[Path]:
    """Write one plot per sensor component (txt) or one HTML page (html); returns paths."""
    folder = Path(folder)
    folder.mkdir(parents=True, exist_ok=True)
    out: list[Path] = []
    sections = []
    for name, r in analysis.result.residuals.items():
        sel = r.valid
        for j, comp in enumerate(r.components):
            t, z, ed = r.t[sel], r.normalized[sel, j], r.edited[sel]
            title = f"{name} {comp}: normalized RMS {r.rms_normalized:.3f}"
            if fmt == "txt":
                p = folder / f"residuals_{name}_{comp}.txt"
                _atomic_write(p, text_plot(t, z, ed, title))
                out.append(p)
            else:
                sections.append(svg_plot(t, z, ed, title))
    if fmt == "html":
        p = folder / "residuals.html"
        page = ("<!doctype html><html><head><meta charset='utf-8'><title>GCS residuals — "
                f"{html.escape(analysis.mission.spec.name)}</title></head><body>"
                f"<h1>Residuals: {html.escape(analysis.mission.spec.name)}</h1>{''.join(sections)}</body></html>")
        _atomic_write(p, page)
        out.append(p)
    return out
