"""The Standard Data File (SDF): all data of a mission in blocks (seed §3.2.2, Table 3-2).

The seed's SDF combines the observation and transition data of every sensor into data
blocks: an *observation* block measures a static state (here: every non-gyro sensor
in one time window), a *transition* block measures the state transitions (the gyro
data of the window). Each block holds time frames; each frame header gives the frame
time, the number of data records and the number of data points of each model. A file
of type 1 holds headers and data; a file of type 2 holds headers only (times and
counts), which is all an observability predictor needs (seed §3.2.2).

HDF5 layout (see docs/formats.md)::

    /                      gcs_format="SDF", n_blocks, file_type, mission, epoch, ...
    /frames/t              (F,) frame times [s], blocks in order
    /frames/block          (F,) block index of each frame
    /frames/n_records      (F,) sensors with data in the frame
    /frames/n_points       (F, S) data points per sensor (mission order)
    /blocks/NNNNN          kind, block_id, t0, t1, n_frames, frame_start
    /blocks/NNNNN/<SENSOR> t (n,), frame (n,), data (n, m) and aux (n, k) [type 1]
    /sensors/<SENSOR>      type, kind, book (JSON), alignment_deg, noise, columns
    /ephemeris             t, r_I_km, v_I_km_s, sun_I_km
    /aux, /onboard         the auxiliary channels and onboard quaternions, if any

Blocks are cut on a grid of ``block_seconds`` aligned to the epoch; in each window the
observation block comes before the transition block.
"""

from __future__ import annotations

import json
import math
import os
from collections.abc import Iterator, Mapping
from dataclasses import dataclass, field
from datetime import UTC, datetime
from pathlib import Path
from typing import Any

import h5py
import numpy as np

from gcs_core.ephem.timescale import parse_utc
from gcs_core.errors import DataFileError
from gcs_core.io import h5store
from gcs_core.io.importer import COLUMN_UNITS, ImportedMission

FORMAT = "SDF"
VERSION = 1
FILE_TYPE_DATA = 1  # headers + data
FILE_TYPE_HEADERS = 2  # headers only
OBSERVATION, TRANSITION = "observation", "transition"
BLOCK_IDS = {OBSERVATION: 1, TRANSITION: 2}
#: sensor types whose data are state transitions (everything else observes).
TRANSITION_TYPES = ("gyro",)


@dataclass(frozen=True)
class SdfSensor:
    """A sensor as recorded in ``/sensors/<name>``.

    Attributes
    ----------
    name, type : as in mission.toml.
    kind : "observation" or "transition".
    telemetry : the telemetry file it was read from.
    alignment_deg : ``(a1, a2, a3)`` or None; noise : 1-sigma or None.
    book : the data-book values (JSON round trip: lists for tuples).
    columns : telemetry columns stored in each block's ``data`` (``t`` excluded).
    units : unit of each column ("" for extra columns of no stated unit).
    n_samples : samples written over all blocks.
    """

    name: str
    type: str
    kind: str
    telemetry: str
    alignment_deg: tuple[float, float, float] | None
    noise: float | None
    book: Mapping[str, Any]
    columns: tuple[str, ...]
    n_samples: int
    units: tuple[str, ...] = ()


@dataclass(frozen=True)
class SdfSensorData:
    """One sensor's data in one block.

    Attributes
    ----------
    t : (n,) sample times [s since epoch].
    frame : (n,) index of each sample's frame within the block.
    data : (n, m) telemetry values in the order of ``columns``; None in a headers-only file.
    columns : names of the m columns.
    aux : (n, k) auxiliary channels held at each sample (NaN before the first aux row),
        or None; aux_columns : their names.
    """

    t: np.ndarray
    frame: np.ndarray
    data: np.ndarray | None
    columns: tuple[str, ...]
    aux: np.ndarray | None = None
    aux_columns: tuple[str, ...] = ()


@dataclass(frozen=True)
class SdfBlock:
    """One data block (seed Table 3-2, records 2 to m).

    Attributes
    ----------
    index : 0-based block number in the file.
    kind : "observation" or "transition"; block_id : 1 or 2 (the seed's Block ID).
    t0, t1 : the time window [t0, t1) of the block [s].
    frame_t : (n_frames,) frame times; n_points : (n_frames, S) data points per sensor
        of the mission (sensor order of ``SdfContents.sensors``).
    sensors : name -> :class:`SdfSensorData`, the sensors with data in the block.
    """

    index: int
    kind: str
    block_id: int
    t0: float
    t1: float
    frame_t: np.ndarray
    n_points: np.ndarray
    sensors: Mapping[str, SdfSensorData]

    @property
    def n_frames(self) -> int:
        return int(self.frame_t.shape[0])


@dataclass(frozen=True)
class SdfContents:
    """A whole SDF as read by :func:`read_sdf`."""

    path: Path
    file_type: int
    mission: str
    epoch: datetime
    attitude_mode: str
    source_dir: str
    block_seconds: float
    sensors: Mapping[str, SdfSensor]
    frames_t: np.ndarray
    frames_block: np.ndarray
    frames_n_points: np.ndarray
    blocks: tuple[SdfBlock, ...]
    ephemeris: Mapping[str, np.ndarray]
    aux: Mapping[str, np.ndarray] | None = None
    onboard: Mapping[str, np.ndarray] | None = None
    attrs: Mapping[str, Any] = field(default_factory=dict)

    @property
    def headers_only(self) -> bool:
        return self.file_type == FILE_TYPE_HEADERS

    @property
    def n_blocks(self) -> int:
        return len(self.blocks)


# --- writing --------------------------------------------------------------------------


def _epoch_text(epoch: datetime) -> str:
    text = epoch.astimezone(UTC).strftime("%Y-%m-%dT%H:%M:%S")
    if epoch.microsecond:
        text += f".{epoch.microsecond:06d}"
    return text + "Z"


def _json(value: Any) -> str:
    return json.dumps(value, default=str, allow_nan=False)


def _hold(aux_t: np.ndarray, aux_values: np.ndarray, t: np.ndarray) -> np.ndarray:
    """Zero-order hold of the aux channels at times t (ICD §6); NaN before the first row."""
    if aux_t.size == 0:
        return np.full((t.size, aux_values.shape[1]), np.nan)
    idx = np.searchsorted(aux_t, t, side="right") - 1
    out = aux_values[np.clip(idx, 0, None)].astype(np.float64, copy=True)
    out[idx < 0] = np.nan
    return out


@dataclass(frozen=True)
class _Layout:
    """How a mission's data fall into blocks (the plan :func:`write_sdf` writes).

    Attributes
    ----------
    names : sensors with telemetry, in mission order; index_of : name -> column of ``n_points``.
    kinds : sensor -> "observation" or "transition" (every sensor of the mission).
    tables : sensor -> its telemetry table.
    block_seconds : width of the windows [s]; t_start : start of window 0 [s], on the grid.
    window_of : sensor -> (n,) window index of each sample; windows : the windows with data.
    aux_columns, aux_values : the auxiliary channels and their (n_aux, k) values, if any.
    """

    names: list[str]
    index_of: dict[str, int]
    kinds: dict[str, str]
    tables: dict[str, Any]
    block_seconds: float
    t_start: float
    window_of: dict[str, np.ndarray]
    windows: list[int]
    aux_columns: tuple[str, ...]
    aux_values: np.ndarray | None


@dataclass
class _FrameTable:
    """The ``/frames`` table as it grows, one entry per block written."""

    t: list[np.ndarray] = field(default_factory=list)
    block: list[np.ndarray] = field(default_factory=list)
    points: list[np.ndarray] = field(default_factory=list)

    @property
    def n_blocks(self) -> int:
        return len(self.t)

    @property
    def n_frames(self) -> int:
        return sum(a.size for a in self.t)


def _layout(m: ImportedMission, block_seconds: float) -> _Layout:
    """Sensors, kinds and the block windows of a mission on a grid of ``block_seconds``."""
    spec = m.spec
    names = [s.name for s in spec.sensors if s.name in m.telemetry]
    tables = {n: m.telemetry[n] for n in names}
    nonempty = [tables[n].t for n in names if len(tables[n])]
    t_start = math.floor(min(float(t[0]) for t in nonempty) / block_seconds) * block_seconds if nonempty else 0.0
    window_of = {n: np.floor((tables[n].t - t_start) / block_seconds).astype(np.int64) for n in names}
    aux = m.aux
    aux_columns = tuple(c for c in aux.columns if c != "t") if aux is not None else ()
    return _Layout(
        names=names,
        index_of={n: i for i, n in enumerate(names)},
        kinds={s.name: TRANSITION if s.type in TRANSITION_TYPES else OBSERVATION for s in spec.sensors},
        tables=tables,
        block_seconds=block_seconds,
        t_start=t_start,
        window_of=window_of,
        windows=sorted(set().union(*(np.unique(w).tolist() for w in window_of.values()))),
        aux_columns=aux_columns,
        aux_values=aux.stack(aux_columns) if aux is not None else None,
    )


def _write_block(
    blocks: h5py.Group,
    lay: _Layout,
    m: ImportedMission,
    frames: _FrameTable,
    kind: str,
    t0: float,
    members: dict[str, np.ndarray],
    headers_only: bool,
) -> None:
    """Write one block (``/blocks/NNNNN``: seed Table 3-2, records 2 to m) of the sensors
    ``members`` (name -> samples of the window) and append its frames to ``frames``."""
    aux = m.aux
    times = {n: lay.tables[n].t[sel] for n, sel in members.items()}
    frame_t = np.unique(np.concatenate(list(times.values())))
    points = np.zeros((frame_t.size, len(lay.names)), dtype=np.int32)
    g = blocks.create_group(f"{frames.n_blocks:05d}")
    g.attrs.update(
        {
            "kind": kind,
            "block_id": np.int64(BLOCK_IDS[kind]),
            "t0": float(t0),
            "t1": float(t0 + lay.block_seconds),
            "n_frames": np.int64(frame_t.size),
            "frame_start": np.int64(frames.n_frames),
            "sensors": _json(list(members)),
        }
    )
    for n, sel in members.items():
        t = times[n]
        frame = np.searchsorted(frame_t, t).astype(np.int32)
        points[frame, lay.index_of[n]] += 1
        sg = g.create_group(n)
        cols = tuple(c for c in lay.tables[n].columns if c != "t")
        sg.attrs.update({"n": np.int64(t.size), "columns": _json(cols), "aux_columns": _json(lay.aux_columns)})
        h5store.write_array(sg, "t", t, attrs={"unit": "s"})
        h5store.write_array(sg, "frame", frame)
        if not headers_only:
            h5store.write_array(sg, "data", lay.tables[n].stack(cols)[sel])
            if aux is not None and lay.aux_values is not None and lay.aux_columns:
                h5store.write_array(sg, "aux", _hold(aux.t, lay.aux_values, t))
    frames.block.append(np.full(frame_t.size, frames.n_blocks, dtype=np.int32))
    frames.t.append(frame_t)
    frames.points.append(points)


def _write_blocks(f: h5py.File, lay: _Layout, m: ImportedMission, headers_only: bool) -> _FrameTable:
    """Every block, window by window (observation before transition); their frames."""
    frames = _FrameTable()
    blocks = f.create_group("blocks")
    for w in lay.windows:
        t0 = lay.t_start + w * lay.block_seconds
        for kind in (OBSERVATION, TRANSITION):
            members = {n: lay.window_of[n] == w for n in lay.names if lay.kinds[n] == kind}
            members = {n: sel for n, sel in members.items() if sel.any()}
            if members:
                _write_block(blocks, lay, m, frames, kind, t0, members, headers_only)
    return frames


def _write_frames(f: h5py.File, frames: _FrameTable, names: list[str]) -> None:
    """``/frames``: the frame headers of every block (time, block, records, points)."""
    fr = f.create_group("frames")
    cat = lambda xs, shape, dt: np.concatenate(xs) if xs else np.zeros(shape, dt)
    points_all = cat(frames.points, (0, len(names)), np.int32)
    h5store.write_array(fr, "t", cat(frames.t, (0,), np.float64), attrs={"unit": "s"})
    h5store.write_array(fr, "block", cat(frames.block, (0,), np.int32))
    h5store.write_array(fr, "n_records", (points_all > 0).sum(axis=1).astype(np.int32))
    h5store.write_array(fr, "n_points", points_all, attrs={"sensors": _json(names)})


def _write_sensors(f: h5py.File, m: ImportedMission, lay: _Layout) -> None:
    """``/sensors/<name>``: what mission.toml says of each sensor with telemetry."""
    sg = f.create_group("sensors")
    for s in m.spec.sensors:
        if s.name not in lay.tables:
            continue
        tab = lay.tables[s.name]
        g = sg.create_group(s.name)
        g.attrs.update(
            {
                "type": s.type,
                "kind": lay.kinds[s.name],
                "telemetry": str(s.telemetry),
                "alignment_deg": _json(list(s.alignment_deg) if s.alignment_deg else None),
                "noise": _json(s.noise),
                "book": _json(dict(s.book)),
                "unknown_keys": _json(list(s.unknown_keys)),
                "columns": _json([c for c in tab.columns if c != "t"]),
                "units": _json([COLUMN_UNITS.get(c, "") for c in tab.columns if c != "t"]),
                "n_samples": np.int64(len(tab)),
                "dropped_nan": np.int64(tab.dropped_nan),
                "dropped_duplicates": np.int64(tab.dropped_duplicates),
            }
        )


def _write_ancillary(f: h5py.File, m: ImportedMission, lay: _Layout) -> None:
    """``/ephemeris``, and ``/aux`` and ``/onboard`` when the mission has them."""
    eph = m.ephemeris_table
    eg = f.create_group("ephemeris")
    eg.attrs["source"] = str(eph.path)
    h5store.write_array(eg, "t", eph.t, attrs={"unit": "s"})
    h5store.write_array(eg, "r_I_km", eph.stack(("rx", "ry", "rz")), attrs={"unit": "km"})
    h5store.write_array(eg, "v_I_km_s", eph.stack(("vx", "vy", "vz")), attrs={"unit": "km/s"})
    h5store.write_array(eg, "sun_I_km", eph.stack(("sx", "sy", "sz")), attrs={"unit": "km"})
    if m.aux is not None:
        ag = f.create_group("aux")
        ag.attrs.update({"source": str(m.aux.path), "columns": _json(lay.aux_columns)})
        h5store.write_array(ag, "t", m.aux.t, attrs={"unit": "s"})
        h5store.write_array(ag, "values", lay.aux_values)
    if m.onboard is not None:
        og = f.create_group("onboard")
        og.attrs["source"] = str(m.onboard.path)
        h5store.write_array(og, "t", m.onboard.t, attrs={"unit": "s"})
        h5store.write_array(
            og,
            "q",
            m.onboard.stack(("q1", "q2", "q3", "q4")),
            attrs={"convention": "q1, q2, q3, q4 (scalar last), GCI to body"},
        )


def write_sdf(
    path: str | os.PathLike,
    imported_mission: ImportedMission,
    *,
    block_seconds: float = 600.0,
    headers_only: bool = False,
) -> Path:
    """Write the Standard Data File of an imported mission (seed Table 3-2), atomically.

    Parameters
    ----------
    path : destination ``.h5`` file (replaced atomically if it exists).
    imported_mission : from :func:`~gcs_core.io.importer.load_mission` (or any object
        with the same ``spec``, ``telemetry``, ``ephemeris_table``, ``aux``, ``onboard``).
    block_seconds : width of the block windows [s], > 0.
    headers_only : write file type 2 (times and counts only) for the predictor.
    """
    if not (isinstance(block_seconds, (int, float)) and math.isfinite(block_seconds) and block_seconds > 0):
        raise ValueError(f"block_seconds must be a positive number, not {block_seconds!r}")
    path = Path(path)
    m = imported_mission
    spec = m.spec
    lay = _layout(m, block_seconds)
    with h5store.atomic_create(path, FORMAT, VERSION) as f:
        f.attrs.update(
            {
                "file_type": np.int64(FILE_TYPE_HEADERS if headers_only else FILE_TYPE_DATA),
                "mission": spec.name,
                "epoch": _epoch_text(spec.epoch),
                "attitude_mode": spec.attitude_mode,
                "source_dir": str(spec.root),
                "block_seconds": float(block_seconds),
                "sensor_names": _json(lay.names),
            }
        )
        frames = _write_blocks(f, lay, m, headers_only)
        f.attrs["n_blocks"] = np.int64(frames.n_blocks)
        _write_frames(f, frames, lay.names)
        _write_sensors(f, m, lay)
        _write_ancillary(f, m, lay)
    return path


# --- reading --------------------------------------------------------------------------


def _loads(text: Any) -> Any:
    if isinstance(text, bytes):
        text = text.decode("utf-8")
    return json.loads(text)


def _read_block(f: h5py.File, name: str, file_type: int) -> SdfBlock:
    g = f["blocks"][name]
    a = g.attrs
    start, n_frames = int(a["frame_start"]), int(a["n_frames"])
    sensors = {}
    for sname in _loads(a["sensors"]):
        sg = g[sname]
        cols = tuple(_loads(sg.attrs["columns"]))
        aux_cols = tuple(_loads(sg.attrs.get("aux_columns", "[]")))
        data = sg["data"][()] if file_type == FILE_TYPE_DATA else None
        aux = sg["aux"][()] if (file_type == FILE_TYPE_DATA and "aux" in sg) else None
        sensors[sname] = SdfSensorData(
            t=sg["t"][()],
            frame=sg["frame"][()],
            data=data,
            columns=cols,
            aux=aux,
            aux_columns=aux_cols if aux is not None else (),
        )
    fr = f["frames"]
    return SdfBlock(
        index=int(name),
        kind=h5store.attr_str(g, "kind", ""),
        block_id=int(a["block_id"]),
        t0=float(a["t0"]),
        t1=float(a["t1"]),
        frame_t=fr["t"][start : start + n_frames],
        n_points=fr["n_points"][start : start + n_frames],
        sensors=sensors,
    )


def _header(f: h5py.File, path: Path) -> dict:
    a = f.attrs
    file_type = int(a["file_type"])
    if file_type not in (FILE_TYPE_DATA, FILE_TYPE_HEADERS):
        raise DataFileError(f"unknown SDF file type {file_type}", file=path)
    try:
        epoch = parse_utc(h5store.attr_str(f, "epoch", ""))  # missing: "bad epoch", one line
    except ValueError as err:
        raise DataFileError(f"bad epoch attribute ({err})", file=path) from None
    return {
        "file_type": file_type,
        "mission": h5store.attr_str(f, "mission"),
        "epoch": epoch,
        "attitude_mode": h5store.attr_str(f, "attitude_mode"),
        "source_dir": h5store.attr_str(f, "source_dir"),
        "block_seconds": float(a["block_seconds"]),
    }


def _read_sensors(f: h5py.File) -> dict[str, SdfSensor]:
    out = {}
    for name in _loads(f.attrs["sensor_names"]):
        a = f["sensors"][name].attrs
        align = _loads(a["alignment_deg"])
        out[name] = SdfSensor(
            name=name,
            type=h5store.attr_str(f["sensors"][name], "type", ""),
            kind=h5store.attr_str(f["sensors"][name], "kind", ""),
            telemetry=h5store.attr_str(f["sensors"][name], "telemetry", ""),
            alignment_deg=tuple(align) if align is not None else None,
            noise=_loads(a["noise"]),
            book=_loads(a["book"]),
            columns=tuple(_loads(a["columns"])),
            n_samples=int(a["n_samples"]),
            units=tuple(_loads(a.get("units", "[]"))),
        )
    return out


def read_sdf(path: str | os.PathLike) -> SdfContents:
    """Read a whole Standard Data File (see :func:`iter_blocks` to stream it)."""
    path = Path(path)
    with h5store.open_read(path, FORMAT, max_version=VERSION) as f:
        head = _header(f, path)
        blocks = tuple(_read_block(f, name, head["file_type"]) for name in sorted(f["blocks"]))
        if len(blocks) != int(f.attrs["n_blocks"]):
            raise DataFileError(f"holds {len(blocks)} blocks but its header says {int(f.attrs['n_blocks'])}", file=path)
        fr = f["frames"]
        eg = f["ephemeris"]
        ephemeris = {k: eg[k][()] for k in ("t", "r_I_km", "v_I_km_s", "sun_I_km")}
        aux = None
        if "aux" in f:
            cols = _loads(f["aux"].attrs["columns"])
            values = f["aux"]["values"][()]
            aux = {"t": f["aux"]["t"][()], **{c: values[:, i] for i, c in enumerate(cols)}}
        onboard = None
        if "onboard" in f:
            onboard = {"t": f["onboard"]["t"][()], "q": f["onboard"]["q"][()]}
        return SdfContents(
            path=path,
            sensors=_read_sensors(f),
            frames_t=fr["t"][()],
            frames_block=fr["block"][()],
            frames_n_points=fr["n_points"][()],
            blocks=blocks,
            ephemeris=ephemeris,
            aux=aux,
            onboard=onboard,
            attrs={k: v for k, v in f.attrs.items()},
            **head,
        )


def iter_blocks(path: str | os.PathLike) -> Iterator[SdfBlock]:
    """Stream the blocks of an SDF one at a time, in file order.

    The file stays open (under a shared lock) while the generator runs; closing the
    generator early (``break``, ``close()``) closes the file.
    """
    path = Path(path)
    with h5store.open_read(path, FORMAT, max_version=VERSION) as f:
        file_type = _header(f, path)["file_type"]
        for name in sorted(f["blocks"]):
            yield _read_block(f, name, file_type)
