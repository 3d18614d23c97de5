"""Numbers for people: units at the edge and honest precision.

Every number a screen shows goes through here; no widget ever renders a raw float.

* Internal units (rad, rad/s, nT, s …) become display units with
  :data:`gcs_core.units.UNIT_SCALE`: angles in arcsec (small) or deg (large), rates
  in deg/h.
* An estimate with an uncertainty keeps two significant digits of σ and rounds the
  value to the same decimal place (``12.346 ± 0.023``). Very small or very large σ
  switch to a shared power of ten: ``(1.23 ± 0.11)e-5``.
* Statistics without σ (RMS, Δχ², p) get a fixed number of significant digits.

Nothing here imports Textual.
"""

from __future__ import annotations

import math

from gcs_core.units import DEG, UNIT_SCALE

#: internal unit -> (display unit when small, display unit when large, threshold in
#: internal units above which the large unit is used).
_ANGLE_CHOICES = {
    "rad": ("arcsec", "deg", 1.0 * DEG),
    "rad/s": ("deg/h", "deg/h", math.inf),
}

#: shown instead of the unit string for dimensionless quantities.
_NO_UNIT = {"1", ""}


def display_unit(unit: str, magnitude: float) -> str:
    """Display unit for a quantity of internal ``unit`` and typical size ``magnitude``.

    ``rad`` becomes ``arcsec`` below 1 deg and ``deg`` above; ``rad/s`` becomes
    ``deg/h``; every other unit is shown as it is.
    """
    choice = _ANGLE_CHOICES.get(unit)
    if choice is None:
        return unit
    small, large, threshold = choice
    return large if math.isfinite(magnitude) and abs(magnitude) >= threshold else small


def scale(unit: str, shown: str) -> float:
    """Factor from internal ``unit`` to display unit ``shown`` (every conversion is linear)."""
    return 1.0 if shown == unit else UNIT_SCALE[shown] / UNIT_SCALE.get(unit, 1.0)


def to_display(value: float, unit: str, shown: str) -> float:
    """Convert ``value`` from internal ``unit`` to the display unit ``shown``."""
    if shown == unit:
        return float(value)
    return float(value) * UNIT_SCALE[shown] / UNIT_SCALE.get(unit, 1.0)


def from_display(value: float, unit: str, shown: str) -> float:
    """Inverse of :func:`to_display` (what an edit field typed in ``shown`` means)."""
    if shown == unit:
        return float(value)
    return float(value) * UNIT_SCALE.get(unit, 1.0) / UNIT_SCALE[shown]


def unit_label(shown: str) -> str:
    """The unit as printed after a number (empty for dimensionless)."""
    return "" if shown in _NO_UNIT else shown


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
    return f"{round(x, decimals) + 0.0:.{decimals}f}"    # + 0.0: no "-0.0"


def pvalue(p: float) -> str:
    """A p-value: two significant digits, ``<1e-16`` below double precision."""
    if p is None or math.isnan(p):
        return "—"
    if p < 1e-16:
        return "<1e-16"
    return f"{p:.2g}"


def value_sigma(value: float, sigma: float | None) -> tuple[str, str]:
    """``(value, sigma)`` strings: σ to 2 significant digits, value to σ's decimal place.

    With no usable σ (None, 0, inf, NaN) the value gets 6 significant digits and σ is
    ``—`` (or ``∞``). Fixed-point while that needs at most 10 decimals and the numbers
    are below 1e5; otherwise both share a power of ten, the value's mantissa rounded to
    the σ's second digit (``1.23e-5``, ``0.11e-5``).
    """
    if sigma is None or not math.isfinite(sigma) or sigma <= 0:
        s = "∞" if sigma is not None and math.isinf(sigma) else "—"
        return sig(value, 6), s
    exp_s = math.floor(math.log10(sigma))
    decimals = 1 - exp_s                        # keep 2 significant digits of σ
    ref = max(abs(value), sigma)
    if decimals <= 10 and ref < 1e5 and (ref >= 1e-3 or exp_s >= -4):
        d = max(decimals, 0)
        v = round(value, decimals) + 0.0       # + 0.0 turns a rounded -0.0 into 0.0
        s = round(sigma, decimals)
        return f"{v:.{d}f}", f"{s:.{d}f}"
    # shared power of ten, chosen from the larger of |value| and σ
    exp = math.floor(math.log10(ref)) if ref > 0 else exp_s
    scale = 10.0 ** exp
    d = max(exp - exp_s + 1, 0)
    return f"{value / scale:.{d}f}e{exp:+d}", f"{sigma / scale:.{d}f}e{exp:+d}"


def estimate(value: float, sigma: float | None, unit: str, *, shown: str | None = None,
             with_unit: bool = True) -> str:
    """``value ± σ unit`` in display units, honest precision (module docstring).

    ``with_unit=False`` leaves the unit out (a table that has a unit column)."""
    finite_sigma = sigma if sigma is not None and math.isfinite(sigma) else 0.0
    shown = shown or display_unit(unit, max(abs(value), finite_sigma))
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


def quantity(value: float, unit: str, *, digits: int = 4, shown: str | None = None,
             with_unit: bool = True) -> str:
    """A number with no σ in display units, ``digits`` significant digits."""
    shown = shown or display_unit(unit, value)
    text = sig(to_display(value, unit, shown), digits)
    return f"{text} {unit_label(shown)}".rstrip() if with_unit else text


def shown_unit(unit: str, value: float, sigma: float | None = None) -> str:
    """The display unit :func:`estimate` picks for ``value ± sigma``."""
    finite_sigma = sigma if sigma is not None and math.isfinite(sigma) else 0.0
    return display_unit(unit, max(abs(value), finite_sigma))


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
