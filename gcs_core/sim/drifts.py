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
  ``k (x − x_ref) (1, −0.7, 0.5)``.
"""

from __future__ import annotations

import numpy as np

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
