"""Results files of trade studies and Monte Carlo (HDF5 through :mod:`gcs_core.io.h5store`).

Layout (format ``TRADE`` or ``MONTECARLO``, version 1)::

    /                      attrs: gcs_format, gcs_format_version, study (JSON: the
                           definition), study_digest (what the numbers depend on)
    /batches/00001/        one group per batch of finished plans (runs), in the order
                           they finished
        record             (k,) UTF-8 JSON, one per plan (run): its full description
                           and results (∞ and NaN written as Infinity and NaN)
        index              (k,) int64, the plan's (run's) position in the study
        <name>             (k, ...) float64 arrays named by the caller (``sigma``,
                           ``x_hat``, ...), for readers that want plain HDF5

Every batch is appended with :func:`~gcs_core.io.h5append.append_group`: a new file
written beside the old one, checksummed, fsync-ed and renamed over it. A study killed
at any moment leaves the file as it was after the last finished batch, every row
readable; :func:`done_indices` tells a resumed study what is already there.
"""

from __future__ import annotations

import json
from collections.abc import Mapping, Sequence
from pathlib import Path
from typing import Any

import numpy as np

from gcs_core.errors import InputError
from gcs_core.io import h5append, h5store
from gcs_core.io.outputs import refuse_other_kind
from gcs_core.json_values import json_default

TRADE, MONTECARLO = "TRADE", "MONTECARLO"
VERSION = 1
COLLECTION = "batches"


def append_batch(
    path: str | Path,
    fmt: str,
    *,
    study: str,
    digest: str,
    records: Sequence[Mapping],
    arrays: Mapping[str, np.ndarray] | None = None,
) -> int:
    """Append one batch of finished records; returns its group number."""
    recs = [json.dumps(r, default=json_default) for r in records]  # key order kept: it is the study's
    idx = np.array([int(r["index"]) for r in records], dtype=np.int64)

    def build(group, number):
        group.file.attrs["study"] = study
        group.file.attrs["study_digest"] = digest
        h5store.write_array(group, "record", np.array(recs, dtype=object))
        h5store.write_array(group, "index", idx)
        for name, a in (arrays or {}).items():
            h5store.write_array(group, name, np.asarray(a, dtype=float))

    return h5append.append_group(path, fmt, VERSION, COLLECTION, build, max_version=VERSION)


def read(path: str | Path, fmt: str) -> tuple[dict[str, str], list[dict[str, Any]]]:
    """(root attributes ``study``/``study_digest``, records in the order they were written)."""
    records: list[dict[str, Any]] = []
    with h5store.open_read(path, fmt, max_version=VERSION) as f:
        head = {k: h5store.attr_str(f, k, "") for k in ("study", "study_digest")}
        if COLLECTION in f:
            for name in sorted(f[COLLECTION]):
                for text in h5store.read_strings(f[COLLECTION][name]["record"]):
                    records.append(json.loads(text))
    return head, records


def done_indices(path: str | Path, fmt: str, digest: str) -> set[int]:
    """Indices already in ``path`` for the study ``digest`` (empty if there is no file).

    Raises :class:`InputError` when the file holds another study (resuming it would mix
    two studies' numbers)."""
    p = Path(path)
    if not p.exists():
        return set()
    head, records = read(p, fmt)
    if head.get("study_digest") and head["study_digest"] != digest:
        raise InputError(
            f"holds another study (digest {head['study_digest']}, this one {digest}): "
            "write to a new file, or use --overwrite",
            file=p,
        )
    return {int(r["index"]) for r in records}


def prepare_output(path: str | Path, fmt: str, digest: str, *, resume: bool, overwrite: bool) -> set[int]:
    """Check the output file before a run; returns the indices to skip.

    A file that exists needs ``resume`` (continue the same study) or ``overwrite``
    (start again: the old file is removed).
    """
    p = Path(path)
    if not p.parent.is_dir():
        raise InputError("the output's directory does not exist", file=p.parent)
    if p.exists() and not (resume or overwrite):
        raise InputError("exists: add --resume to compute only what is missing, or --overwrite", file=p)
    if p.exists() and overwrite and not resume:
        refuse_other_kind(p, fmt, f"the {fmt.lower()} results")  # --overwrite never deletes an SCDS
        p.unlink()
        return set()
    return done_indices(p, fmt, digest) if resume else set()
