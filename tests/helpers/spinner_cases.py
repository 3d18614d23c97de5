"""Spinners on the real (oblate) horizon, with one hidden calibration error each (issue 11).

A 10 rpm spinner with two horizon scanners (cones 60° and 110°) and a plane-field Sun
sensor (:func:`gcs_core.sim.scenarios.spinner_two_scanners`), 3 h, at 28.5°, 51.6°, 90° and
Sun-synchronous inclinations; the simulator crosses the WGS-84 ellipsoid exactly. Hidden:
a 0.6° cone-angle error Δγ (HS1), a 0.6° slit tilt ε_S (PSS1), an 18 km horizon-height
change (HS1), or nothing. The analyst's state leaves the hidden seed parameter out, so
discovery has to find it. :func:`run_case` simulates, discovers and scores against the
answer file; ``benchmarks/spinner_truth_sweep.py`` runs the whole sweep.
"""

from __future__ import annotations

import math
import time
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np
from test_truth_recovery import normalized_errors, simulate, truth_values

from gcs_core.config_schema import AnalysisConfig
from gcs_core.problem.linearization import linearize
from gcs_core.problem.state import HELD
from gcs_core.reporting import analysis_report
from gcs_core.session import Analysis
from gcs_core.sim.scenarios import spinner_two_scanners, with_effect

INCLINATIONS = (28.5, 51.6, 90.0, "sso")
#: hidden effect -> (effect id, magnitude, seed effects the starting state leaves out)
HIDDEN = {
    "nothing": (None, 0.0, ()),
    "d_gamma": ("HS1.d_gamma", math.radians(0.6), ("HS1.d_gamma",)),
    "tilt": ("PSS1.tilt", math.radians(0.6), ("PSS1.tilt",)),
    "height": ("HS1.horizon_height", 18.0, ()),
}
THREE_HOURS = 10800.0


@dataclass
class Outcome:
    """What one case gave: effects added, RMS, z-scores of the determined elements."""

    inclination: float | str
    hidden: str
    seed: int
    added: list[str]
    rms: dict[str, float]
    holdout: dict[str, float]
    z: dict[str, float]
    z_expected: dict[str, float]
    set_by_prior: dict[str, str]
    aliases: list[str] = field(default_factory=list)
    hidden_aliases: tuple[str, ...] = ()
    seconds: float = 0.0

    @property
    def worst_rms(self) -> float:
        return max(list(self.rms.values()) + list(self.holdout.values()))

    @property
    def worst_z(self) -> tuple[str, float]:
        name = max(self.z, key=lambda k: abs(self.z[k]))
        return name, self.z[name]

    @property
    def worst_z_expected(self) -> tuple[str, float]:
        name = max(self.z_expected, key=lambda k: abs(self.z_expected[k]))
        return name, self.z_expected[name]


def expected_estimates(a: Analysis, truth: dict[str, float]) -> dict[str, float]:
    """What the estimator should return given the truth, to first order: the true values
    plus what the state absorbs of the held elements' errors (a hidden effect the state
    aliases with) and the pull of the a priori (Eq 3-1 at the truth)::

        E[x̂] = x + (P̄⁻¹ + Hᵀ R⁻¹ H)⁻¹ [Hᵀ R⁻¹ H_h δ_h + P̄⁻¹ (x̄ − x)]

    with ``δ_h`` the true minus held value of each held element. Where nothing is hidden
    and the data dominate, this is the truth."""
    res, prob = a.result, a.problem
    state = prob.state
    names = list(res.solve_for)
    held = [e.name for e in state if e.role == HELD and e.name in truth and truth[e.name] != e.value]
    cols = names + held
    n = len(names)
    N = np.zeros((len(cols), len(cols)))
    for lin in linearize(prob, res.state.values(), cols):
        r = res.residuals[lin.name]
        use = lin.valid & ~r.edited
        Hw = (lin.H[use] / lin.sigma[None, :, None]).reshape(-1, len(cols))
        N += Hw.T @ Hw
    s0 = np.array([state[nm].sigma0 for nm in names])
    info0 = np.where(np.isfinite(s0), 1.0 / s0**2, 0.0)
    x_true = np.array([truth[nm] for nm in names])
    x_bar = np.array([state[nm].value for nm in names])
    rhs = info0 * (x_bar - x_true)
    if held:
        rhs += N[:n, n:] @ np.array([truth[h] - state[h].value for h in held])
    shift = np.linalg.solve(N[:n, :n] + np.diag(info0), rhs)
    return {nm: float(x_true[i] + shift[i]) for i, nm in enumerate(names)}


def run_case(inclination, hidden: str, seed: int, folder: Path, duration_s: float = THREE_HOURS) -> Outcome:
    t0 = time.perf_counter()
    effect, magnitude, exclude = HIDDEN[hidden]
    cfg = spinner_two_scanners(seed, inclination_deg=inclination, duration_s=duration_s)
    if effect is not None:
        cfg = with_effect(cfg, effect, magnitude)
    mission, truth = simulate(cfg, folder)
    a = Analysis(AnalysisConfig(mission=mission).with_changes(state={"exclude": exclude}))
    a.fit()
    a.discover()
    res = a.result
    tv = truth_values(truth, a.problem)
    loose = a.not_determined()
    z = {k: v for k, v in normalized_errors(res, tv).items() if k not in loose}
    z_exp = {k: v for k, v in normalized_errors(res, {**tv, **expected_estimates(a, tv)}).items() if k not in loose}
    rep = analysis_report(a)
    cand = next((c for c in a.candidates if c.id == effect), None)
    hidden_aliases = tuple(cand.aliases_state) + tuple(x for x, _ in cand.aliases_candidates) if cand else ()
    return Outcome(
        inclination,
        hidden,
        seed,
        [s.effect for s in a.steps if s.action == "add"],
        a.rms(),
        dict(a.holdout_rms),
        z,
        z_exp,
        loose,
        [al["text"] for al in rep.get("aliases", [])],
        hidden_aliases,
        time.perf_counter() - t0,
    )
