"""The fleet report as one self-contained HTML page: inline CSS and inline SVG, no script,
no external asset (it opens from a mail attachment or an air-gapped share).

Sections: the run; one table row per spacecraft-day (state, fit status, goodness-of-fit
verdict, §4.4 flag, moved parameters, discovered effects, error); the malformed inputs; the
effects discovered; one trend plot per parameter (value ± 1σ per spacecraft over the days;
the spacecraft named as outliers or moved drawn in colour and labelled); each sensor type's
parameters across the fleet with the outliers named.
"""

from __future__ import annotations

import html
import math

__all__ = ["render_html", "trend_svg"]

CSS = """
body{font-family:sans-serif;margin:16px;color:#111;background:#fff}
h1{font-size:20px}h2{font-size:16px;margin-top:24px}
table{border-collapse:collapse;font-size:12px}
td,th{border:1px solid #999;padding:2px 6px;text-align:left;vertical-align:top}
th{background:#e8e8e8}
.ok{background:#d8f0d8}.flag{background:#f8e0a0}.err{background:#f4c0c0}
.plots{display:flex;flex-wrap:wrap;gap:8px}
figure{margin:0;border:1px solid #ccc;padding:4px}
figcaption{font-size:11px}
"""
WIDTH, HEIGHT = 360, 200
PAD_L, PAD_R, PAD_T, PAD_B = 70, 70, 12, 28
GREY = "#9a9a9a"
COLOURS = ("#c0392b", "#2166ac", "#1a9850", "#8e44ad", "#d35400", "#16a085")


def _e(x: object) -> str:
    return html.escape(str(x), quote=True)


def _num(x: float | None) -> str:
    if x is None or not math.isfinite(x):
        return "–"
    return f"{x:.4g}"


def _ticks(lo: float, hi: float, n: int = 4) -> list[float]:
    if not hi > lo:
        return [lo]
    step = 10 ** math.floor(math.log10((hi - lo) / n))
    for m in (1, 2, 5, 10):
        if (hi - lo) / (m * step) <= n:
            step *= m
            break
    start = math.ceil(lo / step) * step
    return [start + k * step for k in range(int((hi - start) / step) + 1)]


def trend_svg(name: str, trend: dict, days: list[str], marked: set[str]) -> str:
    """One parameter's trend over the days as an inline SVG (module docstring)."""
    series = trend["series"]
    pts = [(p[1], p[2]) for s in series.values() for p in s]
    lo = min(x - s for x, s in pts)
    hi = max(x + s for x, s in pts)
    if not hi > lo:
        lo, hi = lo - 1.0, hi + 1.0
    pad = 0.05 * (hi - lo)
    lo, hi = lo - pad, hi + pad
    w, h = WIDTH - PAD_L - PAD_R, HEIGHT - PAD_T - PAD_B
    nx = max(1, len(days) - 1)

    def X(day: str) -> float:
        return PAD_L + (days.index(day) / nx if len(days) > 1 else 0.5) * w

    def Y(v: float) -> float:
        return PAD_T + (hi - v) / (hi - lo) * h

    out = [
        f'<svg xmlns="http://www.w3.org/2000/svg" width="{WIDTH}" height="{HEIGHT}" role="img" '
        f'aria-label="trend of {_e(name)}">',
        f'<rect x="{PAD_L}" y="{PAD_T}" width="{w}" height="{h}" fill="#fff" stroke="#333"/>',
    ]
    for t in _ticks(lo, hi):
        y = Y(t)
        out.append(f'<line x1="{PAD_L - 4}" y1="{y:.1f}" x2="{PAD_L}" y2="{y:.1f}" stroke="#333"/>')
        out.append(f'<text x="{PAD_L - 6}" y="{y + 4:.1f}" font-size="10" text-anchor="end">{t:.4g}</text>')
    for d in days:
        out.append(f'<text x="{X(d):.1f}" y="{HEIGHT - 10}" font-size="10" text-anchor="middle">{_e(d)}</text>')
    ordered = sorted(series, key=lambda sc: sc in marked)  # marked ones drawn on top
    colour_of = {sc: COLOURS[i % len(COLOURS)] for i, sc in enumerate(sorted(marked & set(series)))}
    for sc in ordered:
        c = colour_of.get(sc, GREY)
        pts_sc = [(X(d), Y(x), s) for d, x, s in series[sc] if d in days]
        if len(pts_sc) > 1:
            path = " ".join(f"{x:.1f},{y:.1f}" for x, y, _ in pts_sc)
            out.append(f'<polyline points="{path}" fill="none" stroke="{c}" stroke-width="1.5"/>')
        for (x, y, _), (_, v, s) in zip(pts_sc, [p for p in series[sc] if p[0] in days]):
            y0, y1 = Y(v - s), Y(v + s)
            out.append(f'<line x1="{x:.1f}" y1="{y0:.1f}" x2="{x:.1f}" y2="{y1:.1f}" stroke="{c}"/>')
            out.append(f'<circle cx="{x:.1f}" cy="{y:.1f}" r="2.5" fill="{c}"><title>{_e(sc)}</title></circle>')
        if sc in colour_of and pts_sc:
            x, y, _ = pts_sc[-1]
            out.append(f'<text x="{x + 6:.1f}" y="{y + 4:.1f}" font-size="10" fill="{c}">{_e(sc)}</text>')
    out.append("</svg>")
    return "".join(out)


def _status_table(report: dict) -> list[str]:
    out = [
        "<table id='status'><tr><th>spacecraft</th><th>day</th><th>state</th><th>fit</th>"
        "<th>goodness of fit</th><th>§4.4 flag</th><th>moved (|z|)</th><th>discovered</th><th>error</th></tr>"
    ]
    for sc in report["spacecraft"]:
        for r in sc["days"]:
            err = r.get("error")
            flag = r.get("flag")
            cls = "err" if err else ("flag" if flag or r.get("adequate") is False or r.get("moved") else "ok")
            moved = ", ".join(f"{m['element']} ({abs(m['z']):.1f})" for m in r.get("moved", []))
            fit = "" if err else ("consistent with noise" if r.get("adequate") else "model inadequate")
            out.append(
                f"<tr class='{cls}'><td>{_e(sc['name'])}</td><td>{_e(r['day'])}</td><td>{_e(r['state'])}</td>"
                f"<td>{_e(r.get('status') or '')}</td><td title='{_e(r.get('verdict', ''))}'>{_e(fit)}</td>"
                f"<td title='{_e(r.get('flag_reason', ''))}'>"
                f"{'' if err else ('FLAG' if flag else ('ok' if flag is False else 'not verified'))}</td>"
                f"<td>{_e(moved)}</td><td>{_e(', '.join(r.get('discovered', [])))}</td><td>{_e(err or '')}</td></tr>"
            )
    out.append("</table>")
    return out


def _distribution_tables(report: dict) -> list[str]:
    out = []
    for stype, kinds in report["distributions"].items():
        out.append(
            f"<h3>{_e(stype)}</h3><table><tr><th>parameter</th><th>unit</th><th>n</th>"
            "<th>median</th><th>robust σ</th><th>outliers</th></tr>"
        )
        for kind, d in kinds.items():
            out.append(
                f"<tr class='{'flag' if d['outliers'] else 'ok'}'><td>{_e(kind)}</td><td>{_e(d['unit'])}</td>"
                f"<td>{d['n']}</td><td>{_num(d['median'])}</td><td>{_num(d['robust_sigma'])}</td>"
                f"<td>{_e(', '.join(d['outliers']))}</td></tr>"
            )
        out.append("</table>")
    return out


def _marked(report: dict) -> dict[str, set[str]]:
    """element -> the spacecraft to draw in colour (moved, or an outlier of its kind)."""
    out: dict[str, set[str]] = {}
    for m in report["moved"]:
        out.setdefault(m["element"], set()).add(m["spacecraft"])
    for kinds in report["distributions"].values():
        for kind, d in kinds.items():
            for o in d["outliers"]:
                sc, _, sensor = o.partition("/")
                out.setdefault(f"{sensor}.{kind}", set()).add(sc)
    return out


def render_html(report: dict) -> str:
    """The page (module docstring)."""
    days = report["days"]
    run = report.get("run")
    parts = [
        "<!DOCTYPE html><html lang='en'><head><meta charset='utf-8'>",
        f"<title>GCS fleet report: {_e(report['fleet'])}</title><style>{CSS}</style></head><body>",
        f"<h1>Fleet {_e(report['fleet'])}: {len(report['spacecraft'])} spacecraft, days {_e(', '.join(days))}</h1>",
        f"<p>generated {_e(report['generated_utc'])} from {_e(report['manifest'])}; moved: |Δ| beyond "
        f"{report['moved_sigma']:g} σ since the last accepted calibration; outliers: robust z beyond "
        f"{report['outlier_sigma']:g}.</p>",
    ]
    if run:
        parts.append(
            f"<p>run: {run['spacecraft_days']} spacecraft-days on {run['workers']} worker(s) in {run['wall_s']:.1f} s: "
            f"{run['calibrated']} calibrated, {run['completed']} completed, {run['already_done']} already done, "
            f"{run['errors']} errors.</p>"
        )
        if run.get("per_minute"):
            cpu = sum((run.get("worker_cpu_s") or {}).values())
            parts.append(
                f"<p>throughput: {run['per_minute']:.1f} spacecraft-days calibrated per minute of compute "
                f"({run['compute_s']:.1f} s); CPU: workers {cpu:.1f} s, submitter {run['submitter_cpu_s']:.1f} s "
                "(<code>benchmarks/fleet_throughput.py</code> measures the speed-up).</p>"
            )
    parts.append("<h2>Status</h2>")
    parts += _status_table(report)
    parts.append("<h2>Malformed inputs and failures</h2>")
    if report["errors"]:
        parts.append("<ul id='errors'>")
        parts += [f"<li>{_e(x['spacecraft'])} {_e(x['day'])}: {_e(x['error'])}</li>" for x in report["errors"]]
        parts.append("</ul>")
    else:
        parts.append("<p>none</p>")
    parts.append("<h2>Effects discovered</h2>")
    found = sorted({(d["spacecraft"], d["effect"]) for d in report["discovered"]})
    parts.append("<p>" + (_e("; ".join(f"{s}: {e}" for s, e in found)) or "none") + "</p>")
    parts.append("<h2>Trends</h2><div class='plots'>")
    marked = _marked(report)
    for name, t in report["trends"].items():
        parts.append(
            f"<figure>{trend_svg(name, t, days, marked.get(name, set()))}"
            f"<figcaption>{_e(name)} [{_e(t['unit'])}], ±1σ</figcaption></figure>"
        )
    parts.append("</div>")
    parts.append("<h2>Parameters across the fleet (latest day)</h2>")
    parts += _distribution_tables(report)
    parts.append("</body></html>")
    return "\n".join(parts)
