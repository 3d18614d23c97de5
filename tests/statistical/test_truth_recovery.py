"""Truth recovery on simulated missions (issue 6 acceptance).

"On simulator missions with known truth (three-axis and spinner), every estimated parameter
lies within 3σ of truth." Each case simulates a mission with :mod:`gcs_core.sim`, fits it
through :class:`~gcs_core.session.Analysis` with the default state, and compares *every*
solve-for element with its true value read from the answer file (``truth.json``)::

    z_i = (x̂_i − x_i) / σ_i,     |z_i| ≤ 3        (σ_i = sqrt(P_ii), the fit's own sigma)

Truth of each element (:func:`truth_values`):

* ``att.roll/pitch/yaw``: the true attitude at ``t_ref`` rebuilt from the answer file's
  attitude profile and orbit (the simulator's :class:`~gcs_core.sim.truth.World`),
  expressed as roll/pitch/yaw in the estimator's own reference frame;
  ``att.ra/dec``: the answer file's ``spin_axis_deg``.
* gyro ``G_ij``: ``G_true − I``; ``bias``/``bias_rate``: the least-squares line through the
  true bias history (the simulator's random walk logged once a minute), as the estimator
  parametrizes it: ``b(t) = bias + bias_rate (t − t_mid)`` in a batch fit, and in the Kalman
  smoother the random-walk part at ``t_ref``, ``b(t_ref) − bias_rate (t_ref − t_mid)``. The
  whole-span fit carries ``b(t) = bias + bias_rate (t − t_mid) + β(t)`` with the knots'
  random walk ``β(t_ref) = 0`` (:mod:`gcs_core.estimators.whole_span.knots`): its ``bias_rate`` is the
  simulator's deterministic drift (0 unless hidden), not the slope of the walk, which ``β``
  carries and the fit's σ counts, and its ``bias`` is ``b(t_ref) − bias_rate (t_ref − t_mid)``
  with that drift (as :mod:`gcs_core.trade.montecarlo` reads it).
* every other element: the sensor's ``true`` values (scale, bias, transfer coefficients,
  horizon angles, ephemeris time error).

Method. The three-axis cases use ``method = "kalman"``: the batch estimator propagates the
attitude with the gyros at Q = 0, so the gyro's angle random walk σ_v and rate random walk
σ_u are not in its covariance; on a two-hour mission its gyro elements miss the truth by up
to ~9σ, where the default whole-span fit, which carries them, stays within 3σ
(:func:`test_default_covariance_carries_gyro_noise_on_long_missions`). On 30-minute missions the accumulated gyro
noise is still small (σ_v·sqrt(T) ≈ 2.8″ against the trackers' 8″ per sighting) and the
batch σ matches the Monte-Carlo scatter within 15 % (200 seeds; at 60 minutes the attitude
and gyro-bias σ are 23–50 % too small), so the batch fit is tested at 30 minutes. The
spinner has no gyro: batch least squares is exact there.

Statistics. A correct fit puts each |z_i| above 3 with probability 0.27 %; with 9–37
elements per mission, about one mission in ten would fail by chance. The seeds are fixed
(same seed, same files) and were chosen before looking: seed 1 for every case. Largest
|z| at seed 1: Sun-pointing 2.13 (IRU.G_11), Earth-pointing 2.27 (IRU.G_11), inertial 1.65
(FHST2.scale_h), 30-min batch 2.35 (TAM1.bias_z), calibrated three-axis 2.24
(CSS1.K_beta), spinner 1.25 and calibrated spinner 1.26 (HS1.d_rho). Over seeds 1–6 every
case stays within 3σ (largest 2.94), and the RMS of z per element is near 1; the
predicted σ against the Monte-Carlo scatter over 200 seeds is in
``benchmarks/monte_carlo_consistency.py``.

References
----------
Bar-Shalom, Li & Kirubarajan, *Estimation with Applications to Tracking and Navigation*,
Wiley 2001, §5.4 (normalized estimation errors).
"""

from __future__ import annotations

import json
import math
from collections.abc import Callable, Mapping
from dataclasses import dataclass, field
from pathlib import Path
from types import SimpleNamespace

import numpy as np
import pytest

from gcs_core.config_schema import AnalysisConfig
from gcs_core.session import Analysis
from gcs_core.sim.config import MissionConfig, OrbitElements, Slew, ThreeAxisProfile
from gcs_core.sim.scenarios import nominal_threeaxis, spinner_nominal, with_effect
from gcs_core.sim.truth import World
from gcs_core.sim.writer import write_mission
from gcs_core.units import DEG

#: the acceptance bound of issue 6, in sigmas of the fit's own covariance
three_sigma = 3.0
ONE_HOUR = 3600.0
HALF_HOUR = 1800.0


# ----------------------------------------------------------------------------- truth
def _angle_diff(a: float, b: float) -> float:
    """a − b wrapped to (−π, π]."""
    return (a - b + math.pi) % (2.0 * math.pi) - math.pi


def _world(truth: Mapping) -> World:
    """The simulator's truth environment rebuilt from the answer file (three-axis)."""
    att = dict(truth["attitude"])
    slews = [Slew(**s) for s in att.pop("slews", [])]
    profile = ThreeAxisProfile(**{k: tuple(v) for k, v in att.items()}, slews=slews)
    cfg = MissionConfig(
        name=truth["mission"],
        epoch=truth["epoch"],
        attitude_mode=truth["attitude_mode"],
        duration_s=float(truth["duration_s"]),
        orbit=OrbitElements(**truth["orbit"]),
        attitude=profile,
    )
    return World(cfg)


def _bias_line(truth: Mapping, gyro: str, t0: float, t1: float):
    """Intercept at the span's middle and slope of the LS line through the true bias, (3,) each."""
    h = np.asarray(truth["gyro_bias_history"][gyro], float)
    t, b = h[:, 0], h[:, 1:]
    sel = (t >= t0 - 1e-9) & (t <= t1 + 1e-9)
    A = np.column_stack([np.ones(int(sel.sum())), t[sel] - 0.5 * (t0 + t1)])
    coef, *_ = np.linalg.lstsq(A, b[sel], rcond=None)
    return coef[0], coef[1]


def truth_values(truth: Mapping, problem, method: str = "batch") -> dict[str, float]:
    """Element name -> true value, from an answer file (module docstring).

    ``problem`` is the fitted :class:`~gcs_core.problem.build.Problem` (for ``t_ref``, the
    gyro span and the estimator's reference frame); ``method`` selects the gyro-bias
    parametrization (module docstring): ``"batch"`` (the line through the walk),
    ``"kalman"`` (the walk at ``t_ref`` less that line's drift) or ``"whole_span"`` (the walk
    at ``t_ref`` and the simulator's deterministic drift).
    """
    out: dict[str, float] = {}
    att = problem.attitude
    for name, s in truth["sensors"].items():
        tr, kind = s["true"], s["type"]
        if kind == "magnetometer":
            out |= {f"{name}.bias_{c}": float(tr["bias"][i]) for i, c in enumerate("xyz")}
        elif kind == "gyro":
            G = np.asarray(tr.get("G", np.eye(3)), float) - np.eye(3)
            out |= {f"{name}.G_{i + 1}{j + 1}": float(G[i, j]) for i in range(3) for j in range(3)}
            if getattr(att, "gyro", None) == name:
                t0, t1 = float(att.knots[0]), float(att.knots[-1])
                b_mid, slope = _bias_line(truth, name, t0, t1)
                if method in ("kalman", "whole_span"):
                    # the process-noise fits carry the bias from t_ref (their knots start there)
                    h = np.asarray(truth["gyro_bias_history"][name], float)
                    b_ref = np.array([np.interp(att.t_ref, h[:, 0], h[:, 1 + i]) for i in range(3)])
                    if method == "whole_span":
                        # the knots' β carries the walk (its slope included, in the fit's σ):
                        # bias_rate is the simulator's deterministic drift
                        slope = np.asarray(tr.get("bias_rate", (0.0, 0.0, 0.0)), float)
                    b_mid = b_ref - slope * (att.t_ref - 0.5 * (t0 + t1))
                for i, c in enumerate("xyz"):
                    out[f"{name}.bias_{c}"] = float(b_mid[i])
                    out[f"{name}.bias_rate_{c}"] = float(slope[i])
            else:
                out |= {f"{name}.bias_{c}": float(tr["bias"][i]) for i, c in enumerate("xyz")}
        elif kind == "star_tracker":
            out[f"{name}.scale_h"], out[f"{name}.scale_v"] = map(float, tr["scale"])
        elif kind == "fine_sun":
            for side, coeff in (("alpha", tr["coeff_alpha"]), ("beta", tr["coeff_beta"])):
                names = ("A1", "A2", "A3", "k_alpha") if side == "alpha" else ("B1", "B2", "B3", "k_beta")
                out |= {f"{name}.{k}": float(v) for k, v in zip(names, coeff)}
        elif kind == "coarse_sun":
            out[f"{name}.K_alpha"], out[f"{name}.K_beta"] = map(float, tr["scale"])
            out[f"{name}.b_alpha"], out[f"{name}.b_beta"] = map(float, tr["bias"])
        elif kind == "plane_field_sun":
            out[f"{name}.tilt"] = float(tr["tilt_deg"]) * DEG
            out[f"{name}.bias"] = float(tr["bias"])
        elif kind == "horizon":
            out |= {f"{name}.{k}": float(tr.get(k, 0.0)) for k in ("d_gamma", "d_rho", "d_phi", "eps_H")}
            out[f"{name}.d_t"] = float(truth.get("ephemeris_time_error_s", 0.0))
            out[f"{name}.horizon_height"] = float(tr["horizon_height_km"]) - float(s["book"]["horizon_height_km"])
            out[f"{name}.oblateness"] = float(tr.get("flattening_excess", 0.0))
    if truth["attitude_mode"] == "spinning":
        ra, dec = truth["spin_axis_deg"]
        out["att.ra"], out["att.dec"] = ra * DEG, dec * DEG
    elif hasattr(att, "t_ref"):
        ref = getattr(att, "ref", att)
        C_true = _world(truth).attitude(np.array([att.t_ref]))[0]
        out["att.roll"], out["att.pitch"], out["att.yaw"] = ref.rpy_from_dcm(C_true, att.t_ref)
    return out


def normalized_errors(result, truth: Mapping[str, float]) -> dict[str, float]:
    """Solve-for element -> ``(x̂ − x)/σ`` (angles wrapped); KeyError if a truth is missing."""
    z = {}
    for i, name in enumerate(result.solve_for):
        if name not in truth:
            raise KeyError(f"no truth for solve-for element {name}")
        d = result.x[i] - truth[name]
        if name.startswith("att."):
            d = _angle_diff(result.x[i], truth[name])
        z[name] = float(d / math.sqrt(result.P[i, i]))
    return z


# ----------------------------------------------------------------------------- missions
def simulate(cfg: MissionConfig, folder: Path) -> tuple[Path, dict]:
    """Write the mission and its answer file; returns (mission dir, truth)."""
    mission = write_mission(cfg, folder / "mission", truth_path=folder / "truth.json")
    return mission, json.loads((folder / "truth.json").read_text())


def fit_and_compare(cfg: MissionConfig, folder: Path, method: str):
    """Simulate, fit with the default state; returns (analysis, result, z, truth by element)."""
    mission, truth = simulate(cfg, folder)
    a = Analysis(AnalysisConfig(mission=mission, method=method))
    res = a.fit(holdout=False)
    tv = truth_values(truth, a.problem, method)
    return a, res, normalized_errors(res, tv), tv


def threeaxis(mode: str, seed: int, duration_s: float = ONE_HOUR) -> MissionConfig:
    cfg = nominal_threeaxis(mode, seed=seed, duration_s=duration_s)
    if mode == "earth_pointing" and duration_s < 5400.0:
        # the zenith-looking fine Sun sensor sees the Sun only near orbit noon; an empty
        # telemetry file is refused by the importer
        cfg.sensors = [s for s in cfg.sensors if s.name != "FSS1"]
    return cfg


def calibrated_threeaxis(seed: int) -> MissionConfig:
    """Sun-pointing, true parameters away from the data book (elements all in the state)."""
    cfg = threeaxis("sun_pointing", seed)
    cfg = with_effect(cfg, "TAM1.bias", 50.0)  # nT, direction (0.6, -0.48, 0.64)
    cfg = with_effect(cfg, "IRU.bias", 1e-6)  # rad/s
    cfg = with_effect(cfg, "FHST1.scale", 1e-3)  # S_H, S_V = 1.001, 0.9993
    return with_effect(cfg, "CSS1.bias", 1e-3)  # rad


def calibrated_spinner(seed: int) -> MissionConfig:
    cfg = with_effect(spinner_nominal(seed=seed), "HS1.d_gamma", 0.2 * DEG)
    return with_effect(cfg, "PSS1.bias", 4e-3)  # rad (σ ≈ 3.7e-4 in 3 h)


@dataclass(frozen=True)
class Case:
    id: str
    build: Callable[[int], MissionConfig]
    seed: int
    method: str
    #: elements whose truth differs from the data book (they must move to it)
    moved: tuple[str, ...] = field(default_factory=tuple)


CASES = [
    Case("sun_pointing", lambda s: threeaxis("sun_pointing", s), 1, "kalman"),
    Case("earth_pointing", lambda s: threeaxis("earth_pointing", s), 1, "kalman"),
    Case("inertial", lambda s: threeaxis("inertial", s), 1, "kalman"),
    Case("sun_pointing_30min_batch", lambda s: threeaxis("sun_pointing", s, HALF_HOUR), 1, "batch"),
    Case(
        "calibrated_threeaxis",
        calibrated_threeaxis,
        1,
        "kalman",
        ("TAM1.bias_x", "IRU.bias_x", "FHST1.scale_h", "CSS1.b_alpha"),
    ),
    Case("spinner", spinner_nominal, 1, "batch"),
    Case("calibrated_spinner", calibrated_spinner, 1, "batch", ("HS1.d_gamma", "PSS1.bias")),
]


@pytest.mark.parametrize("case", CASES, ids=[c.id for c in CASES])
def test_every_element_within_three_sigma_of_truth(case, tmp_path):
    a, res, z, tv = fit_and_compare(case.build(case.seed), tmp_path, case.method)
    # the iterated smoother may stop at its pass limit a hair short of its 0.01σ tolerance
    assert res.status in (("converged", "max_passes") if case.method == "kalman" else ("converged",)), res.message
    outside = {k: round(v, 2) for k, v in z.items() if abs(v) > three_sigma}
    assert not outside, f"{case.id} (seed {case.seed}, {case.method}): outside 3σ {outside}; {len(z)} elements"
    # the parameters moved away from the data book are determined by the data (σ well
    # below the offset), so "within 3σ of truth" means "moved to the truth"
    book = {e.name: e.value for e in a.problem.state}
    for name in case.moved:
        i = res.solve_for.index(name)
        offset = abs(tv[name] - book[name])
        assert math.sqrt(res.P[i, i]) < 0.2 * offset, f"{name}: σ not small against the offset"


def test_default_covariance_carries_gyro_noise_on_long_missions(tmp_path):
    """Inertial, two hours, default (whole-span) method: the gyro's random walks are
    process noise, so every element, the gyro's included, is within 3σ of its truth
    (the batch, which takes the gyro as exact, missed by up to ~9σ here)."""
    _, _, z, _ = fit_and_compare(threeaxis("inertial", 1, 2 * ONE_HOUR), tmp_path, "whole_span")
    assert max(abs(v) for v in z.values()) <= three_sigma


def test_gyro_bias_truth_follows_each_estimator_form():
    """The drift bias's truth in each estimator's parametrization (module docstring), on a
    logged walk with a deterministic drift: the whole-span fit's ``bias_rate`` is the drift
    (its knots carry the walk and its slope), the batch's and the smoother's the line
    through the walk; each form's ``bias + bias_rate (t − t_mid)`` meets the simulator's
    bias where that form anchors it (``t_ref`` for the process-noise fits)."""
    rng = np.random.default_rng(11)
    span, drift = 4 * ONE_HOUR, np.array([2e-10, -1e-10, 0.0])  # rad/s, rad/s²
    t = np.arange(0.0, span + 1.0, 60.0)
    walk = np.cumsum(rng.standard_normal((t.size, 3)) * 3.2e-10 * math.sqrt(60.0), axis=0)
    b = 1e-6 + walk + drift * t[:, None]
    truth = {
        "attitude_mode": "spinning",
        "spin_axis_deg": [0.0, 0.0],
        "sensors": {"IRU": {"type": "gyro", "true": {"bias_rate": drift.tolist()}}},
        "gyro_bias_history": {"IRU": np.column_stack([t, b]).tolist()},
    }
    t_ref, t_mid = 0.0, 0.5 * span

    att = SimpleNamespace(gyro="IRU", knots=np.array([0.0, span]), t_ref=t_ref)  # what the truth reads
    problem = SimpleNamespace(attitude=att)
    rate = {
        m: np.array([truth_values(truth, problem, m)[f"IRU.bias_rate_{c}"] for c in "xyz"])
        for m in ("batch", "kalman", "whole_span")
    }
    bias = {m: np.array([truth_values(truth, problem, m)[f"IRU.bias_{c}"] for c in "xyz"]) for m in rate}
    one_rad_s2 = 1e-15  # far below the walk's slope scatter over 4 h (~2e-12 rad/s²)
    assert np.allclose(rate["whole_span"], drift, atol=one_rad_s2)
    assert np.allclose(rate["kalman"], rate["batch"], atol=one_rad_s2)
    assert np.max(np.abs(rate["batch"] - drift)) > 1e-13  # the walk's slope is not the drift
    for m in ("kalman", "whole_span"):  # anchored at t_ref: b(t_ref) = bias + bias_rate (t_ref − t_mid)
        assert np.allclose(bias[m] + rate[m] * (t_ref - t_mid), b[0], atol=1e-15)
