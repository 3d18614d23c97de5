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
estimated within :data:`AMPLITUDE_Z` of its σ from 0 (a two-sided 95 % test).
"""

from __future__ import annotations

from typing import Mapping

#: an amplitude within this many σ of zero is "consistent with zero" (two-sided 95 %)
AMPLITUDE_Z = 1.96


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
                    if not (s > 0 and abs(v) < AMPLITUDE_Z * s):
                        break
                    parts.append(f"{ea} = {v:.3g} ± {s:.2g}")
                elif v != 0.0:
                    break
                else:
                    parts.append(f"{ea} held at 0")
            else:
                if parts:
                    out[el] = ("not determined by the data: seen only through "
                               + ", ".join(parts) + ", consistent with 0; its σ mirrors the a priori "
                               "and the noise in that amplitude")
    return out
