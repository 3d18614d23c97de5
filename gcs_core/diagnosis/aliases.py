"""Combinations of elements the data leave to the a priori, named.

A fit with an a priori always returns numbers, but along some directions of the state the
data say little or nothing: a spinner's horizon scanner sees its azimuth bias ΔΦ and its
plane tilt ε_H only through ``ΔΦ − asin(cot γ' tan ε_H)`` (Eq 4-12a, e), an exact alias;
and when the Sun angle β hardly changes over the span, the in-track time error Δt, the
spin axis's right ascension and the Sun sensor's tilt ε_S (through ``ΔΦ_S =
asin(cot β tan ε_S)``, Eq 4-12d) all move the horizon timing by near-constant phases, a
near alias. Along such a direction the estimate is its a priori and the σ the a priori's.

Rule. From the data information ``A = Hᵀ R⁻¹ H`` of the fit's last linearization (Eq 3-2)
and the a-priori σ₀, form the information relative to the a priori,
``Ã = S A S`` with ``S = diag(σ₀)`` (after marginalizing elements without an a priori).
An eigenvalue ``λ`` of ``Ã`` is the data's information along its direction in units of the
a priori's: the posterior variance there is ``1/(1 + λ)`` of the a priori's. A direction
with ``λ <`` :data:`WEAK_INFORMATION` is *set by the a priori*; ``λ <``
:data:`EXACT_INFORMATION` (round-off, not data) is an exact alias. Degenerate exact directions are
rotated to the sparsest basis (reduced row echelon form of the null space, pivoting on the
largest weight) so that each named combination involves as few elements as possible
(one sensor's ΔΦ and ε_H, not a blend of two sensors').

Only directions with at least two elements of weight ≥ :data:`COMBINATION_WEIGHT` are
named (a combination); one element weak on its own is left to the generic determination marks.
An element with weight ≥ :data:`MEMBER_WEIGHT` in an exact direction, or in a weak one
while its posterior σ is at least :data:`PRIOR_SHARE` of its a priori, is marked *set by
the a priori* (not determined), with the combination named. Models may declare their
exact aliases with the reason (``ObservationModel.aliases``: local parameter names ->
text); the names here then carry that reason.
"""

from __future__ import annotations

from collections.abc import Mapping, Sequence
from dataclasses import dataclass

import numpy as np

from gcs_core.linalg import sparse_basis

#: data information below this share of the a priori's along a direction: set by the a priori
WEAK_INFORMATION = 0.25
#: ... below this: exact (a millionth of the a priori's information is round-off, not data)
EXACT_INFORMATION = 1e-6
#: weight (unit vector in a-priori σ) from which an element takes part in a combination
MEMBER_WEIGHT = 0.3
#: a direction is a combination when two elements or more weigh at least this
COMBINATION_WEIGHT = 0.15
#: posterior σ / a-priori σ from which a member of a near alias counts as set by the a priori
PRIOR_SHARE = 0.5


@dataclass(frozen=True)
class Alias:
    """One direction of the state the data leave to the a priori.

    Attributes
    ----------
    elements : the elements taking part, largest weight first.
    weights : their weights in the unit direction, in units of each a-priori σ.
    information : the data's information along it, in units of the a priori's (λ).
    exact : True when the data carry none (round-off), False when little.
    reason : why, when a model declares it, else "".
    """

    elements: tuple[str, ...]
    weights: tuple[float, ...]
    information: float
    exact: bool
    reason: str = ""

    def combination(self) -> str:
        return " ".join(f"{w:+.2f}·{n}" for n, w in zip(self.elements, self.weights))

    def describe(self) -> str:
        kind = "exact" if self.exact else f"nearly: the data carry {self.information:.2g} of the a priori's information"
        text = f"{', '.join(self.elements)} ({kind}) along {self.combination()} (in a-priori σ)"
        return text + (f"; {self.reason}" if self.reason else "")

    def as_report(self) -> dict:
        return {
            "elements": list(self.elements),
            "weights": [round(w, 4) for w in self.weights],
            "information": float(self.information),
            "exact": self.exact,
            "reason": self.reason,
            "text": self.describe(),
        }


def weak_directions(
    information: np.ndarray,
    sigma0: Sequence[float],
    names: Sequence[str],
    reasons: Mapping[frozenset, str] | None = None,
) -> list[Alias]:
    """The directions the data leave to the a priori (module docstring), weakest first.

    ``information`` (n, n) is the data information over ``names``; ``sigma0`` (n,) the
    a-priori σ (``inf``: none; those elements are marginalized out first). ``reasons``
    maps a set of element names to the text of a declared alias.
    """
    names = list(names)
    s0 = np.asarray(sigma0, dtype=float)
    A = np.asarray(information, dtype=float)
    fin = np.isfinite(s0) & (s0 > 0)
    if not np.any(fin):
        return []
    f, i = np.flatnonzero(fin), np.flatnonzero(~fin)
    Af = A[np.ix_(f, f)]
    if i.size:
        Aii = A[np.ix_(i, i)]
        Af = Af - A[np.ix_(f, i)] @ np.linalg.pinv(Aii, hermitian=True) @ A[np.ix_(i, f)]
    S = s0[f]
    At = 0.5 * (Af + Af.T) * np.outer(S, S)
    lam, V = np.linalg.eigh(At)
    exact = lam < EXACT_INFORMATION
    weak = (lam < WEAK_INFORMATION) & ~exact
    out: list[Alias] = []
    fn = [names[j] for j in f]
    reasons = reasons or {}

    def alias(v, info, is_exact):
        order = [j for j in np.argsort(-np.abs(v)) if abs(v[j]) >= 0.1]
        if v[order[0]] < 0:
            v = -v
        els = tuple(fn[j] for j in order)
        reason = next((t for key, t in reasons.items() if key and key <= frozenset(els)), "")
        return Alias(els, tuple(float(v[j]) for j in order), max(0.0, float(info)), is_exact, reason)

    if np.any(exact):
        B = sparse_basis(V[:, exact])
        out += [alias(B[:, c], 0.0, True) for c in range(B.shape[1])]
    out += [alias(V[:, c], lam[c], False) for c in np.flatnonzero(weak)]
    # a combination names two elements or more; one element the data leave to its a priori
    # on its own is not an alias (the generic determination marks speak for it)
    return [a for a in out if sum(abs(w) >= COMBINATION_WEIGHT for w in a.weights) >= 2]


def set_by_prior(aliases: Sequence[Alias], sigma: Mapping[str, float], sigma0: Mapping[str, float]) -> dict[str, str]:
    """Element -> note, for the members of ``aliases`` the a priori sets (module docstring)."""
    out: dict[str, str] = {}
    for a in aliases:
        for name, w in zip(a.elements, a.weights):
            if abs(w) < MEMBER_WEIGHT or name in out:
                continue
            s, s0 = float(sigma.get(name, np.inf)), float(sigma0.get(name, np.inf))
            if not a.exact and not (np.isfinite(s0) and s >= PRIOR_SHARE * s0):
                continue
            others = [n for n in a.elements if n != name]
            with_ = f" with {', '.join(others)}" if others else ""
            out[name] = (
                f"set by its a priori: the data do not separate it{with_} "
                f"({'exact' if a.exact else f'{a.information:.2g} of the a-priori information'} "
                f"along {a.combination()}, in a-priori σ)" + (f"; {a.reason}" if a.reason else "")
            )
    return out


def problem_aliases(problem, result) -> list[Alias]:
    """:func:`weak_directions` of a fitted problem, with the reasons its models declare
    (``aliases`` of each model: tuple of local parameter names -> text) and, for a
    spinner, how much the Sun angle moved over the span."""
    names = list(result.solve_for)
    info = getattr(result, "information", None)
    if not names or info is None or not np.any(info):
        return []  # a filter/smoother result carries no data information
    state = problem.state
    reasons: dict[frozenset, str] = {}
    for sd in problem.sensors:
        pm = problem.param_map.get(sd.name, {})
        for local, text in (getattr(sd.model, "aliases", None) or {}).items():
            els = frozenset(pm[p] for p in local if p in pm)
            if len(els) == len(local):
                reasons[els] = text
    sun_span = _sun_angle_span(problem)
    if sun_span is not None:
        timing = frozenset(
            n for n in names if n.endswith(".d_t") or n == "att.ra" or n.endswith(".tilt") or n.endswith(".eps_S")
        )
        text = (
            f"the Sun angle β moved by only {np.degrees(sun_span):.2g}° over the span, so the "
            "in-track time error Δt, the spin axis's right ascension and the Sun sensor's tilt "
            "ε_S (ΔΦ_S = asin(cot β tan ε_S), Eq 4-12d) all shift the horizon timing by "
            "near-constant phases"
        )
        for n in timing:
            reasons.setdefault(frozenset([n]), text)
    return weak_directions(result.information, [state[n].sigma0 for n in names], names, reasons)


def _sun_angle_span(problem) -> float | None:
    """Range of the measured Sun angle β of a spinner's plane-field Sun sensors [rad]."""
    spans = [
        float(np.ptp(sd.y[:, 0])) for sd in problem.sensors if sd.model.type_name == "plane_field_sun" and sd.n > 1
    ]
    return max(spans) if spans else None
