"""Plots of trade studies and Monte Carlo as text: σ against one varied key, a heat map
for two, and the Monte-Carlo scatter against the predicted σ."""

from __future__ import annotations

import math
import re
from collections.abc import Sequence

import numpy as np
import plotext as plt

from gcs_core.trade.report import sigma_display
from gcs_core.trade.run import sigma_grid

#: shades of a text heat map, light (small σ) to dark (large σ)
SHADES = " .:-=+*#%@"
_ANSI = re.compile(r"\x1b\[[0-9;]*m")


def _plain(text: str) -> str:
    """plotext's text without its terminal colour codes (the plot goes to a file)."""
    return _ANSI.sub("", text)


def _numeric(values) -> bool:
    return all(isinstance(v, (int, float)) and not isinstance(v, bool) for v in values)


def study_plot(rows: Sequence, keys: tuple[str, ...], *, width: int = 100, height: int = 24) -> str:
    """σ of every target element against the first varied key (the best over the other
    keys), or, for two or more keys, one heat map per element over the first two."""
    ok = [r for r in rows if r.status == "ok"]
    if not ok or not keys:
        return "no plans to plot\n"
    r0 = ok[0]
    out = []
    for name, unit in zip(r0.elements, r0.units):
        if len(keys) >= 2:
            out.append(heat_map(ok, name, unit, (keys[0], keys[1])))
            continue
        v1, _, G = sigma_grid(ok, name, keys[:1])
        y = [sigma_display(float(g), unit)[0] for g in G[:, 0]]
        plt.clear_figure()
        plt.plotsize(width, height)
        plt.theme("clear")
        x = v1 if _numeric(v1) else list(range(len(v1)))
        fin = [(a, b) for a, b in zip(x, y) if math.isfinite(b)]
        if fin:
            plt.plot([a for a, _ in fin], [b for _, b in fin], marker="dot")
        if not _numeric(v1):
            plt.xticks(x, [str(v) for v in v1])
        plt.title(f"σ {name}{_unit(unit)} against {keys[0]}")
        plt.xlabel(keys[0])
        out.append(_plain(plt.build()))
    return "\n\n".join(out) + "\n"


def _unit(unit: str) -> str:
    """`` [label]`` of the display unit, nothing for a dimensionless element."""
    label = sigma_display(1.0, unit)[1]
    return f" [{label}]" if label else ""


def heat_map(rows: Sequence, name: str, unit: str, keys: tuple[str, str]) -> str:
    """A text heat map of σ over two keys (log shades; the best over any other keys)."""
    v1, v2, G = sigma_grid(rows, name, keys)
    disp = np.array([[sigma_display(float(g), unit)[0] for g in row] for row in G])
    fin = disp[np.isfinite(disp) & (disp > 0)]
    lo, hi = (float(fin.min()), float(fin.max())) if fin.size else (1.0, 1.0)
    span = math.log(hi / lo) if hi > lo else 1.0
    lines = [
        f"σ {name}{_unit(unit)}: rows {keys[0]}, columns {keys[1]}; "
        f"shade '{SHADES[1]}' {lo:.3g} … '{SHADES[-1]}' {hi:.3g}, '?' not determined"
    ]
    w = max(6, *(len(str(v)) for v in v2))
    lines.append(" " * 12 + "".join(str(v).rjust(w + 1) for v in v2))
    for i, a in enumerate(v1):
        cells = []
        for j in range(len(v2)):
            d = disp[i, j]
            if not math.isfinite(d):
                cells.append("?".rjust(w + 1))
                continue
            k = 1 + int(round((len(SHADES) - 2) * (math.log(d / lo) / span if span else 0.0)))
            cells.append(f"{SHADES[k] * 2}{d:.3g}".rjust(w + 1))
        lines.append(str(a).rjust(12) + "".join(cells))
    return "\n".join(lines)


def montecarlo_plot(result, *, width: int = 100, height: int = 22) -> str:
    """Ratio Monte-Carlo scatter / predicted σ per element the plan determines, with the
    15 % band."""
    keep = [k for k in range(len(result.names)) if result.determined[k]]
    names = [result.names[k] for k in keep]
    ratio = [float(result.ratio[k]) if math.isfinite(result.ratio[k]) else 0.0 for k in keep]
    plt.clear_figure()
    plt.plotsize(width, height)
    plt.theme("clear")
    plt.bar(list(range(len(names))), ratio, width=0.4)
    plt.hline(1.15)
    plt.hline(0.85)
    plt.xticks(list(range(len(names))), [n.split(".")[-1] for n in names])
    plt.title(f"Monte-Carlo scatter / predicted σ ({result.runs} runs; lines: ±15 %)")
    return _plain(plt.build()) + "\n"
