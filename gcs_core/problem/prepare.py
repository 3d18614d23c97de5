"""Data preparation (the seed's SIDP, §3.2.2): telemetry + ephemeris → model inputs.

For each sensor this builds, once, everything its observation model needs except the
attitude: reference vectors in GCI at the sensor's frame times (Sun, geomagnetic field,
catalog stars), the spacecraft state, auxiliary channels held to each frame (ICD §6) and
non-measurement telemetry (the horizon scanner's spin rate). The estimator then only
adds the attitude at each iteration.

The *physics options* choose which always-on corrections the reference vectors carry:

* ``stellar_aberration`` — annual + orbital aberration of catalog star directions;
* ``solar_aberration`` — the Sun seen from the moving spacecraft (orbital aberration;
  the ephemeris Sun is already apparent-geocentric, ICD §4);
* ``sun_parallax`` — the Sun from the spacecraft (``s − r``) rather than from the Earth;
* ``earth_oblateness`` — the horizon scanners see the WGS-84 ellipsoid (flattening
  ``f = 1/298.257223563``) under the CO2 layer, not the ICD's sphere (``docs/horizon.md``);
* ``field_model`` — ``"igrf"`` (degree 13), ``"dipole"``, or ``"constant"``: one unknown
  field vector of the reference frame, estimated with the rest (a laboratory on the
  ground, docs/ground.md); the geometry then carries no field and the magnetometer model
  holds the three elements ``field.B_x/y/z``.

Each option is also a catalogue effect (``model.<option>``): the diagnosis compares the
predictions with and without it (:func:`geometry_variants`).

Memory. What is stored per frame is what the models read: the reference vectors (and
the magnetometer's field rate). The spacecraft position and velocity are not kept (no
model reads them; :meth:`GeometryBuilder.orbit` gives them for any frames), and the
auxiliary channels are held lazily (:class:`HeldChannels`), so a week of 1 Hz data costs
a few tens of bytes per frame beyond the measurements.
"""

from __future__ import annotations

from collections.abc import Iterator, Mapping
from dataclasses import dataclass, field, fields, replace
from typing import Any

import numpy as np

from gcs_core.ephem import corrections
from gcs_core.ephem.ephemeris import Ephemeris
from gcs_core.ephem.geomag import GeomagField
from gcs_core.frames.reference import spin_axis
from gcs_core.io.aux_hold import aux_channel_names
from gcs_core.io.types import MissionSpec, Table
from gcs_core.models import make_model
from gcs_core.models.base import Geometry, ObservationModel
from gcs_core.models.horizon import FLATTENING as WGS84_FLATTENING
from gcs_core.units import DEG

#: ``[physics] field_model``: IGRF, a tilted dipole, or an unknown constant field (a lab)
FIELD_MODELS = ("igrf", "dipole", "constant")


@dataclass(frozen=True)
class PhysicsOptions:
    """Always-on physics applied to reference vectors (module docstring).

    The defaults here are the one table of them: the analysis config
    (:mod:`gcs_core.config`), the session and the predictor take theirs from it.
    """

    stellar_aberration: bool = field(default=True, metadata={"doc": "stellar aberration of star directions"})
    solar_aberration: bool = field(default=True, metadata={"doc": "aberration of the Sun's direction"})
    sun_parallax: bool = field(default=True, metadata={"doc": "the Sun seen from the spacecraft, not the Earth"})
    earth_oblateness: bool = field(
        default=True, metadata={"doc": "WGS-84 horizon for horizon scanners (docs/horizon.md)"}
    )
    field_model: str = field(
        default="igrf",
        metadata={
            "doc": "IGRF-14, a dipole, or a constant unknown field (a lab, docs/ground.md)",
            "choices": FIELD_MODELS,
        },
    )

    def as_dict(self) -> dict:
        return {f.name: getattr(self, f.name) for f in fields(self)}


#: frames per chunk when reference vectors are computed (bounded temporaries)
CHUNK_FRAMES = 50_000

#: physics effects of the catalogue: option name -> (value when on: the default, value when off)
PHYSICS_EFFECTS = {
    name: (getattr(PhysicsOptions(), name), off)
    for name, off in {
        "stellar_aberration": False,
        "solar_aberration": False,
        "sun_parallax": False,
        "earth_oblateness": False,
        "field_model": "dipole",
    }.items()
}


@dataclass(frozen=True)
class SensorData:
    """One sensor's measurements and attitude-free geometry.

    Attributes
    ----------
    name : sensor name.
    model : its observation model.
    t : (N,) frame times [s].
    y : (N, m) measurements, telemetry units.
    sigma : (m,) 1-sigma noise per component.
    geom : model inputs without the attitude (``C_BI`` / ``spin_axis_I`` unset).
    lines : (N,) line numbers in the telemetry file (for the editing report).
    """

    name: str
    model: ObservationModel
    t: np.ndarray
    y: np.ndarray
    sigma: np.ndarray
    geom: Geometry
    lines: np.ndarray

    @property
    def n(self) -> int:
        return int(self.t.shape[0])


class HeldChannels(Mapping):
    """The auxiliary channels held at N frames (ICD §6, :func:`~gcs_core.io.aux_hold.hold_channels`), computed
    when a channel is read rather than stored: ``name -> (N,)`` array.

    A full-length mapping keeps what it has computed (the TUI and the Kalman filter read
    whole channels); :meth:`window` gives the mapping of frames ``lo..hi−1``, which the
    chunked linearization reads chunk by chunk without ever holding a whole channel.
    """

    def __init__(self, aux: Table | None, t: np.ndarray, *, keep: bool = True, names: tuple[str, ...] | None = None):
        self._aux = aux
        self._t = t
        if names is None:
            names = aux_channel_names(aux) if aux is not None and len(aux) else ()
        self._names = names
        self._keep = keep
        self._done: dict[str, np.ndarray] = {}
        self._idx: np.ndarray | None = None

    def _index(self) -> np.ndarray:
        idx, aux = self._idx, self._aux
        if idx is None:
            assert aux is not None  # channels are named only with aux data
            idx = np.clip(np.searchsorted(aux.t, self._t, side="right") - 1, 0, len(aux) - 1)
            if not self._keep:  # a chunk's mapping: every channel reads it
                self._idx = idx
        return idx

    def __getitem__(self, name: str) -> np.ndarray:
        if name not in self._names:
            raise KeyError(name)
        out = self._done.get(name)
        if out is None:
            assert self._aux is not None  # channels are named only with aux data
            out = np.asarray(self._aux.columns[name])[self._index()]
            if self._keep:
                self._done[name] = out
        return out

    def __contains__(self, name) -> bool:
        return name in self._names

    def __iter__(self) -> Iterator[str]:
        return iter(self._names)

    def __len__(self) -> int:
        return len(self._names)

    def window(self, lo: int, hi: int) -> HeldChannels:
        w = HeldChannels(self._aux, self._t[lo:hi], keep=False, names=self._names)  # not listed again
        w._done = {k: v[lo:hi] for k, v in self._done.items()}
        return w

    def subset(self, mask: np.ndarray) -> HeldChannels:
        return HeldChannels(self._aux, self._t[mask], keep=self._keep, names=self._names)


class GeometryBuilder:
    """Computes reference vectors for any times, with the mission's physics options."""

    def __init__(self, spec: MissionSpec, ephemeris: Ephemeris, physics: PhysicsOptions, aux: Table | None = None):
        self.spec = spec
        self.ephemeris = ephemeris
        self.physics = physics
        self.aux = aux
        self._fields: dict[str, GeomagField] = {}

    def field(self, model: str | None = None) -> GeomagField:
        model = model or self.physics.field_model
        if model not in self._fields:
            self._fields[model] = GeomagField(self.spec.epoch, model=model)
        return self._fields[model]

    def sun(self, t, r, v, physics: PhysicsOptions | None = None) -> np.ndarray:
        ph = physics or self.physics
        s = self.ephemeris.sun_geocentric(t)
        u = corrections.sun_from_spacecraft(s, r) if ph.sun_parallax else s / np.linalg.norm(s, axis=-1, keepdims=True)
        return corrections.aberrate(u, v) if ph.solar_aberration else u

    def stars(self, t, v, ra_deg, dec_deg, physics: PhysicsOptions | None = None) -> np.ndarray:
        ph = physics or self.physics
        u = spin_axis(np.asarray(ra_deg) * DEG, np.asarray(dec_deg) * DEG)
        if not ph.stellar_aberration:
            return u
        return corrections.apparent_star_direction(u, self.ephemeris.earth_velocity_km_s(t), v)

    def orbit(self, t) -> tuple[np.ndarray, np.ndarray]:
        """Spacecraft position [km] and velocity [km/s] (N, 3) at frame times ``t``."""
        return self.ephemeris.state(np.atleast_1d(np.asarray(t, dtype=float)))

    def ephemeris_callable(self, physics: PhysicsOptions | None = None):
        def at(t):
            t = np.atleast_1d(np.asarray(t, dtype=float))
            r, v = self.ephemeris.state(t)
            return r, v, self.sun(t, r, v, physics)

        return at

    def geometry(
        self, sensor_type: str, t: np.ndarray, table: Table | None = None, physics: PhysicsOptions | None = None
    ) -> Geometry:
        """Attitude-free :class:`Geometry` for a sensor type at times ``t``.

        Computed in chunks of :data:`CHUNK_FRAMES` frames into the output arrays, so the
        temporaries of the ephemeris, field and aberration computations stay bounded
        (every quantity is per frame: the chunking changes no number).
        """
        ph = physics or self.physics
        t = np.asarray(t, dtype=float)
        n = t.shape[0]
        self.ephemeris.check_covers(t, what=f"{sensor_type} frames")
        # r, v are not kept (no model reads them; see the module docstring)
        kw: dict = {"t": t, "aux": HeldChannels(self.aux, t)}
        extra: dict = {}
        sun = sensor_type in ("fine_sun", "coarse_sun", "plane_field_sun", "horizon")
        mag = sensor_type == "magnetometer"
        star = sensor_type == "star_tracker" and table is not None
        if sun:
            kw["sun_I"] = np.empty((n, 3))
        if mag and ph.field_model == "constant":
            mag = False  # the field is a state element (module docstring)
            kw["B_I"], extra["B_I_dot"] = np.zeros((n, 3)), np.zeros((n, 3))
        if mag:
            fld = self.field(ph.field_model)
            kw["B_I"], extra["B_I_dot"] = np.empty((n, 3)), np.empty((n, 3))
            kw["field_model"] = fld.field_I
        if star and table is not None:
            kw["star_I"] = np.empty((n, 3))
            ra, dec = np.asarray(table.columns["ra"]), np.asarray(table.columns["dec"])
        for lo in range(0, n, CHUNK_FRAMES) if (sun or mag or star) else ():
            sl = slice(lo, min(n, lo + CHUNK_FRAMES))
            tc = t[sl]
            r, v = self.ephemeris.state(tc, what=f"{sensor_type} frames")
            if sun:
                kw["sun_I"][sl] = self.sun(tc, r, v, ph)
            if mag:
                kw["B_I"][sl] = fld.field_I(tc, r)
                h = 1.0
                extra["B_I_dot"][sl] = (fld.field_I(tc + h, r + v * h) - fld.field_I(tc - h, r - v * h)) / (2 * h)
            if star:
                kw["star_I"][sl] = self.stars(tc, v, ra[sl], dec[sl], ph)
        if sensor_type == "horizon":
            kw["ephemeris"] = self.ephemeris_callable(ph)
            extra["earth_flattening"] = WGS84_FLATTENING if ph.earth_oblateness else 0.0
            if table is not None:
                extra["spin_rate"] = np.asarray(table.columns["spin_rate"], dtype=float)
        kw["extra"] = extra
        return Geometry(**kw)


def prepare_sensors(
    spec: MissionSpec, telemetry: Mapping[str, Table], builder: GeometryBuilder, *, include_gyro: bool = False
) -> list[SensorData]:
    """One :class:`SensorData` per sensor in mission order (gyros only if asked)."""
    channels = aux_channel_names(builder.aux)
    out = []
    for s in spec.sensors:
        if s.type == "gyro" and not include_gyro:
            continue
        table = telemetry[s.name]
        model = make_model(
            s,
            aux_channels=channels if s.type == "magnetometer" else (),
            constant_field=builder.physics.field_model == "constant",
        )
        t, y = model.measurements(table)
        geom = builder.geometry(s.type, t, table)
        out.append(
            SensorData(
                s.name,
                model,
                np.asarray(t, float),
                np.asarray(y, float),
                np.asarray(model.sigma(), float),
                geom,
                _line_numbers(table.lines),
            )
        )
    return out


def _line_numbers(lines) -> np.ndarray:
    """File line numbers as int32 when they fit (half the memory of the reader's int64)."""
    lines = np.asarray(lines)
    if lines.size and lines.dtype != np.int32 and 0 <= lines.min() and lines.max() < 2**31:
        return lines.astype(np.int32)
    return lines


def geometry_variants(sd: SensorData, builder: GeometryBuilder, table: Table) -> dict[str, Geometry]:
    """For each physics effect relevant to the sensor: its geometry with the option flipped.

    Returns ``{"model.<option>": geometry}``; the diagnosis evaluates the model on both
    geometries and takes the difference as the effect's signature (exactly linear for
    these small corrections).
    """
    relevant = {
        "star_tracker": ("stellar_aberration",),
        "fine_sun": ("solar_aberration", "sun_parallax"),
        "coarse_sun": ("solar_aberration", "sun_parallax"),
        "plane_field_sun": ("solar_aberration", "sun_parallax"),
        "magnetometer": ("field_model",),
        "horizon": ("earth_oblateness",),
    }.get(sd.model.type_name, ())
    if builder.physics.field_model == "constant":
        relevant = tuple(o for o in relevant if o != "field_model")  # no model to truncate
    out = {}
    for opt in relevant:
        on, off = PHYSICS_EFFECTS[opt]
        current = getattr(builder.physics, opt)
        flipped: Any = off if current == on else on  # a bool or a model name, as the field
        ph = replace(builder.physics, **{opt: flipped})
        out[f"model.{opt}"] = builder.geometry(sd.model.type_name, sd.t, table, ph)
    return out
