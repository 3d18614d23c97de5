"""Numbers for people: the one display rule of every face (CLI tables, TUI screens, exports).

**Unit, chosen from σ.** A quantity is shown in the unit its uncertainty calls for, so
that rows of one table with similar σ share a unit whatever their values:

* an angle (internal ``rad``) is in arcsec while its σ is below 1°, in degrees from 1°
  (``rad/count`` likewise: arcsec/count or deg/count);
* a rate (``rad/s``) is in deg/h (a gyro's bias, its drift's rate), and a body rate whose
  value or σ reaches 1°/s (3600 deg/h: a hand turning a unit, a spinner) in deg/s; an
  angular acceleration (``rad/s2``) in deg/h²;
* an angle whose value reaches 10° is in degrees whatever its σ (``31.78856 ± 0.00023 deg``,
  not ``114436.9 ± 8.2 arcsec``); below 10° (at most 5 digits of arcsec) rows with similar σ
  keep sharing a unit;
* a coefficient per unit of an auxiliary channel is in its channel's unit, by the ICD's
  naming (:func:`aux_unit`, :func:`per_channel`): ``nT/(A m²)`` for a torquer ``mtb_*``;
* every other unit is shown as it is; a dimensionless quantity (``1``) has no unit.

Where there is no σ (an RMS, a plotted series, a threshold), the spread of the numbers
plays its part: :func:`display_unit` takes one "scale" argument, σ or spread.

**Digits, from σ.** σ keeps two significant digits and the value is rounded to the same
decimal place (``12.346 ± 0.023``). Fixed point while that needs at most 10 decimals and
the numbers stay below 10⁷; otherwise value and σ share a power of ten
(``(1.23 ± 0.11)e-5``). A number without σ gets a stated number of significant digits.

**p-values** keep two significant digits; below 1e-16 (the resolution of 1 − P in double
precision) they read ``< 1e-16``, never ``0``.

Nothing here imports a UI library; the ``gcs`` tables and the TUI both import this module.
"""

from __future__ import annotations

import math

import numpy as np

from gcs_core.units import DEG, UNIT_SCALE

#: display unit -> multiply the internal value by this (UNIT_SCALE plus what only display needs)
SCALE: dict[str, float] = {
    **UNIT_SCALE,
    "deg/h2": (3600.0 / DEG) * 3600.0,
    "deg/s": 1.0 / DEG,
    "arcsec/count": 1.0 / (DEG / 3600.0),
    "deg/count": 1.0 / DEG,
}

#: σ (internal units) from which an angle is shown in degrees instead of arcsec
DEG_FROM_SIGMA = 1.0 * DEG

#: internal unit -> (display unit for σ below DEG_FROM_SIGMA, display unit above)
_BY_SIGMA = {
    "rad": ("arcsec", "deg"),
    "rad/count": ("arcsec/count", "deg/count"),
    "rad/s2": ("deg/h2", "deg/h2"),
}

#: how a display unit is printed after a number
_LABEL = {"1": "", "": "", "deg/h2": "deg/h²"}

#: fixed-point numbers stay below this; larger ones share a power of ten
FIXED_LIMIT = 1e7


def display_unit(unit: str, scale: float) -> str:
    """The display unit of a quantity in internal ``unit`` whose σ (or, without σ, its
    spread) is ``scale`` (module docstring). A non-finite scale picks the small unit."""
    if unit == "rad/s":
        return "deg/s" if math.isfinite(scale) and abs(scale) >= LARGE_RATE else "deg/h"
    choice = _BY_SIGMA.get(unit)
    if choice is None:
        return unit
    small, large = choice
    return large if math.isfinite(scale) and abs(scale) >= DEG_FROM_SIGMA else small


def common_unit(unit: str, *arrays) -> str:
    """One display unit for several quantities shown together (a table column, a screen):
    :func:`display_unit` of the largest finite ``|x|`` among them."""
    vals = [abs(float(x)) for a in arrays for x in np.ravel(np.asarray(a, dtype=float)) if math.isfinite(x)]
    return display_unit(unit, max(vals) if vals else float("nan"))


def shown_unit(unit: str, value: float, sigma: float | None = None) -> str:
    """The display unit :func:`estimate` picks for ``value ± sigma``: from σ when it is
    finite and positive, from ``|value|`` otherwise; an angle of 10° or more in degrees."""
    usable = sigma is not None and math.isfinite(sigma) and sigma > 0
    if unit == "rad" and math.isfinite(value) and abs(value) >= LARGE_ANGLE:
        return "deg"
    if unit == "rad/s" and math.isfinite(value) and abs(value) >= LARGE_RATE:
        return "deg/s"
    return display_unit(unit, sigma if usable and sigma is not None else abs(value))


#: a rate (rad/s) from this value or σ on is shown in deg/s (1°/s: beyond 3600 deg/h a
#: number of deg/h stops being read at a glance; a gyro's bias is far below it)
LARGE_RATE = 1.0 * DEG

#: an angle (rad) from this value on is shown in degrees whatever its σ (36 000 arcsec: beyond
#: five digits of arcsec a number stops being read at a glance)
LARGE_ANGLE = 10.0 * DEG

#: auxiliary channels' units by the ICD's naming: (part of the channel's name, unit)
AUX_UNITS = (("mtb", "A m²"), ("temp", "°C"))


def aux_unit(channel: str) -> str:
    """The unit of auxiliary channel ``channel`` by the ICD's naming ('' when unknown)."""
    low = channel.lower()
    return next((u for key, u in AUX_UNITS if key in low), "")


def per_channel(unit: str, channel: str) -> str:
    """The unit of a coefficient in ``unit`` per unit of auxiliary ``channel``:
    ``nT/(A m²)`` for ``mtb_x``, ``nT/°C`` for ``tam_temp``, ``nT/aux`` when unknown."""
    cu = aux_unit(channel)
    if not cu:
        return f"{unit}/aux"
    return f"{unit}/({cu})" if (" " in cu or "/" in cu) else f"{unit}/{cu}"


def scale(unit: str, shown: str) -> float:
    """Factor from internal ``unit`` to display unit ``shown`` (every conversion is linear)."""
    return 1.0 if shown == unit else SCALE[shown] / SCALE.get(unit, 1.0)


def to_display(value: float, unit: str, shown: str) -> float:
    """Convert ``value`` from internal ``unit`` to the display unit ``shown``."""
    return float(value) * scale(unit, shown)


def from_display(value: float, unit: str, shown: str) -> float:
    """Inverse of :func:`to_display` (what an edit field typed in ``shown`` means)."""
    return float(value) / scale(unit, shown)


def unit_label(shown: str) -> str:
    """The unit as printed after a number (empty for dimensionless)."""
    return _LABEL.get(shown, shown)


def unit_column(shown: str) -> str:
    """The unit in a table's unit column: ``—`` for dimensionless."""
    return unit_label(shown) or "—"


def sig(x: float, digits: int = 3) -> str:
    """``x`` with ``digits`` significant digits; ``—`` for NaN, ``∞`` for infinities."""
    if x is None or (isinstance(x, float) and math.isnan(x)):
        return "—"
    if math.isinf(x):
        return "∞" if x > 0 else "-∞"
    if x == 0:
        return "0"
    mag = math.floor(math.log10(abs(x)))
    if -4 <= mag < 6:
        decimals = max(0, digits - 1 - mag)
        return f"{x:.{decimals}f}"
    return f"{x:.{digits - 1}e}"


def fixed(x: float, decimals: int) -> str:
    """``x`` with a fixed number of decimals; ``—`` for NaN."""
    if x is None or math.isnan(x):
        return "—"
    if math.isinf(x):
        return "∞" if x > 0 else "-∞"
    return f"{round(x, decimals) + 0.0:.{decimals}f}"  # + 0.0: no "-0.0"


#: below this a p-value is not resolved in double precision (1 − P rounds to 1)
P_FLOOR = 1e-16


def pvalue(p: float) -> str:
    """A p-value: two significant digits, ``< 1e-16`` below double precision."""
    if p is None or math.isnan(p):
        return "—"
    if p < P_FLOOR:
        return "< 1e-16"
    return f"{p:.2g}"


def p_text(p: float, name: str = "p") -> str:
    """``p = 0.0031`` or ``p < 1e-16`` (for sentences)."""
    text = pvalue(p)
    return f"{name} {text}" if text.startswith("<") else f"{name} = {text}"


def decimals_of(sigma: float) -> int:
    """Decimal places that keep two significant digits of ``sigma`` (may be negative)."""
    return 1 - math.floor(math.log10(sigma))


def value_sigma(value: float, sigma: float | None) -> tuple[str, str]:
    """``(value, sigma)`` strings: σ to 2 significant digits, value to σ's decimal place.

    With no usable σ (None, 0, inf, NaN) the value gets 6 significant digits and σ is
    ``—`` (or ``∞``). Fixed-point while that needs at most 10 decimals and the numbers
    are below :data:`FIXED_LIMIT`; otherwise both share a power of ten.
    """
    if sigma is None or not math.isfinite(sigma) or sigma <= 0:
        return sig(value, 6), "∞" if sigma is not None and math.isinf(sigma) else "—"
    exp_s = math.floor(math.log10(sigma))
    decimals = 1 - exp_s  # keep 2 significant digits of σ
    ref = max(abs(value), sigma)
    if decimals <= 10 and ref < FIXED_LIMIT and (ref >= 1e-3 or exp_s >= -4):
        d = max(decimals, 0)
        v = round(value, decimals) + 0.0  # + 0.0 turns a rounded -0.0 into 0.0
        s = round(sigma, decimals)
        return f"{v:.{d}f}", f"{s:.{d}f}"
    # shared power of ten, chosen from the larger of |value| and σ
    exp = math.floor(math.log10(ref)) if ref > 0 else exp_s
    p10 = 10.0**exp
    d = max(exp - exp_s + 1, 0)
    return f"{value / p10:.{d}f}e{exp:+d}", f"{sigma / p10:.{d}f}e{exp:+d}"


def estimate(value: float, sigma: float | None, unit: str, *, shown: str | None = None, with_unit: bool = True) -> str:
    """``value ± σ unit`` in the display unit chosen from σ, σ-derived digits.

    ``with_unit=False`` leaves the unit out (a table that has a unit column)."""
    shown = shown or shown_unit(unit, value, sigma)
    v = to_display(value, unit, shown)
    s = to_display(sigma, unit, shown) if sigma is not None and math.isfinite(sigma) else sigma
    vs, ss = value_sigma(v, s)
    lab = unit_label(shown)
    if ss in ("—", "∞"):
        body = vs if ss == "—" else f"{vs} ± ∞"
    elif "e" in vs and "e" in ss and vs.split("e")[1] == ss.split("e")[1]:
        body = f"({vs.split('e')[0]} ± {ss.split('e')[0]})e{vs.split('e')[1]}"
    else:
        body = f"{vs} ± {ss}"
    return f"{body} {lab}".rstrip() if with_unit else body


def value_text(value: float, sigma: float | None, unit: str, shown: str) -> str:
    """The value alone in ``shown``, at the decimal place σ calls for (an edit field's
    prefill): ``0.0446`` rather than ``0.044629361519``."""
    v = to_display(value, unit, shown)
    s = to_display(sigma, unit, shown) if sigma is not None and math.isfinite(sigma) and sigma > 0 else None
    if s is None:
        return sig(v, 6)
    # one more digit than the display keeps, so that an untouched prefill loses nothing visible
    d = decimals_of(s) + 1
    if d > 12 or abs(v) >= FIXED_LIMIT:
        return f"{v:.{max(decimals_of(s) - math.floor(math.log10(abs(v) or 1)), 1) + 1}e}"
    return f"{round(v, d) + 0.0:.{max(d, 0)}f}"


def quantity(value: float, unit: str, *, digits: int = 3, shown: str | None = None, with_unit: bool = True) -> str:
    """A number with no σ in display units (chosen from its own size unless ``shown``),
    ``digits`` significant digits."""
    shown = shown or display_unit(unit, value)
    text = sig(to_display(value, unit, shown), digits)
    return f"{text} {unit_label(shown)}".rstrip() if with_unit else text


def seconds(t: float) -> str:
    """A mission time or duration [s] to 0.1 s (``1234.5 s``); large values in hours too."""
    if t is None or math.isnan(t):
        return "—"
    return f"{t:.1f} s" if abs(t) < 1e5 else f"{t / 3600:.2f} h"


def span(t0: float, t1: float) -> str:
    """``t0–t1 s``, both to whole seconds (spans are shown, not computed with)."""
    return f"{t0:.0f}–{t1:.0f} s"


def bar(fraction: float, width: int = 10) -> str:
    """A small horizontal bar (``█▌``) for a fraction in [0, 1] (clipped)."""
    if fraction is None or math.isnan(fraction):
        return ""
    f = min(max(fraction, 0.0), 1.0) * width
    full = int(f)
    half = "▌" if f - full >= 0.5 else ""
    return "█" * full + half


def nice_ticks(lo: float, hi: float, n: int = 5) -> list[float]:
    """About ``n`` round tick values (1, 2, 2.5 or 5 × 10^k steps) covering [lo, hi]."""
    if not (math.isfinite(lo) and math.isfinite(hi)) or hi <= lo:
        return [lo] if math.isfinite(lo) else []
    raw = (hi - lo) / max(n - 1, 1)
    p10 = 10.0 ** math.floor(math.log10(raw))
    steps = [m * p10 for m in (0.5, 1, 2, 2.5, 5, 10)]
    i = next(i for i, step in enumerate(steps) if step >= raw)
    while True:  # a range that just misses two ticks at this step takes the next finer step
        step = steps[i]
        first = math.ceil(lo / step - 1e-9) * step
        out, k = [], 0
        while first + k * step <= hi + 1e-9 * step:
            out.append(round(first + k * step, 12))
            k += 1
        if len(out) >= 2 or i == 0:
            return out
        i -= 1


def tick_labels(ticks: list[float]) -> list[str]:
    """Labels of :func:`nice_ticks` values with the fewest decimals that tell them apart."""
    for d in range(0, 7):
        labels = [f"{t:.{d}f}" for t in ticks]
        if len(set(labels)) == len(labels) and all(
            abs(float(lab) - t) < 1e-9 * max(1.0, abs(t)) for lab, t in zip(labels, ticks)
        ):
            return [lab if lab != "-0" else "0" for lab in labels]
    return [f"{t:g}" for t in ticks]
