"""The channels a sensor's residual may follow, formed at that sensor's frames.

Everything an analyst would plot a residual against, as (N,) arrays on the sensor's own
frame times ``sd.t`` (:func:`sensor_channels`):

* ``aux:<name>`` — each auxiliary channel (ICD §6), held to the frame;
* ``orbit_phase`` — the argument of latitude ``u`` [rad] of the spacecraft, the angle from
  the ascending node in the orbit plane, ``u = atan2(r·(ĥ×n̂), r·n̂)`` with ``ĥ`` the orbit
  normal and ``n̂ = unit(ẑ × ĥ)`` the node (Vallado, *Fundamentals of Astrodynamics and
  Applications*, 4th ed., §2.5: argument of latitude). Families take it as its first and
  second harmonics ``cos u, sin u`` and ``cos 2u, sin 2u``;
* ``sun_angle`` — the angle between the Sun and the spacecraft's position vector [rad]
  (0 over the sub-solar point, π at local midnight), and ``eclipse`` — 1 in the Earth's
  cylindrical shadow (``r·ŝ < 0`` and ``|r − (r·ŝ)ŝ| < R_E``), 0 in sunlight;
* ``rate_x/y/z``, ``rate`` — the body rate the gyro measured [rad/s] and its magnitude,
  and ``angle_turned`` — ``∫|ω| dt`` from the start [rad] (with a gyro);
* ``fov_<component>`` — the sensor's own predicted measurement component (the measured vector's
  position in the field of view: a tracker's ``h, v``, a Sun sensor's counts; for a
  magnetometer the measured field's direction ``b/|b|`` in the sensor frame);
* ``tlm:<column>`` — a telemetry column of the sensor that is not a measurement (a star
  tracker's ``mag``, the catalogue magnitude of the star it reports);
* ``time`` — seconds from the first frame (a drift; its bins see steps);
* ``int:<name>`` — with a gyro carrying the attitude, the time integral of each *switch*
  (an aux channel whose values are exactly 0 and 1: a heater, a valve, a power state;
  :func:`switch_channels`) [s], ``∫(x − x̄) dt``
  less its least-squares quadratic in time over the span. A gyro bias that steps with the
  switch moves the carried attitude by ``∫ k x dt``; the fit's attitude, bias and bias rate
  take up its constant, linear and quadratic parts, and what is left in every sensor's
  residual follows this channel, not the switch itself (:mod:`gcs_core.models.gyro_steps`).

Each :class:`Channel` carries the unit it is in, what kind it is (for the catalogue's forms
and for the families) and the values; NaN where undefined.
"""

from __future__ import annotations

from collections.abc import Mapping
from dataclasses import dataclass

import numpy as np

from gcs_core.models.drift import argument_of_latitude

#: equatorial Earth radius [km] of the cylindrical shadow (WGS-84 a)
R_EARTH_KM = 6378.137
#: telemetry columns that are never channels (catalogue positions, the frame time)
NOT_CHANNELS = frozenset({"t", "ra", "dec"})


@dataclass(frozen=True)
class Channel:
    """One channel at a sensor's frames.

    Attributes
    ----------
    name : ``aux:tam_temp``, ``orbit_phase``, ``time``, ...; kind : ``aux``, ``orbit``,
    ``sun``, ``eclipse``, ``rate``, ``angle``, ``fov``, ``telemetry``, ``time``.
    unit : unit of ``values`` (``rad``, ``rad/s``, ``s``, ``1``, or the aux channel's own,
    shown as ``"unit of <name>"`` when unknown); values : (N,) array.
    periodic : the values are an angle on a circle (the orbit phase).
    """

    name: str
    kind: str
    unit: str
    values: np.ndarray
    periodic: bool = False

    @property
    def label(self) -> str:
        """The channel as the analyst knows it (``tam_temp``, ``orbit phase``)."""
        if self.kind == "aux_integral":
            return f"∫{self.name[4:]} dt"
        return self.name.split(":", 1)[1] if ":" in self.name else self.name.replace("_", " ")


def aux_unit(name: str) -> str:
    """A guess at an aux channel's unit from its name (aux.csv carries none): a name with
    ``temp`` is in °C; otherwise the channel's own unit, unnamed."""
    low = name.lower()
    if "temp" in low:
        return "°C"
    if low.startswith("mtb"):
        return "A m²"
    return f"unit of {name}"


def orbit_channels(builder, t: np.ndarray) -> dict[str, np.ndarray]:
    """``orbit_phase``, ``sun_angle`` and ``eclipse`` at times ``t`` (module docstring)."""
    r, v = builder.orbit(t)
    s = np.asarray(builder.ephemeris.sun_geocentric(t), dtype=float)
    s = s / np.linalg.norm(s, axis=-1, keepdims=True)
    rn = np.linalg.norm(r, axis=1)
    along = np.einsum("ij,ij->i", r, s)
    perp = np.linalg.norm(r - along[:, None] * s, axis=1)
    return {
        "orbit_phase": argument_of_latitude(r, v),
        "sun_angle": np.arccos(np.clip(along / rn, -1.0, 1.0)),
        "eclipse": ((along < 0) & (perp < R_EARTH_KM)).astype(float),
    }


def harmonics(u: np.ndarray, k: int) -> tuple[np.ndarray, np.ndarray]:
    """``cos k u, sin k u``: the orbit phase as a family's regressors."""
    return np.cos(k * u), np.sin(k * u)


def _held(t_src: np.ndarray, values: np.ndarray, t: np.ndarray) -> np.ndarray:
    """A channel sampled at ``t_src`` held to the times ``t`` (ICD §6 hold rule)."""
    k = np.clip(np.searchsorted(t_src, t, side="right") - 1, 0, len(t_src) - 1)
    return np.asarray(values, dtype=float)[k]


def switch_channels(aux) -> tuple[str, ...]:
    """The aux channels that are switches: every value 0 or 1, both present (an on/off
    state). A channel of other levels (a torquer's −60, 0, 60 A m², of which a short span
    may show only two) is not one."""
    if aux is None or len(aux) < 4:
        return ()
    out = []
    for name, col in aux.columns.items():
        x = np.asarray(col, dtype=float)
        if name != "t" and np.all((x == 0.0) | (x == 1.0)) and np.any(x == 0.0) and np.any(x == 1.0):
            out.append(name)
    return tuple(out)


def switched_integrals(aux, t: np.ndarray) -> dict[str, np.ndarray]:
    """``int:<name>`` at times ``t`` of each switch (module docstring): the held channel
    (ICD §6) integrated exactly between its rows, its mean over the rows' span taken out,
    then the least-squares quadratic in time."""
    out: dict[str, np.ndarray] = {}
    ta = np.asarray(aux.t, dtype=float) if aux is not None else np.zeros(0)
    for name in switch_channels(aux):
        x = np.asarray(aux.columns[name], dtype=float)
        span = ta[-1] - ta[0]
        dx = x - float(np.sum(x[:-1] * np.diff(ta)) / span)  # about the time mean of the held channel
        cum = np.concatenate([[0.0], np.cumsum(dx[:-1] * np.diff(ta))])  # ∫ at the rows
        k = np.clip(np.searchsorted(ta, t, side="right") - 1, 0, ta.size - 1)
        val = cum[k] + dx[k] * (t - ta[k])
        tt = (t - ta[0]) / span
        V = np.column_stack([np.ones_like(tt), tt, tt * tt])
        coef, *_ = np.linalg.lstsq(V, val, rcond=None)
        out[f"int:{name}"] = val - V @ coef
    return out


def rate_channels(gyro_table, t: np.ndarray) -> dict[str, np.ndarray]:
    """The measured body rate (interpolated to ``t``), its magnitude and the angle turned."""
    tg = np.asarray(gyro_table.t, dtype=float)
    w = np.column_stack([np.asarray(gyro_table.columns[c], dtype=float) for c in ("wx", "wy", "wz")])
    mag = np.linalg.norm(w, axis=1)
    turned = np.concatenate([[0.0], np.cumsum(0.5 * (mag[1:] + mag[:-1]) * np.diff(tg))])
    out = {f"rate_{ax}": np.interp(t, tg, w[:, i]) for i, ax in enumerate("xyz")}
    out["rate"] = np.interp(t, tg, mag)
    out["angle_turned"] = np.interp(t, tg, turned)
    return out


def sensor_channels(
    sd, *, builder, telemetry: Mapping | None = None, gyro: str | None = None, y_fov: np.ndarray | None = None
) -> list[Channel]:
    """Every channel at the frames of prepared sensor ``sd`` (module docstring).

    ``builder`` gives the orbit and the Sun; ``telemetry`` (sensor name -> table) the gyro's
    rates and the sensor's own non-measurement columns; ``gyro`` the gyro's name. ``y_fov``:
    the fit's predicted measurements, for the position in the field of view (the measured
    values carry the noise the residual carries: binned on them, any residual would seem
    to follow them, regression to the mean); the measurements where not given.
    """
    t = np.asarray(sd.t, dtype=float)
    out: list[Channel] = []
    aux = sd.geom.aux
    for name in aux:
        if name in ("pos_x", "pos_y", "pos_z") and sd.model.type_name != "magnetometer":
            continue
        out.append(Channel(f"aux:{name}", "aux", aux_unit(name), np.asarray(aux[name], dtype=float)))
    if sd.model.attitude_kind == "three_axis" and getattr(builder.physics, "field_model", "") != "constant":
        orb = orbit_channels(builder, t)
        out.append(Channel("orbit_phase", "orbit", "rad", orb["orbit_phase"], periodic=True))
        out.append(Channel("sun_angle", "sun", "rad", orb["sun_angle"]))
        if np.any(orb["eclipse"] > 0) and np.any(orb["eclipse"] == 0):
            out.append(Channel("eclipse", "eclipse", "1", orb["eclipse"]))
    if gyro is not None and sd.model.attitude_kind == "three_axis":
        for name, vals in switched_integrals(getattr(builder, "aux", None), t).items():
            out.append(Channel(name, "aux_integral", "s", vals))
    if telemetry is not None and gyro is not None and gyro in telemetry:
        for name, vals in rate_channels(telemetry[gyro], t).items():
            kind = "angle" if name == "angle_turned" else "rate"
            out.append(Channel(name, kind, "rad" if kind == "angle" else "rad/s", vals))
    y = np.asarray(sd.y if y_fov is None else np.where(np.isfinite(y_fov), y_fov, sd.y), dtype=float)
    if sd.model.type_name == "magnetometer":
        d = y / np.linalg.norm(y, axis=1, keepdims=True)
        for i, c in enumerate(sd.model.components):
            out.append(Channel(f"fov_{c}", "fov", "1", d[:, i]))
    else:
        for i, c in enumerate(sd.model.components):
            out.append(Channel(f"fov_{c}", "fov", sd.model.unit, y[:, i]))
    if telemetry is not None and sd.name in telemetry:
        tab = telemetry[sd.name]
        used_cols = set(sd.model.columns) | NOT_CHANNELS
        for col, vals in tab.columns.items():
            if col in used_cols:
                continue
            arr = np.asarray(vals)
            if arr.dtype.kind not in "fiu" or arr.shape[0] != len(tab.t):
                continue
            out.append(Channel(f"tlm:{col}", "telemetry", "1", _held(np.asarray(tab.t, float), arr, t)))
    out.append(Channel("time", "time", "s", t - t[0]))
    return [c for c in out if np.nanstd(c.values) > 0]
