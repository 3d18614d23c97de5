"""Each spacecraft's SCDS and ASF in the fleet's output folder, and what is already done.

Layout (``[fleet] output``)::

    <output>/<spacecraft>/<spacecraft>.scds.h5   calibration history (gcs_core.io.scds)
    <output>/<spacecraft>/<spacecraft>.asf.h5    ground attitude history (gcs_core.io.asf)

A spacecraft-day's **input hash** is the SHA-256 of its config (its digest with the
mission path left out, so moving the data changes nothing) and of every file the mission
reads (mission.toml, ephemeris or TLE, telemetry, aux, onboard attitude: each file's name
relative to the mission and its bytes). It is stored in the provenance of both the SCDS
version and the ASF solution (key ``fleet``), with the day and the spacecraft's results.
A day is done for a spacecraft when both files hold an entry with that hash: running it
again adds nothing. An SCDS entry without its ASF solution (a run stopped between the two
appends) is completed by appending only the ASF solution.

Appends are made by the submitting process only, one at a time, through
:mod:`gcs_core.io.scds` and :mod:`gcs_core.io.asf` (locked, atomic, append-only).
"""

from __future__ import annotations

import hashlib
import json
import os
from dataclasses import dataclass, replace
from pathlib import Path

from gcs_core.errors import DataFileError
from gcs_core.io import asf, h5store, scds
from gcs_core.io.locks import locked

__all__ = ["FleetStore", "input_hash", "Done", "FLEET_KEY"]

#: the provenance key of the fleet's facts (day, input hash, results)
FLEET_KEY = "fleet"


def _mission_files(spec) -> list[Path]:
    files = [Path(spec.root) / "mission.toml"]
    for p in (spec.ephemeris_file, spec.aux_file, spec.onboard_file, spec.orbit_tle):
        if p is not None:
            files.append(Path(p))
    files += [Path(s.telemetry) for s in spec.sensors]
    return files


def input_hash(mission, config) -> str:
    """SHA-256 (hex) of the config and of every file ``mission`` was read from (module docstring)."""
    h = hashlib.sha256()
    h.update(replace(config, mission=Path("."), path=None).digest().encode())
    root = Path(mission.spec.root)
    for p in sorted(set(_mission_files(mission.spec)), key=lambda x: str(x)):
        try:
            rel = p.resolve().relative_to(root.resolve()).as_posix()
        except ValueError:
            rel = p.name
        h.update(b"\0" + rel.encode() + b"\0")
        with open(p, "rb") as f:
            for chunk in iter(lambda: f.read(1 << 20), b""):
                h.update(chunk)
    return h.hexdigest()


def _signature(path: Path) -> tuple:
    st = os.stat(path)
    return (st.st_dev, st.st_ino, st.st_size, st.st_mtime_ns, st.st_ctime_ns)


@dataclass(frozen=True)
class Done:
    """What the store already holds for one input hash: the SCDS version (or None) and
    the ASF solution (or None)."""

    scds_version: int | None
    asf_solution: int | None

    @property
    def complete(self) -> bool:
        return self.scds_version is not None and self.asf_solution is not None


class FleetStore:
    """The fleet's output folder (module docstring)."""

    def __init__(self, root: str | Path):
        self.root = Path(root)
        #: str(path) -> (file signature, [(number, provenance)]) (:meth:`_provenances`)
        self._index: dict[str, tuple[tuple, list[tuple[int, dict]]]] = {}

    def scds_path(self, spacecraft: str) -> Path:
        return self.root / spacecraft / f"{spacecraft}.scds.h5"

    def asf_path(self, spacecraft: str) -> Path:
        return self.root / spacecraft / f"{spacecraft}.asf.h5"

    # ------------------------------------------------------------------ reading
    def _provenances(self, path: Path, collection: str, fmt: str, version: int) -> list[tuple[int, dict]]:
        """(number, provenance) of every entry of an SCDS or ASF, oldest first ([] if absent).

        Kept in an index while the file stays the file it was (same inode, size and change
        times: an append replaces the file, so any append by anyone changes them); the
        appends of this store extend the index under the file's lock (:meth:`append`)."""
        if not path.exists():
            return []
        with locked(path, exclusive=False):
            sig = _signature(path)
            hit = self._index.get(str(path))
            if hit is not None and hit[0] == sig:
                return list(hit[1])
            out = []
            with h5store.open_read(path, fmt, max_version=version) as f:
                for name in h5store.numbered_names(f, collection):
                    g = f[collection][name]
                    try:
                        prov = json.loads(h5store.attr_str(g, "provenance", "{}"))
                    except json.JSONDecodeError:
                        raise DataFileError(f"entry {name} has an unreadable provenance", file=path) from None
                    out.append((int(name), prov))
            self._index[str(path)] = (sig, out)
        return list(out)

    def calibrations(self, spacecraft: str) -> list[tuple[int, dict]]:
        """(version, provenance) of the spacecraft's SCDS, oldest first."""
        return self._provenances(self.scds_path(spacecraft), scds.COLLECTION, scds.FORMAT, scds.VERSION)

    def attitudes(self, spacecraft: str) -> list[tuple[int, dict]]:
        """(solution, provenance) of the spacecraft's ASF, oldest first."""
        return self._provenances(self.asf_path(spacecraft), asf.COLLECTION, asf.FORMAT, asf.VERSION)

    def _append(self, path: Path, append, record: dict) -> int:
        """``append(path, **record)`` under the file's lock, the index extended when it was
        the file appended to (with the provenance exactly as stored)."""
        prov = {**record["provenance"]}
        prov.setdefault("created_utc", h5store.utc_now())
        prov.setdefault("gcs_version", h5store.gcs_version())
        record = {**record, "provenance": prov}
        with locked(path, exclusive=True):
            before = _signature(path) if path.exists() else None
            number = append(path, **record)
            hit = self._index.pop(str(path), None)
            if before is None or (hit is not None and hit[0] == before):
                entries = [] if hit is None else hit[1]
                self._index[str(path)] = (
                    _signature(path),
                    [*entries, (int(number), json.loads(json.dumps(prov, sort_keys=True)))],
                )
        return number

    def done(self, spacecraft: str, digest: str) -> Done:
        """Which entries already carry ``digest`` (module docstring)."""

        def find(entries):
            hits = [n for n, p in entries if (p.get(FLEET_KEY) or {}).get("input_hash") == digest]
            return hits[-1] if hits else None

        return Done(find(self.calibrations(spacecraft)), find(self.attitudes(spacecraft)))

    # ------------------------------------------------------------------ writing
    def append(self, outcome, *, done: Done | None = None) -> Done:
        """Append an outcome's SCDS version and ASF solution (what ``done`` lacks); return
        what is stored now. Only the submitting process calls this, one call at a time."""
        done = done or Done(None, None)
        facts = {
            "spacecraft": outcome.spacecraft,
            "day": outcome.day,
            "input_hash": outcome.input_hash,
            **outcome.summary,
        }
        version = done.scds_version
        if version is None:
            cal = dict(outcome.calibration)
            cal["provenance"] = {**cal["provenance"], FLEET_KEY: facts}
            path = self.scds_path(outcome.spacecraft)
            path.parent.mkdir(parents=True, exist_ok=True)
            version = self._append(path, scds.append_version, cal)
        solution = done.asf_solution
        if solution is None and outcome.attitude is not None:
            att = dict(outcome.attitude)
            prov = {**att["provenance"], "scds_version": int(version), FLEET_KEY: facts}
            att["provenance"] = prov
            path = self.asf_path(outcome.spacecraft)
            path.parent.mkdir(parents=True, exist_ok=True)
            solution = self._append(path, asf.append_solution, att)
        return Done(version, solution)
