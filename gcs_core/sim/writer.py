"""Write a simulated mission as an ICD mission directory, plus its answer file.

``write_mission(cfg, out_dir, truth_path=...)`` produces (ICD §1, §3 to §6)::

    out_dir/mission.toml            data-book values (what the team believes)
    out_dir/ephemeris.csv           t, r, v, apparent geocentric Sun, every ephemeris_cadence_s
                                    (r, v of time t − Δt with the hidden in-track error Δt)
    out_dir/telemetry/<SENSOR>.csv  one file per sensor
    out_dir/aux.csv                 torquer dipoles and tam_temp (three-axis missions)
    out_dir/onboard_attitude.csv    onboard quaternions (three-axis missions)
    out_dir/star_catalog.csv        the simulation's star catalog ``ra, dec, mag`` (deg, deg,
                                    visual magnitude), when the mission has a star tracker:
                                    the run catalog an analyst would hold (the predictor's
                                    ``stars = "catalog"``); not named in mission.toml

and, at a separate place chosen by the caller, ``truth.json``: the true parameters of every
sensor, the hidden effects (ids ``<SENSOR>.<effect>`` / ``model.<effect>``), the orbit,
attitude profile and injected onboard error.

The time span is simulated in chunks of ``cfg.chunk_s`` and appended to the CSV files, so a
week-long mission runs in bounded memory. Random streams are seeded per sensor name
(``default_rng([seed, crc32(name)])``): the same seed gives the same files, and a scenario
with one hidden effect shares its noise with the base scenario. The directory is built
under a temporary name next to ``out_dir`` and renamed into place at the end; the answer
file is written to a temporary file and renamed.

Number formats follow the example mission of the ICD (shared/examples/sunpoint-nominal).
"""

from __future__ import annotations

import dataclasses
import json
import logging
import os
import shutil
import zlib
from pathlib import Path

import numpy as np

from gcs_core.errors import InputError
from gcs_core.sim.aux import AuxSchedule
from gcs_core.sim.config import ATTITUDE_MODES, SENSOR_TYPES, MissionConfig, SensorConfig, SpinProfile, as_plain
from gcs_core.sim.sensors import CoarseSunSim, FineSunSim, MagnetometerSim
from gcs_core.sim.spinner import HorizonSim, PlaneFieldSim, SunSightings
from gcs_core.sim.stars import StarCatalog, StarTrackerSim
from gcs_core.sim.truth import GyroSim, World, onboard_quaternions

log = logging.getLogger(__name__)

__all__ = ["write_mission", "write_catalog", "validate", "time_grid", "mission_toml", "STAR_CATALOG_FILE"]

#: the catalog file of the mission directory (read by :mod:`gcs_core.predictor.stars`)
STAR_CATALOG_FILE = "star_catalog.csv"

_EPH_COLS = ("t", "rx", "ry", "rz", "vx", "vy", "vz", "sx", "sy", "sz")
_SPINNER_TYPES = ("plane_field_sun", "horizon")


def validate(cfg: MissionConfig) -> None:
    """Refuse an inconsistent configuration with one clear line (InputError)."""
    if cfg.attitude_mode not in ATTITUDE_MODES:
        raise InputError(f"unknown attitude_mode '{cfg.attitude_mode}'", key="mission.attitude_mode")
    if not cfg.duration_s > 0:
        raise InputError("duration_s must be positive", key="mission.duration_s")
    if not 0 < cfg.ephemeris_cadence_s <= 60:
        raise InputError("ephemeris cadence must be in (0, 60] s (ICD §4)", key="ephemeris_cadence_s")
    names = set()
    for i, s in enumerate(cfg.sensors):
        if s.type not in SENSOR_TYPES:
            raise InputError(f"unknown sensor type '{s.type}'", key=f"sensor[{i}].type")
        if s.name in names:
            raise InputError(f"duplicate sensor name '{s.name}'", key=f"sensor[{i}].name")
        names.add(s.name)
        if (s.type in _SPINNER_TYPES) != cfg.spinning:
            raise InputError(
                f"sensor type '{s.type}' does not fit attitude mode '{cfg.attitude_mode}'", key=f"sensor[{i}].type"
            )
        if s.type not in _SPINNER_TYPES and not s.cadence_s > 0:
            raise InputError("cadence_s must be positive", key=f"sensor[{i}].cadence_s")
    if cfg.spinning and sum(s.type == "plane_field_sun" for s in cfg.sensors) != 1:
        raise InputError(
            "a spinning mission needs exactly one plane_field_sun sensor (it times the horizon)", key="sensor"
        )


def time_grid(cadence: float, start: float, t0: float, t1: float, *, last: bool) -> np.ndarray:
    """Times ``start + k cadence`` in ``[t0, t1)`` (``[t0, t1]`` when ``last``)."""
    k0 = int(np.ceil((t0 - start) / cadence - 1e-9))
    k1 = int(np.floor((t1 - start) / cadence + 1e-9))
    t = start + cadence * np.arange(max(k0, 0), k1 + 1)
    return t[(t >= t0 - 1e-9) & ((t <= t1 + 1e-9) if last else (t < t1 - 1e-9))]


class _Csv:
    """One CSV file written row block by row block."""

    def __init__(self, path: Path, columns, formats):
        self.path, self.columns, self.formats = path, tuple(columns), list(formats)
        self.fh = open(path, "w", newline="\n")
        self.fh.write(",".join(self.columns) + "\n")
        self.rows = 0

    def append(self, data: dict) -> None:
        n = len(data["t"])
        if n == 0:
            return
        arr = np.column_stack([np.asarray(data[c], dtype=float) for c in self.columns])
        np.savetxt(self.fh, arr, fmt=self.formats, delimiter=",")
        self.rows += n

    def close(self) -> None:
        self.fh.close()


def _rng(seed: int, name: str) -> np.random.Generator:
    return np.random.default_rng([int(seed), zlib.crc32(name.encode())])


# --- mission.toml -------------------------------------------------------------------------
def _toml_value(v) -> str:
    if isinstance(v, (bool, np.bool_)):
        return "true" if v else "false"
    if isinstance(v, (int, np.integer)):
        return str(int(v))
    if isinstance(v, (float, np.floating)):
        x = float(v)
        if not np.isfinite(x):
            raise ValueError("non-finite value in mission.toml")
        return repr(x)
    if isinstance(v, str):
        return json.dumps(v)
    if isinstance(v, (list, tuple, np.ndarray)):
        return "[" + ", ".join(_toml_value(x) for x in v) + "]"
    raise TypeError(f"cannot write {type(v).__name__} to TOML")


def mission_toml(cfg: MissionConfig) -> str:
    """Text of mission.toml (ICD §3) with the data-book values."""
    out = [
        "# Mission description: sensor inventory and data-book values.",
        "[mission]",
        f"name = {_toml_value(cfg.name)}",
        f"epoch = {_toml_value(cfg.epoch)}",
        f"attitude_mode = {_toml_value(cfg.attitude_mode)}",
    ]
    if cfg.spinning:
        sp = cfg.attitude
        assert isinstance(sp, SpinProfile)
        guess = [round(sp.ra_deg + sp.guess_error_deg[0], 6), round(sp.dec_deg + sp.guess_error_deg[1], 6)]
        out.append(f"spin_axis_guess_deg = {_toml_value(guess)}")
    out += ["", "[ephemeris]", 'file = "ephemeris.csv"']
    if cfg.aux is not None and not cfg.spinning:
        out += ["", "[aux]", 'file = "aux.csv"']
    if cfg.onboard is not None and not cfg.spinning:
        out += ["", "[onboard_attitude]", 'file = "onboard_attitude.csv"']
    for s in cfg.sensors:
        out += [
            "",
            "[[sensor]]",
            f"name = {_toml_value(s.name)}",
            f"type = {_toml_value(s.type)}",
            f"telemetry = {_toml_value('telemetry/' + s.name + '.csv')}",
        ]
        out += [f"{k} = {_toml_value(v)}" for k, v in s.book.items()]
    return "\n".join(out) + "\n"


def write_catalog(catalog: StarCatalog, path: Path, seed: int) -> None:
    """``star_catalog.csv``: one row ``ra, dec, mag`` per star (telemetry's number format)."""
    with open(path, "w", newline="\n") as fh:
        fh.write(
            f"# star catalog of the simulation (catalog_seed {seed}): J2000 ra, dec [deg], "
            "visual magnitude\nra,dec,mag\n"
        )
        np.savetxt(fh, np.column_stack([catalog.ra_deg, catalog.dec_deg, catalog.mag]), fmt="%.12g", delimiter=",")


# --- generation ----------------------------------------------------------------------------
def _generate(cfg: MissionConfig, root: Path) -> dict:
    world = World(cfg)
    D = float(cfg.duration_s)
    files: dict[str, _Csv] = {}
    record: dict = {"rows": {}, "counters": {}}
    try:
        files["ephemeris"] = _Csv(root / "ephemeris.csv", _EPH_COLS, ["%.9f"] * 10)
        aux = None
        if cfg.aux is not None and not cfg.spinning:
            aux = AuxSchedule(cfg.aux, D, _rng(cfg.seed, "aux"), _rng(cfg.seed, "heater"))
            files["aux"] = _Csv(root / "aux.csv", aux.columns, aux.formats)
        onboard_rng = _rng(cfg.seed, "onboard")
        if cfg.onboard is not None and not cfg.spinning:
            files["onboard"] = _Csv(root / "onboard_attitude.csv", ("t", "q1", "q2", "q3", "q4"), ["%.12f"] * 5)
        catalog = StarCatalog(cfg.catalog_seed) if any(s.type == "star_tracker" for s in cfg.sensors) else None
        if catalog is not None:
            write_catalog(catalog, root / STAR_CATALOG_FILE, cfg.catalog_seed)
        sightings = None
        t_max = D
        if cfg.spinning:
            pss = next(s for s in cfg.sensors if s.type == "plane_field_sun")
            sightings = SunSightings(world, pss)
            t_max = D - 2.0 * 2 * np.pi / float(world.spin_rate(np.array([0.0]))[0]) - 1.0
        sims = {}
        for s in cfg.sensors:
            sims[s.name] = make_sensor_sim(
                s, world, _rng(cfg.seed, s.name), catalog=catalog, aux=aux, sightings=sightings
            )
            files[s.name] = _Csv(root / "telemetry" / f"{s.name}.csv", sims[s.name].columns, sims[s.name].formats)
        n_chunks = int(np.ceil(D / cfg.chunk_s))
        for c in range(n_chunks):
            t0, t1 = c * cfg.chunk_s, min((c + 1) * cfg.chunk_s, D)
            last = c == n_chunks - 1
            te = time_grid(cfg.ephemeris_cadence_s, 0.0, t0, t1, last=last)
            if last and (te.size == 0 or te[-1] < D - 1e-9):
                te = np.append(te, D)  # the span always ends on a row
            r, v = world.orbit(te - cfg.ephemeris_time_error_s)  # Δt = 0 unless hidden
            sun = world.sun(te)
            files["ephemeris"].append(dict(zip(_EPH_COLS, [te, *r.T, *v.T, *sun.T])))
            if aux is not None and cfg.aux is not None:
                files["aux"].append(aux.rows(time_grid(cfg.aux.cadence_s, 0.0, t0, t1, last=last)))
            if "onboard" in files and cfg.onboard is not None:
                to = time_grid(cfg.onboard.cadence_s, 0.0, t0, t1, last=last)
                q = onboard_quaternions(world, to, cfg.onboard.error_deg, cfg.onboard.noise_arcsec, onboard_rng)
                files["onboard"].append({"t": to, "q1": q[:, 0], "q2": q[:, 1], "q3": q[:, 2], "q4": q[:, 3]})
            for s in cfg.sensors:
                sim = sims[s.name]
                if s.type in _SPINNER_TYPES:
                    data = sim.run_span(t0, t1 if not last else t1 + 1e-9, t_max)
                else:
                    start = s.cadence_s if s.type == "gyro" else 0.0
                    data = sim.run(time_grid(s.cadence_s, start, t0, t1, last=last))
                files[s.name].append(data)
            log.debug("chunk %d/%d written", c + 1, n_chunks)
    finally:
        for f in files.values():
            f.close()
    for name, f in files.items():
        record["rows"][name] = f.rows
    for name, sim in sims.items():
        counters = {
            k: getattr(sim, k) for k in ("n_eclipsed", "n_occulted", "n_misidentified", "n_missed") if hasattr(sim, k)
        }
        if counters:
            record["counters"][name] = counters
        if hasattr(sim, "bias_log"):
            step = max(1, len(sim.bias_log) // 200)
            record.setdefault("gyro_bias", {})[name] = [[t, *b] for t, b in sim.bias_log[::step]]
    return record


def _truth(cfg: MissionConfig, record: dict) -> dict:
    sensors = {}
    for s in cfg.sensors:
        true = dict(s.book)
        true.update(s.true)
        sensors[s.name] = {
            "type": s.type,
            "cadence_s": s.cadence_s,
            "book": as_plain(s.book),
            "true": as_plain(true),
            "rows": record["rows"].get(s.name, 0),
            **({"counters": record["counters"][s.name]} if s.name in record["counters"] else {}),
        }
    effects = []
    for e in cfg.effects:
        sensor, _, effect = e.id.partition(".")
        effects.append(
            {
                "id": e.id,
                "sensor": None if sensor == "model" else sensor,
                "effect": effect,
                "magnitude": e.magnitude,
                "unit": e.unit,
                "description": e.description,
            }
        )
    out = {
        "mission": cfg.name,
        "generator": "gcs_core.sim",
        "seed": cfg.seed,
        "epoch": cfg.epoch,
        "attitude_mode": cfg.attitude_mode,
        "duration_s": cfg.duration_s,
        "hidden_effects": effects,
        "physics": dict(cfg.physics),
        "ephemeris_time_error_s": cfg.ephemeris_time_error_s,
        "sensors": sensors,
        "orbit": dataclasses.asdict(cfg.orbit),
        "attitude": as_plain(dataclasses.asdict(cfg.attitude)),
        "rows": record["rows"],
    }
    if cfg.onboard is not None and not cfg.spinning:
        out["onboard_attitude"] = as_plain(dataclasses.asdict(cfg.onboard))
    if "gyro_bias" in record:
        out["gyro_bias_history"] = record["gyro_bias"]
    if cfg.spinning:
        sp = cfg.attitude
        assert isinstance(sp, SpinProfile)
        out["spin_axis_deg"] = [sp.ra_deg, sp.dec_deg]
    return as_plain(out)


# The engine's atomic writes are gcs_core.fileperm; the simulator keeps these few lines of
# its own on purpose: it imports nothing of the engine it is meant to check.
def _write_text_atomic(path: Path, text: str) -> None:
    path = Path(path)
    path.parent.mkdir(parents=True, exist_ok=True)
    tmp = path.with_name(f".{path.name}.tmp-{os.getpid()}")
    tmp.write_text(text)
    os.replace(tmp, path)


def write_mission(cfg: MissionConfig, out_dir, *, truth_path=None) -> Path:
    """Simulate ``cfg`` and write the ICD mission directory ``out_dir`` (replaced if present).

    ``truth_path``: where to write the answer file (truth.json); keep it outside
    ``out_dir``. Returns ``out_dir`` as a Path.
    """
    validate(cfg)
    out_dir = Path(out_dir)
    if truth_path is not None and Path(truth_path).resolve().is_relative_to(out_dir.resolve()):
        raise InputError("the answer file must not be inside the mission directory", key="truth_path")
    out_dir.parent.mkdir(parents=True, exist_ok=True)
    tmp = out_dir.parent / f".{out_dir.name}.partial-{os.getpid()}"
    shutil.rmtree(tmp, ignore_errors=True)
    (tmp / "telemetry").mkdir(parents=True)
    try:
        record = _generate(cfg, tmp)
        (tmp / "mission.toml").write_text(mission_toml(cfg))
        if out_dir.exists():
            old = out_dir.parent / f".{out_dir.name}.old-{os.getpid()}"
            os.replace(out_dir, old)
            os.replace(tmp, out_dir)
            shutil.rmtree(old, ignore_errors=True)
        else:
            os.replace(tmp, out_dir)
    except BaseException:
        shutil.rmtree(tmp, ignore_errors=True)
        raise
    if truth_path is not None:
        _write_text_atomic(Path(truth_path), json.dumps(_truth(cfg, record), indent=1) + "\n")
    log.debug("mission %s written to %s", cfg.name, out_dir)
    return out_dir


def make_sensor_sim(sensor: SensorConfig, world, rng: np.random.Generator, *, catalog=None, aux=None, sightings=None):
    """The simulator object of one sensor (any of the seven ICD §5 types).

    ``catalog`` (star trackers), ``aux`` (magnetometer contamination) and ``sightings``
    (:class:`~gcs_core.sim.spinner.SunSightings`, spinner sensors) are shared objects.
    """
    kind = sensor.type
    if kind == "magnetometer":
        return MagnetometerSim(sensor, world, rng, aux)
    if kind == "gyro":
        return GyroSim(sensor, world, rng, aux)
    if kind == "star_tracker":
        st = StarTrackerSim(
            sensor, world, catalog, rng, stellar_aberration=bool(world.cfg.physics.get("stellar_aberration", True))
        )
        st.aux = aux
        return st
    if kind == "fine_sun":
        fss = FineSunSim(sensor, world, rng)
        fss.aux = aux
        return fss
    if kind == "coarse_sun":
        return CoarseSunSim(sensor, world, rng)
    if kind == "plane_field_sun":
        return PlaneFieldSim(sensor, world, rng, sightings)
    if kind == "horizon":
        return HorizonSim(sensor, world, rng, sightings)
    raise ValueError(f"unknown sensor type '{kind}' for {sensor.name}")
