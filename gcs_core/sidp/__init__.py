"""SIDP: state initialization and data preparation (seed §3.2.2).

Reading the mission directory (ICD §1-§6) and the GCS data sets kept in HDF5:

* :mod:`~gcs_core.sidp.csvio` — CSV tables per ICD §1;
* :mod:`~gcs_core.sidp.mission` — mission.toml (ICD §3, §5);
* :mod:`~gcs_core.sidp.importer` — the whole mission directory, checked;
* :mod:`~gcs_core.sidp.h5store` — the one place HDF5 files are opened (atomic, locked,
  checksummed);
* :mod:`~gcs_core.sidp.sdf` — the Standard Data File (seed Table 3-2);
* :mod:`~gcs_core.sidp.scds` — the Sensor Calibration Data Set (append-only versions);
* :mod:`~gcs_core.sidp.asf` — the Attitude Status File (append-only solutions).

The names below are imported lazily so that ``import gcs_core.sidp.types`` stays light.
"""

from __future__ import annotations

import importlib

_EXPORTS = {
    "Table": "types", "SensorSpec": "types", "MissionSpec": "types",
    "read_table": "csvio", "write_table": "csvio",
    "read_mission_spec": "mission",
    "load_mission": "importer", "ImportedMission": "importer", "ImportReport": "importer",
    "write_sdf": "sdf", "read_sdf": "sdf", "iter_blocks": "sdf",
    "append_version": "scds", "list_versions": "scds", "read_version": "scds",
    "diff_versions": "scds",
    "append_solution": "asf", "list_solutions": "asf", "read_solution": "asf",
}

__all__ = sorted(_EXPORTS)


def __getattr__(name: str):
    if name in _EXPORTS:
        module = importlib.import_module(f"{__name__}.{_EXPORTS[name]}")
        return getattr(module, name)
    raise AttributeError(f"module {__name__!r} has no attribute {name!r}")
