"""The gyro's noise from the data book and Farrenkopf's process noise (ICD §5 ``gyro``; Eq 3-4, 4-38).

One definition, read by every estimator, the predictor and the gyro observation model:

* :func:`gyro_noise` — σ_v (``arw``), σ_u (``rrw``) and σ_e (``electronic``) of a gyro,
  as a :class:`GyroNoise`;
* :func:`farrenkopf_q` — the process noise of one gyro step (Eq 3-4's ``Q``), used by
  the Kalman filter, the covariance-only predictor and the whole-span knots.

The noise model (Farrenkopf 1978): a rate output ``y`` integrated over a step carries an
angle random walk of spectral density σ_v² [rad²/s] and a bias that random-walks with
σ_u² [rad²/s³]; an optional read-out (electronic) noise σ_e [rad] is a white error of
the integrated angle at each sample, which telescopes in the integral: it does not
accumulate, so it is not process noise but a white attitude error seen by the
measurements (the Kalman filter and the predictor add ``σ_e² H_θ H_θᵀ`` to the
measurement covariance of one epoch; the whole-span fit eliminates it per epoch,
:mod:`gcs_core.estimators.whole_span.readout`).

Rule for a missing key (a mission file always holds ``arw`` and ``rrw``,
:mod:`gcs_core.io.mission`; a data book built in memory may not): without ``arw`` the
gyro's generic ``noise`` [rad/s] is the 1-sigma rate per sample of length Δt, i.e.
``σ_v = noise·sqrt(Δt)`` (the same variance per sample the observation model gives);
without both the gyro is refused (InputError naming the key). ``rrw`` and
``electronic`` default to 0.

References
----------
Farrenkopf, R. L., "Analytic steady-state accuracy solutions for two common spacecraft
attitude estimators", J. Guidance & Control 1(4), 1978. Crassidis, J. L. and Junkins,
J. L., *Optimal Estimation of Dynamic Systems*, 2nd ed., CRC 2012, §7.2.1 (σ_v, σ_u
and the discrete Q).
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from gcs_core.errors import InputError
from gcs_core.models import common


@dataclass(frozen=True)
class GyroNoise:
    """Gyro noise of the data book (ICD §5 ``gyro``), Farrenkopf's model.

    Attributes
    ----------
    sigma_v : angle random walk σ_v [rad/s^0.5] (``arw``).
    sigma_u : rate random walk σ_u [rad/s^1.5] (``rrw``); the bias random-walks iff > 0.
    sigma_e : electronic (angle read-out) noise σ_e [rad] (``electronic``).
    """

    sigma_v: float = 0.0
    sigma_u: float = 0.0
    sigma_e: float = 0.0

    @property
    def process(self) -> bool:
        """Whether the gyro adds process noise (σ_v or σ_u > 0; σ_e does not accumulate)."""
        return self.sigma_v > 0 or self.sigma_u > 0

    def scaled(self, k: float) -> GyroNoise:
        """Every σ multiplied by ``k`` (a process-noise tuning factor)."""
        return GyroNoise(k * self.sigma_v, k * self.sigma_u, k * self.sigma_e)


def gyro_noise(sensor, dt: float = 1.0) -> GyroNoise:
    """σ_v, σ_u, σ_e of a gyro's data book (module docstring, rule for missing keys).

    Parameters
    ----------
    sensor : the gyro's :class:`~gcs_core.io.types.SensorSpec`.
    dt : sample interval [s] (only used when ``arw`` is absent: ``σ_v = noise·sqrt(dt)``).
    """
    arw = common.book_scalar(sensor, "arw")
    if arw is None:
        if sensor.noise is None:
            raise InputError(f"gyro '{sensor.name}' needs 'arw' (or 'noise')", key=common.book_key(sensor, "arw"))
        arw = float(sensor.noise) * np.sqrt(float(dt))
    rrw = common.book_scalar(sensor, "rrw", 0.0) or 0.0
    ele = common.book_scalar(sensor, "electronic", 0.0) or 0.0
    return GyroNoise(float(arw), float(rrw), float(ele))


def farrenkopf_q(dt: np.ndarray, noise: GyroNoise, Wy: np.ndarray, Wb: np.ndarray, axes=()) -> np.ndarray:
    """Process noise of gyro steps (Eq 3-4's ``Q``, the Eq 4-38 noise matrix; Farrenkopf 1978).

    Over a step ``Δt`` the attitude error gathers the rate noise and the integral of the
    bias walk; the bias gathers the walk::

        Q_θθ = σ_v² Δt W_y W_yᵀ + σ_u² Δt³/3 W_b W_bᵀ,   Q_θb = σ_u² Δt²/2 W_b,   Q_bb = σ_u² Δt I

    with ``W_y = ∂ω/∂y = Mᵀ G⁻¹`` and ``W_b = ∂ω/∂b = −Mᵀ`` (Eq 4-32 inverted) for the
    body-frame error; another frame's error takes its own maps (the whole-span knots'
    GCI-frame α: ``W_y = I``, ``W_b = −R``). The bias walks on every axis; only the
    ``axes`` in the state get the ``θb``, ``bb`` blocks. σ_e is not in Q (module
    docstring).

    Parameters: dt (K,) [s]; Wy, Wb (3, 3) or one per step (K, 3, 3); axes: bias axes
    in the state (nb). Returns (K, d, d), d = 3 + nb.
    """
    dt = np.asarray(dt, float)[:, None, None]
    Wy, Wb = np.asarray(Wy, float), np.asarray(Wb, float)
    axes = list(axes)
    nb = len(axes)
    Q = np.zeros((dt.shape[0], 3 + nb, 3 + nb))
    v2, u2 = noise.sigma_v**2, noise.sigma_u**2
    Q[:, :3, :3] = v2 * dt * (Wy @ np.swapaxes(Wy, -1, -2)) + u2 * dt**3 / 3.0 * (Wb @ np.swapaxes(Wb, -1, -2))
    if nb:
        Q[:, :3, 3:] = u2 * dt**2 / 2.0 * Wb[..., axes]
        Q[:, 3:, :3] = np.swapaxes(Q[:, :3, 3:], 1, 2)
        Q[:, 3:, 3:] = u2 * dt * np.eye(nb)
    return Q
