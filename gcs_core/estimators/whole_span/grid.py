"""The knots of a whole-span fit laid out for a problem (:mod:`.fit`): whether the gyro
carries process noise at all (:func:`process_noise`) and the grid spaced from the
information the data give the attitude (:func:`make_knots`, :func:`.knots.knot_spacing`)."""

from __future__ import annotations

import numpy as np

from gcs_core.estimators.kalman.mekf import attitude_gyro_noise
from gcs_core.estimators.whole_span import knots as kn
from gcs_core.models.gyro_noise import GyroNoise
from gcs_core.problem.attitude import RPY
from gcs_core.problem.build import Problem
from gcs_core.problem.gyro_attitude import GyroAttitude


def process_noise(problem: Problem) -> GyroNoise | None:
    """The gyro noise of the data book when the attitude is gyro-carried and noisy."""
    if problem.gyro_name is None or not isinstance(problem.attitude, GyroAttitude):
        return None
    noise = attitude_gyro_noise(problem)
    return noise if noise.process else None


def make_knots(
    problem: Problem, noise: GyroNoise, information: np.ndarray, names, *, spacing: float | None = None
) -> kn.KnotGrid:
    """Knots over the span of the gyro knots, spaced by :func:`knots.knot_spacing` from the
    information per second the data give the attitude (the batch's roll/pitch/yaw block)."""
    att = problem.gyro_attitude
    t0, t1 = float(att.knots[0]), float(att.knots[-1])
    for sd in problem.sensors:
        if sd.n:
            t1 = max(t1, float(sd.t[-1]))
    dt = float(np.median(att.dt)) if att.dt.size else 1.0
    if spacing is None:
        ix = [names.index(nm) for nm in RPY if nm in names]
        rate = float(np.linalg.eigvalsh(information[np.ix_(ix, ix)])[-1]) / max(t1 - t0, 1.0) if ix else 0.0
        spacing = kn.knot_spacing(
            noise.sigma_v if noise.sigma_v > 0 else noise.sigma_u * 1e3, rate, dt_min=max(dt, 1e-3)
        )
    return kn.make_grid(t0, t1, spacing, noise.sigma_v, noise.sigma_u, min_step=max(dt, 1e-3))
