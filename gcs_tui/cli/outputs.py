"""Every output path of a ``gcs`` command, checked before its work starts.

A read-only ``--report`` or a typo naming the calibration history must cost one line and
no fitting time: :func:`check_outputs` runs before the command (the checks themselves are
:mod:`gcs_core.io.outputs`).
"""

from __future__ import annotations

import os
from datetime import UTC, datetime
from pathlib import Path

from gcs_core.errors import DataFileError
from gcs_core.io.outputs import check_distinct, check_output_dir, check_output_file

#: option attribute -> (option, kind written, what, appended to)
FILES = {
    "sdf": ("--sdf", "SDF", "the SDF", False),
    "report": ("--report", "text", "the JSON report", False),
    "scds": ("--scds", "SCDS", "the calibration", True),
    "asf": ("--asf", "ASF", "the ground attitudes", True),
    "plot": ("--plot", "text", "the plot", False),
    "write_config": ("--write-config", "text", "the plan's config", False),
}
#: option attribute -> (option, what) of output folders
FOLDERS = {"plots": ("--plots", "the plots")}


def check_outputs(args) -> None:
    """Check each output option ``args`` carries (InputError naming the first bad one)."""
    given: dict[str, str] = {}
    for attr, (option, kind, what, append) in FILES.items():
        path = getattr(args, attr, None)
        if path:
            check_output_file(path, kind=kind, what=f"{what} ({option})", append=append)
            if append and Path(path).exists():  # a history that would refuse the append: before the fit
                from gcs_core.io import asf, h5append, scds

                module = scds if kind == "SCDS" else asf
                h5append.check_appendable(path, module.FORMAT, module.COLLECTION, max_version=module.VERSION)
            given[option] = path
    for attr, (option, what) in FOLDERS.items():
        path = getattr(args, attr, None)
        if path:
            check_output_dir(path, what=f"{what} ({option})")
    check_distinct(given)


def beside(path: str | os.PathLike) -> Path:
    """A new file beside ``path`` for what could not be appended to it."""
    p = Path(path)
    stamp = datetime.now(UTC).strftime("%Y%m%dT%H%M%SZ")
    return p.with_name(f"{p.name}.unsaved-{stamp}-{os.getpid()}.h5")


def save_calibration_kept(analysis, path: str | os.PathLike, note: str) -> tuple[int, Path, str]:
    """Append the calibration of a finished fit to the SCDS ``path``; never lose it.

    Returns ``(version, file, problem)``. When the SCDS cannot take it (locked past the
    wait, damaged, refused), the calibration goes to a new SCDS :func:`beside` it and
    ``problem`` says why; the analyst appends it later.
    """
    from gcs_core.calibration import save_calibration

    try:
        return save_calibration(analysis, Path(path), note=note), Path(path), ""
    except DataFileError as err:
        other = beside(path)
        version = save_calibration(analysis, other, note=note)
        return version, other, err.message
