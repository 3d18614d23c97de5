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
observation block comes before the transition block. :mod:`gcs_core.io.sdf_write` writes
the file; this module holds its layout and reads it.
"""

from __future__ import annotations

import json
import os
from collections.abc import Iterator, Mapping
from dataclasses import dataclass, field
from datetime import datetime
from pathlib import Path
from typing import Any

import h5py
import numpy as np

from gcs_core.ephem.timescale import parse_utc
from gcs_core.errors import DataFileError
from gcs_core.io import h5store

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
