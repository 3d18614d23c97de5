"""Engine calls that run as background jobs, beyond fitting (which lives on the Workbench).

Each function takes the workbench, a ``progress(done, total, text)`` callback and a
``cancelled()`` predicate, stores its result on the workbench and returns it. They
are plain functions (no Textual) so tests can call them directly. They import the engine
plainly (inside each function, so that starting the TUI does not load what a view may never
use), where the type checker and the layer test see them.
"""

from __future__ import annotations

import logging
from pathlib import Path

from gcs_tui.tui import paths

log = logging.getLogger(__name__)


# ---------------------------------------------------------------------------- predictor
def predict(wb, progress=None, cancelled=None):
    """σ of every solve-for element along the config's data plan (gcs_core.predictor)."""
    from gcs_core.predictor.predict import predict as run

    if progress:
        progress(0, None, "accumulating information")
    result = run(wb.analysis)
    if cancelled is not None and cancelled():
        return None
    wb.prediction = result
    return result


# ---------------------------------------------------------------------------- verification
def verify(wb, progress=None, cancelled=None):
    """Onboard against ground attitude (gcs_core.verif.verify_analysis); fits first if needed."""
    from gcs_core.verif.analysis import verify_analysis as run

    if wb.result is None:
        if progress:
            progress(0, 2, "fitting first")
        wb.fit(progress=None, cancelled=cancelled)
    if progress:
        progress(1, 2, "comparing attitudes")
    result = run(wb.analysis)
    if cancelled is not None and cancelled():
        return None
    wb.verification = result
    return result


# ---------------------------------------------------------------------------- calibration
def scds_path(wb) -> Path:
    """The SCDS this session reads and appends to: the workbench's, else
    ``<mission>.scds.h5`` in the work directory (beside the analysis config, or beside the
    mission directory; :meth:`~gcs_tui.tui.workbench.Workbench.work_dir`)."""
    if wb.scds_path is not None:
        return Path(wb.scds_path)
    return paths.inside(wb.work_dir(), wb.mission.name, ".scds.h5")


def save_calibration(wb, path=None, note: str = "", progress=None, cancelled=None) -> int:
    """Append the latest fit to the SCDS at ``path`` (default :func:`scds_path`);
    returns the new version number and remembers the file on the workbench."""
    from gcs_core.calibration import save_calibration as save

    if progress:
        progress(0, None, "writing the SCDS")
    path = Path(path).expanduser() if path else scds_path(wb)
    path.parent.mkdir(parents=True, exist_ok=True)  # gcs tui --out to a folder not made yet
    version = save(wb.analysis, path, note=note or "")
    wb.scds_path = path
    return version


def scds_versions(path: Path):
    """Version summaries of an SCDS file (empty when the file does not exist)."""
    if path is None or not Path(path).exists():
        return []
    from gcs_core.io.scds import list_versions

    return list_versions(path)


def scds_diff(path: Path, a: int, b: int):
    from gcs_core.io.scds import diff_versions

    return diff_versions(path, a, b)


def scds_version(path: Path, n: int | None = None):
    from gcs_core.io.scds import read_version

    return read_version(path, n)
