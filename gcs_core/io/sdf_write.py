"""Writing the Standard Data File (seed §3.2.2, Table 3-2; layout in :mod:`gcs_core.io.sdf`).

:func:`write_sdf` lays a mission's samples out in block windows (:class:`_Layout`), writes
each block and its frame headers, then the sensors, the ephemeris and the auxiliary and
onboard channels, all in one atomic HDF5 write.
"""

from __future__ import annotations

import json
import math
import os
from dataclasses import dataclass, field
from datetime import UTC, datetime
from pathlib import Path
from typing import Any

import h5py
import numpy as np

from gcs_core.io import h5store
from gcs_core.io.importer import COLUMN_UNITS, ImportedMission
from gcs_core.io.sdf import (
    BLOCK_IDS,
    FILE_TYPE_DATA,
    FILE_TYPE_HEADERS,
    FORMAT,
    OBSERVATION,
    TRANSITION,
    TRANSITION_TYPES,
    VERSION,
)


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
