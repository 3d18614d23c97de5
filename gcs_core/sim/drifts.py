"""Hidden drifts no data book mentions: parameters that follow a temperature or the orbit.

Each is the sensor's own physics, written independently of the estimation model's
families (:mod:`gcs_core.models.drift`), which are first-order in the drift:

* ``bend`` (star tracker): the optics bend thermo-elastically; the sensor frame turns by
  the rotation vector ``θ(t) = k (x(t) − x_ref) â`` about a fixed axis ``â`` (a focal-plane
  axis or the boresight), ``M(t) = exp(−[θ×]) M`` exactly (a rotation matrix per frame);
  ``x`` is an aux channel (the bench temperature);
* ``orbit_bend`` (star tracker): the same rotation with angle ``A sin(u + φ)``, ``u`` the
  argument of latitude computed here from the true orbit;
* ``mag_error`` (star tracker): the centroid of a star of magnitude ``m`` is displaced in
  ``h`` by ``c (m − m_ref)`` (a brightness-dependent centroiding error: a form no family
  of the model holds);
* ``bias_drift`` (fine Sun sensor): the transfer function's offsets ``A1, B1`` [tan] move by
  ``k (x − x_ref)``;
* ``scale_drift`` (magnetometer): the response's diagonal gains move by
  ``k (x − x_ref) (1, −0.7, 0.5)``;
* ``heater_step`` (gyro): the drift-rate bias steps by a fixed vector ``Δb`` [rad/s] while
  the IRU's heater is on, ``b(t) = b_walk(t) + Δb h(t)`` with ``h`` ∈ {0, 1} the aux channel
  ``iru_heater`` (:func:`thermostat`): the heater changes the temperature gradient across
  the sensor block, and the bias follows the gradient within seconds (a step at the
  resolution of the 1 s rows).

The heater channel itself (:func:`thermostat`) is a bang-bang thermostat on a first-order
thermal model, not a sinusoid: the housing temperature ``T`` relaxes towards the
environment with time constant ``τ`` and the heater adds ``ΔT_on`` to the equilibrium::

    dT/dt = (T_env(t) + ΔT_on h − T) / τ,   T_env = T0 + A sin(2π t / P + φ)

The heater switches on below ``T_set − w/2`` and off above ``T_set + w/2`` (each threshold
jittered by a few hundredths of a degree per switch, as a real thermistor's read-out is), so
the duty cycle is long in the cold half of the orbit and short in the warm half: several
switches per orbit at irregular intervals.
"""

from __future__ import annotations

import numpy as np

from gcs_core.errors import InputError
from gcs_core.sim._rot import rotvec_to_dcm


def argument_of_latitude(r: np.ndarray, v: np.ndarray) -> np.ndarray:
    """``u`` [rad]: the angle in the orbit plane from the ascending node to the spacecraft."""
    h = np.cross(r, v)
    h = h / np.linalg.norm(h, axis=-1, keepdims=True)
    node = np.cross(np.array([0.0, 0.0, 1.0]), h)
    node = node / np.linalg.norm(node, axis=-1, keepdims=True)
    y = np.cross(h, node)
    return np.arctan2(np.sum(r * y, axis=-1), np.sum(r * node, axis=-1))


def channel(aux, spec: dict, t: np.ndarray) -> np.ndarray:
    """``x(t) − x_ref`` of a drift's aux channel at the (true) times ``t``."""
    if aux is None:
        raise ValueError(f"drift on aux channel '{spec['channel']}' needs the mission's aux channels")
    return np.asarray(aux.value(spec["channel"], t), dtype=float) - float(spec.get("ref", 0.0))


def bent_alignment(sensor, M: np.ndarray, world, aux, t: np.ndarray, r: np.ndarray, v: np.ndarray) -> np.ndarray:
    """(N, 3, 3) true alignment of a star tracker at times ``t`` (``bend``, ``orbit_bend``),
    or ``M`` broadcast when it has neither."""
    theta = np.zeros((t.size, 3))
    bend = sensor.value("bend", None)
    if bend:
        axis = np.asarray(bend["axis"], dtype=float)
        theta += float(bend["rate"]) * channel(aux, bend, t)[:, None] * (axis / np.linalg.norm(axis))
    ob = sensor.value("orbit_bend", None)
    if ob:
        axis = np.asarray(ob["axis"], dtype=float)
        ang = float(ob["amplitude"]) * np.sin(argument_of_latitude(r, v) + float(ob.get("phase", 0.0)))
        theta += ang[:, None] * (axis / np.linalg.norm(axis))
    if not (bend or ob):
        return np.broadcast_to(M, (t.size, 3, 3))
    return rotvec_to_dcm(theta) @ M[None]


def magnitude_error(sensor, mag: np.ndarray) -> np.ndarray:
    """Centroid displacement in ``h`` [rad] of stars of magnitude ``mag`` (``mag_error``)."""
    me = sensor.value("mag_error", None)
    if not me:
        return np.zeros_like(mag)
    return float(me["rate"]) * (np.asarray(mag, dtype=float) - float(me.get("ref", 4.0)))


def offsets(sensor, aux, t: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """(N,) extra offsets ``ΔA1, ΔB1`` [tan] of a fine Sun sensor (``bias_drift``)."""
    bd = sensor.value("bias_drift", None)
    if not bd:
        return np.zeros(t.size), np.zeros(t.size)
    x = channel(aux, bd, t)
    k = np.asarray(bd["rate"], dtype=float)
    return k[0] * x, k[1] * x


def gains(sensor, aux, t: np.ndarray) -> np.ndarray | None:
    """(N, 3) extra diagonal gains of a magnetometer (``scale_drift``), None without."""
    sd = sensor.value("scale_drift", None)
    if not sd:
        return None
    pattern = np.asarray(sd.get("pattern", (1.0, -0.7, 0.5)), dtype=float)
    return float(sd["rate"]) * channel(aux, sd, t)[:, None] * pattern[None, :]


#: the thermostat of the IRU heater (:func:`thermostat`): setpoint and band [°C], time
#: constant [s], heater's equilibrium rise [°C], environment mean, amplitude [°C] and period [s]
HEATER = {"set_c": 20.0, "band_c": 1.0, "tau_s": 1200.0, "rise_c": 8.0, "env_c": 16.0, "env_amp_c": 3.0}


def thermostat(duration_s: float, step_s: float, period_s: float, rng: np.random.Generator, **kw) -> np.ndarray:
    """Times [s] (multiples of ``step_s``, the first 0) at which the heater switches; it is
    off from 0 to the first switch after 0 when the first time is followed by an on-switch
    (module docstring). Seeded by ``rng`` (the environment's phase, the initial temperature,
    the thresholds' jitter)."""
    c = {**HEATER, **kw}
    n = int(np.floor(duration_s / step_s)) + 1
    phase = float(rng.uniform(0.0, 2.0 * np.pi))
    T = float(c["set_c"] + rng.uniform(-0.5, 0.5) * c["band_c"])
    on = False
    lo = c["set_c"] - 0.5 * c["band_c"] + 0.03 * rng.standard_normal()
    hi = c["set_c"] + 0.5 * c["band_c"] + 0.03 * rng.standard_normal()
    a = np.exp(-step_s / c["tau_s"])
    t = np.arange(n) * step_s
    env = c["env_c"] + c["env_amp_c"] * np.sin(2.0 * np.pi * t / period_s + phase)
    switches = [0.0]
    for k in range(1, n):
        target = env[k - 1] + (c["rise_c"] if on else 0.0)
        T = target + (T - target) * a  # exact over the step at a constant target
        if (not on and T < lo) or (on and T > hi):
            on = not on
            switches.append(float(t[k]))
            lo = c["set_c"] - 0.5 * c["band_c"] + 0.03 * rng.standard_normal()
            hi = c["set_c"] + 0.5 * c["band_c"] + 0.03 * rng.standard_normal()
    return np.asarray(switches)


def heater_step(sensor, aux, t: np.ndarray) -> np.ndarray | None:
    """(N, 3) the gyro's bias step [rad/s] at times ``t`` (``heater_step``), None without."""
    hs = sensor.value("heater_step", None)
    if not hs:
        return None
    return np.asarray(hs["rate"], dtype=float)[None, :] * channel(aux, hs, t)[:, None]


def heater_effect(s, m: float, kw: dict) -> None:
    """The hidden effect ``<GYRO>.bias_vs_iru_heater``: a step ``m (0.6, −0.48, 0.64)`` [rad/s]."""
    s.true["heater_step"] = {"channel": "iru_heater", "ref": 0.0, "rate": [0.6 * m, -0.48 * m, 0.64 * m]}


def with_heater(cfg, effect: str) -> None:
    """The heater's channel is written with its effect (it needs the mission's aux channels)."""
    if effect == "bias_vs_iru_heater":
        if cfg.aux is None:
            raise InputError(f"effect '{effect}' needs the mission's aux channels", key="effect_id")
        cfg.aux.heater = True
