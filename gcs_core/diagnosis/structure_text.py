"""Sentences for the residual-structure search (the CLI prints them, the TUI lists them).

``FHST2 h follows tam_temp: −19″ at 19.1 °C … +20″ at 24.9 °C (p adj < 1e-16, 31 % of
its variance); also the orbit phase (same period); a family holds it: alignment_vs_tam_temp``.
"""

from __future__ import annotations

from gcs_core import display
from gcs_core.diagnosis.channels import aux_unit
from gcs_core.diagnosis.structure import ALIAS_R2, Dependency, StructureReport, strongest
from gcs_core.units import DEG

#: channel kinds whose form a generic family holds (:mod:`gcs_core.diagnosis.families`)
FAMILY_KINDS = ("aux", "orbit", "sun", "eclipse", "time", "aux_integral")


def residual_text(value: float, unit: str, spread: float) -> str:
    """A residual in the sensor's unit, by the display rule (arcsec for small angles)."""
    shown = display.display_unit(unit, spread)
    v = display.to_display(value, unit, shown)
    lab = display.unit_label(shown)
    lab = "″" if lab == "arcsec" else (" " + lab if lab else "")
    return f"{display.sig(v, 2)}{lab}".replace("-", "−")


def channel_text(value: float, d: Dependency) -> str:
    """A channel's value as the analyst reads it (degrees for an angle, hours for time)."""
    if d.channel_unit == "rad":
        return f"{value / DEG:.0f}°"
    if d.channel_unit == "rad/s":  # deg/h, a body rate from 1°/s in deg/s (the display rule)
        shown = display.shown_unit("rad/s", value)
        return f"{display.sig(display.to_display(value, 'rad/s', shown), 2)} {shown}"
    if d.kind == "aux_integral":  # a switch's time integral: seconds on
        return f"{display.sig(value, 2)} s"
    if d.channel_unit == "s":
        return f"{value / 3600.0:.1f} h"
    if d.channel_unit == "1":
        return display.sig(value, 3)
    unit = aux_unit(d.label) if d.kind == "aux" else d.channel_unit
    return f"{display.sig(value, 3)} {unit}" if not unit.startswith("unit of") else display.sig(value, 3)


def label(channel: str) -> str:
    if channel.startswith("int:"):  # the time integral of a switch
        return f"∫{channel[4:]} dt"
    return channel.split(":", 1)[1] if ":" in channel else channel.replace("_", " ")


def dependency_line(d: Dependency, offered: tuple[str, ...] = ()) -> str:
    """One finding as a sentence (module docstring)."""
    lo, hi = int(d.means.argmin()), int(d.means.argmax())
    spread = float(abs(d.means).max()) if d.means.size else float("nan")
    first, last = (lo, hi) if d.centers[lo] <= d.centers[hi] else (hi, lo)
    text = (
        f"{d.sensor} {d.component} follows {label(d.channel)}: "
        f"{residual_text(float(d.means[first]), d.unit, spread)} at {channel_text(float(d.centers[first]), d)} … "
        f"{residual_text(float(d.means[last]), d.unit, spread)} at {channel_text(float(d.centers[last]), d)} "
        f"({display.p_text(d.p_adjusted, 'p adj')}, "
        + (
            f"{100 * d.share:.0f} % of its variance)"
            if d.share == d.share
            else f"score test χ² {display.sig(d.F * d.dof[0], 3)} on {d.dof[0]:.0f} dof)"  # the gyro's
        )
    )
    if d.aliases:
        text += "; also " + ", ".join(label(a) for a in d.aliases) + " (aliases: they follow one another here)"
    if d.catalogue:
        text += "; catalogue effects of this form: " + ", ".join(d.catalogue)
    fams = [f for f in offered if _family_on(f, d)]
    if fams:
        text += "; families holding it: " + ", ".join(fams)
    elif d.kind not in FAMILY_KINDS and not d.catalogue:
        text += "; no catalogue effect or family has this form"
    return text


def _family_on(effect: str, d: Dependency) -> bool:
    from gcs_core.diagnosis.families import channel_of

    ch = channel_of(effect.split(".", 1)[1] if "." in effect else effect)
    if ch is not None and d.kind == "aux_integral":
        return "." in effect and d.channel == "int:" + ch.removeprefix("aux:")
    return ch is not None and (ch == d.channel or ch in d.aliases)


def report_lines(report: StructureReport | None, offered: dict | None = None, *, per_sensor: int = 3) -> list[str]:
    """What the residuals of the searched sensors follow; a line per sensor without finding."""
    if report is None or not report.searched:
        return []
    offered = offered or {}
    out = [
        f"residual structure ({report.tests} tests, family-wise α = {report.alpha:g}; "
        + ", ".join(f"{s}: {why}" for s, why in report.searched.items())
        + "):"
    ]
    for sensor in report.searched:
        deps = strongest(report.found, sensor)[:per_sensor]
        if not deps:
            best = report.best.get(sensor, ())
            tail = (
                f" (strongest: {label(best[0].channel)}, {display.p_text(best[0].p_adjusted, 'p adj')})" if best else ""
            )
            out.append(f"  {sensor}: follows none of the channels searched{tail}")
            continue
        for d in deps:
            mine = tuple(offered.get(sensor, ()))
            if d.kind == "aux_integral":  # the gyro's bias following the switch (families.py)
                mine += tuple(f"{s}.{f}" for s, fs in offered.items() if s not in report.searched for f in fs)
            out.append("  " + dependency_line(d, mine))
    for sensor, groups in report.alias_groups.items():
        for g in groups:
            if len(g) > 1:
                out.append(
                    f"  {sensor}: aliases (R² ≥ 0.9, one stands for the other): " + ", ".join(label(c) for c in g)
                )
    for sensor, rel in report.relations.items():
        loose = [f"{label(a)} ~ {label(b)} ({r2:.2f})" for a, b, r2 in rel if r2 < ALIAS_R2 and "fov" not in a + b]
        if loose:
            out.append(f"  {sensor}: channels that follow one another (R²): " + ", ".join(loose))
    return out
