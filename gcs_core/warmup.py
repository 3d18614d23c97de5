"""Compile the numerical kernels ahead of the first fit (``gcs warmup``, run by ``make run``'s install).

GCS's inner loops are numba functions cached on disk (:mod:`gcs_core.compiled`): the first
fit on a machine compiles them (about 30 s; warm, the same fit takes 3 s). :func:`warm_up`
pays that once, at install, by fitting and ranking the bundled sample missions (a
sun-pointing one with a gyro and every three-axis sensor, and a spinner) and stepping one
FILTR block; :func:`uncompiled_kernels` tells a face whether the next fit will compile, so
that it can say so instead of sitting silent.
"""

from __future__ import annotations

import logging
import sys
import time
from collections.abc import Callable, Iterator
from pathlib import Path

from gcs_core.compiled import COMPILED

log = logging.getLogger(__name__)

#: the bundled missions whose fits use every kernel (sample_data/missions/<name>)
WARMUP_MISSIONS = ("hidden-tam-contamination", "spinner-hidden-horizon")
SAMPLE_MISSIONS = Path(__file__).resolve().parent.parent / "sample_data" / "missions"


def _kernels() -> Iterator[tuple[str, object]]:
    """``(qualified name, dispatcher)`` of every numba function in the imported engine."""
    import gcs_core.session  # noqa: F401 — imports the estimators and models, so their kernels

    if not COMPILED:
        return
    from numba.core.registry import CPUDispatcher

    for name, module in list(sys.modules.items()):
        if not name.startswith("gcs_core.") or module is None:
            continue
        for attr, value in list(vars(module).items()):
            if isinstance(value, CPUDispatcher) and getattr(value, "__module__", name) == name:
                yield f"{name}.{attr}", value


def uncompiled_kernels() -> list[str]:
    """Kernels with no compiled version on disk yet (empty without numba): the next fit
    compiles them."""
    missing = []
    for name, dispatcher in _kernels():
        try:
            cache_file = dispatcher._cache._cache_file  # type: ignore[attr-defined] # numba private, untyped
            index = Path(cache_file._index_path)
        except AttributeError:  # another numba's layout: assume compiled rather than cry wolf
            continue
        if not index.exists():
            missing.append(name)
    return missing


def warm_up(
    missions: list[Path] | None = None, say: Callable[[str], None] = lambda text: None
) -> tuple[float, list[str]]:
    """Fit, rank and step one FILTR block on each mission (default: the bundled
    :data:`WARMUP_MISSIONS` that are present); ``(seconds taken, kernels still uncompiled)``."""
    from gcs_core.config import config_for
    from gcs_core.session import Analysis

    t0 = time.monotonic()
    if missions is None:
        missions = [SAMPLE_MISSIONS / n for n in WARMUP_MISSIONS if (SAMPLE_MISSIONS / n / "mission.toml").is_file()]
    if not COMPILED:
        say("numba is not installed (or GCS_NO_NUMBA is set): nothing to compile")
        return 0.0, []
    for path in missions:
        say(f"compiling with {path.name}: fit, ranking, one FILTR block")
        a = Analysis(config_for(path))
        a.fit()
        a.rank()
        a.make_filter().step()
    return time.monotonic() - t0, uncompiled_kernels()


#: kernels every fit runs: when one of them is not compiled, the next fit compiles them all
EVERY_FIT = ("gcs_core.problem.kernels.", "gcs_core.models.common.")


def cold_start() -> bool:
    """True when the next fit will compile the kernels (``gcs warmup`` has not run)."""
    return any(name.startswith(EVERY_FIT) for name in uncompiled_kernels())
