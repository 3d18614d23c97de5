"""Elements a fit did not determine, though its covariance says it did.

Some parameters reach the data only through an amplitude: the fine Sun sensor's frequency
``k`` enters Eq 4-23 as ``A3 sin(k tan α)`` (and ``A4h sin(2k tan α)``). When every such
amplitude is consistent with zero, the data carry no information on ``k``; the
linearized covariance (Eq 3-2) is still formed at the *fitted* amplitude, which is then
noise, and its σ for ``k`` shrinks with that noise squared. Over seeds of one plan the
fitted ``k`` scatters like its a priori while the reported σ ranges down to 60 % of it
(``benchmarks/predictor_vs_fit.py``). Such an element is flagged rather than trusted.

Rule: a solve-for element ``p`` a model declares seen through amplitudes
(``ObservationModel.seen_through``) is *not determined* when each of them is held at 0 or
consistent with 0 at the 5 % level (:func:`amplitude_p_value`).

The frequency searched
----------------------
The amplitude's ``z = â/σ_a`` is formed at the *fitted* frequency, which the fit chose
where the noise lines up best with a sine: under "amplitude 0", ``z`` is the largest of
a continuum of correlated normal statistics ``z(k)``, not one normal draw (Davies'
problem: a parameter present only under the alternative). A plain two-sided 1.96 test
then calls the amplitude "clear", and the frequency determined, on 25 % of nominal 4 h
missions instead of 5 % (the FSS β axis, inertial and Earth-pointing,
``benchmarks/false_alarms_vs_span.py``), and those frequencies land up to 5σ from the
book. The tail of the largest ``|z(k)|`` is bounded by its upcrossings (Rice's formula;
Davies 1987)::

    P(max |z(k)| > c) ≤ 2 Φ̄(c) + (L/π) e^{−c²/2},   L = ∫ sqrt(λ₂) w(k) dk

with ``λ₂ = Var ∂z/∂k`` and ``w`` the weight of frequency ``k`` in the search. The fit's a
priori on ``k`` (σ_k0) lowers a frequency ``Δk`` from the book by ``(Δk/σ_k0)²`` in χ²,
i.e. ``w = exp(−Δk²/2σ_k0²)``, so ``L = sqrt(2π) σ_k0 sqrt(λ₂)``. ``λ₂`` follows from the
fit itself: the data information on ``k`` is ``â² λ₂`` times that on the amplitude, so
``sqrt(λ₂) = 1/(z σ_k,data)`` with ``σ_k,data⁻² = σ_k⁻² − σ_k0⁻²`` (the posterior σ without
the a priori's share). Without an a priori on ``k`` the search spans ``0..2k̂``
(``L = 2|k̂| sqrt(λ₂)``).

Davies, R. B., "Hypothesis testing when a nuisance parameter is present only under the
alternative", Biometrika 74(1), 1987.
"""

from __future__ import annotations

import math
from collections.abc import Mapping

import numpy as np

from gcs_core.estimators.batch.least_squares import name_combinations, normal_equations

#: an amplitude within this many σ of zero is "consistent with zero" (two-sided 95 %)
#: when its frequency is not searched (held, or without data information)
AMPLITUDE_Z = 1.96
#: the level of the amplitude test (:func:`amplitude_p_value`): two-sided 95 %
AMPLITUDE_ALPHA = 0.05


def amplitude_p_value(z: float, sigma_k: float, sigma_k0: float, k: float) -> float:
    """P-value of an amplitude ``z = â/σ_a`` fitted together with its frequency ``k``
    (posterior σ ``sigma_k``, a-priori σ ``sigma_k0``; module docstring, Davies' bound):
    ``2 Φ̄(|z|) + (L/π) e^{−z²/2}``, capped at 1. Without data information on ``k``
    (``sigma_k ≥ sigma_k0``) the frequency was not searched and ``L = 0``."""
    z = abs(float(z))
    tail = math.erfc(z / math.sqrt(2.0))  # 2 Φ̄(|z|)
    info = (1.0 / sigma_k**2 if sigma_k > 0 else math.inf) - (
        1.0 / sigma_k0**2 if math.isfinite(sigma_k0) and sigma_k0 > 0 else 0.0
    )
    if not (info > 0 and z > 0):
        return min(1.0, tail)
    root_l2 = math.sqrt(info) / z  # sqrt(λ₂) = 1/(z σ_k,data)
    span = math.sqrt(2.0 * math.pi) * sigma_k0 if math.isfinite(sigma_k0) and sigma_k0 > 0 else 2.0 * abs(k)
    L = span * root_l2
    return min(1.0, tail + L / math.pi * math.exp(-0.5 * z * z))


def not_determined(problem, values: Mapping[str, float], sigma: Mapping[str, float]) -> dict[str, str]:
    """Element -> why the data do not determine it (module docstring), for the solve-for
    elements of ``problem`` at the fitted ``values`` with their 1-σ ``sigma``."""
    state = problem.state
    solve = set(state.solve_for)
    out = {}
    for sd in problem.sensors:
        seen = getattr(sd.model, "seen_through", None) or {}
        pm = problem.param_map.get(sd.name, {})
        for local, amps in seen.items():
            el = pm.get(local)
            if el is None or el not in solve:
                continue
            parts = []
            for a in amps:
                ea = pm.get(a)
                if ea is None:
                    continue
                v = float(values.get(ea, state[ea].value))
                if ea in solve:
                    s = float(sigma.get(ea, state[ea].sigma0))
                    if not s > 0:
                        break
                    p = amplitude_p_value(
                        v / s,
                        float(sigma.get(el, state[el].sigma0)),
                        float(state[el].sigma0),
                        float(values.get(el, state[el].value)),
                    )
                    if p < AMPLITUDE_ALPHA:
                        break
                    parts.append(f"{ea} = {v:.3g} ± {s:.2g} (p {p:.2g} over the frequencies searched)")
                elif v != 0.0:
                    break
                else:
                    parts.append(f"{ea} held at 0")
            else:
                if parts:
                    out[el] = (
                        "not determined by the data: seen only through "
                        + ", ".join(parts)
                        + ", consistent with 0; its σ mirrors the a priori "
                        "and the noise in that amplitude"
                    )
    return out


# ------------------------------------------------------------------ set by the a priori
#: an element whose prior share of information exceeds this is "set by the a priori"
PRIOR_SHARE = 0.5
#: ... which covers every element whose posterior σ is within 10 % of its a-priori σ
#: (share ≥ 0.9² = 0.81)
SIGMA_RATIO = 0.9


def prior_shares(names, P, sigma0) -> dict[str, float]:
    """Element -> the share of its posterior information that comes from the a priori.

    With the batch information ``P⁻¹ = P̄⁻¹ + A`` (Eq 3-2, ``A`` the data's), the resolution
    (averaging-kernel) matrix is ``P A = I − P P̄⁻¹``; its complement on the diagonal,
    ``P_ii / σ̄_i²``, is the a priori's share of what is known about element ``i``: 0 when
    the data determine it alone, 1 when they add nothing (posterior σ = a-priori σ). It is
    the square of the posterior-to-prior σ ratio. Elements without a finite a priori
    (σ̄ = ∞) are left out: the data alone set them.

    References
    ----------
    Rodgers, C. D., *Inverse Methods for Atmospheric Sounding*, World Scientific 2000, §2.4
    (the averaging kernel; an element's information from the measurement and the a priori).
    """
    P = np.asarray(P, dtype=float)
    out = {}
    for i, name in enumerate(names):
        s0 = float(sigma0[i])
        if math.isfinite(s0) and s0 > 0 and math.isfinite(P[i, i]):
            out[name] = float(P[i, i]) / s0**2
    return out


def set_by_prior(problem, names, P) -> dict[str, str]:
    """Solve-for element -> why the a priori, not the data, set it: its prior share of
    information (:func:`prior_shares`) above :data:`PRIOR_SHARE` (the data give less
    information than the a priori), which includes every element whose posterior σ is
    within 10 % of its a-priori σ."""
    state = problem.state
    sigma0 = [state[n].sigma0 for n in names]
    out = {}
    for name, share in prior_shares(names, P, sigma0).items():
        if share > PRIOR_SHARE:
            ratio = math.sqrt(share)
            out[name] = (
                f"set by the a priori: posterior σ is {100 * ratio:.0f} % of the a-priori σ; "
                f"the data give {100 * max(0.0, 1 - share):.0f} % of what is known about it"
            )
    return out


def null_at_prior(problem, names, rank_tol: float = 1e-7) -> list[str]:
    """Combinations of ``names`` the data do not determine when linearized at the a priori
    (the configured values): eigen-directions of the equilibrated data information with
    eigenvalue below ``rank_tol`` of the largest, and elements no data depend on there
    (:func:`~gcs_core.estimators.batch.least_squares.name_combinations`). A parameter that reaches the data
    only through an amplitude whose a priori is 0 (the FSS frequency ``k`` of Eq 4-23)
    is null here though a fitted amplitude's noise gives it curvature at the solution."""
    names = tuple(names)
    if not names:
        return []
    A, _, _, _ = normal_equations(problem, problem.state.values(), names)
    combos = name_combinations(A, names, rank_tol)
    # an element no data depend on is also an eigen-direction of its own: name it once
    alone = {c.split(" (no data", 1)[0] for c in combos if c.endswith("(no data depends on it)")}
    return [c for c in combos if not (c[1:].startswith("1.00·") and c[6:] in alone)]
