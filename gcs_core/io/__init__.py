"""Mission files and GCS data sets: reading, checking, writing (ICD §1-§6, seed Table 3-2).

No physics here: what the files say, checked, as plain objects.

* :mod:`~gcs_core.io.types` — the tables and mission description the rest reads;
* :mod:`~gcs_core.io.csvio` — CSV tables per ICD §1;
* :mod:`~gcs_core.io.mission` — mission.toml (ICD §3, §5), with
  :mod:`~gcs_core.io.orbit_spec` for its orbit and ground-site tables;
* :mod:`~gcs_core.io.importer` — the whole mission directory, checked;
* :mod:`~gcs_core.io.tle_table` — a TLE file tabulated as an ephemeris table;
* :mod:`~gcs_core.io.h5store` — the one place HDF5 files are opened (atomic, locked,
  checksummed), with :mod:`~gcs_core.io.locks` for the locks between processes;
* :mod:`~gcs_core.io.outputs` — output paths checked before work (kinds GCS recognises,
  writability); :mod:`~gcs_core.inputs` — input paths that are not regular files;
* :mod:`~gcs_core.io.sdf` — the Standard Data File (seed Table 3-2), read;
  :mod:`~gcs_core.io.sdf_write` writes it;
* :mod:`~gcs_core.io.scds` — the Sensor Calibration Data Set (append-only versions);
* :mod:`~gcs_core.io.asf` — the Attitude Status File (append-only solutions).
"""
