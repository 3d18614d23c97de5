"""A trade study from its definition to its results file (resumable, serial or on Dask).

:func:`run_study` computes every plan not already in the output file
(:func:`gcs_core.trade.store.done_indices`), appends each finished batch atomically, and
returns every row of the study (old and new) in study order. A killed study keeps what
it had written; ``resume=True`` computes only what is missing.
"""

from __future__ import annotations

import json
import math
from collections.abc import Callable, Sequence
from dataclasses import asdict
from pathlib import Path

import numpy as np

from gcs_core.trade import engine, store
from gcs_core.trade.study import PlanRow, StudyDefinition, check_study, evaluate_plans


def row_from_record(rec: dict) -> PlanRow:
    """A :class:`PlanRow` back from its stored record."""
    tup = lambda v: tuple(float(x) for x in v)
    return PlanRow(
        int(rec["index"]),
        rec["plan_id"],
        rec["values"],
        rec["description"],
        tuple(rec["elements"]),
        tup(rec["sigma"]),
        tup(rec["noise_only"]),
        tuple(rec["units"]),
        {k: tup(v) for k, v in rec["budget"].items()},
        tuple(rec["undetermined"]),
        tuple(rec["unobservable"]),
        dict(rec["frames"]),
        rec["status"],
        float(rec["seconds"]),
        tuple(bool(x) for x in rec.get("prior_limited", ())),
        tuple(rec.get("warnings", ())),
    )


def read_study(path: str | Path) -> tuple[StudyDefinition | None, list[PlanRow]]:
    """(definition, rows in study order) of a results file."""
    head, recs = store.read(path, store.TRADE)
    defn = StudyDefinition.from_json(head["study"]) if head.get("study") else None
    rows = {}
    for r in recs:
        rows[int(r["index"])] = row_from_record(r)
    return defn, [rows[i] for i in sorted(rows)]


def _evaluate(defn: StudyDefinition, batch: list) -> list[PlanRow]:
    return evaluate_plans(defn, batch)


def run_study(
    defn: StudyDefinition,
    output: str | Path | None = None,
    *,
    workers: int | None = None,
    scheduler: str | None = None,
    resume: bool = False,
    overwrite: bool = False,
    batch: int | None = None,
    progress: Callable[[int, int], None] | None = None,
) -> list[PlanRow]:
    """Compute the study (module docstring); without ``output`` nothing is written.

    ``progress(done, total)`` counts plans, those already in the file included.
    """
    defn = defn.with_source()  # read here once; the workers get it with the tasks
    check_study(defn)  # a varied key or value no plan could use: refused before any work
    combos = defn.combos()
    digest = defn.digest()
    skip: set[int] = set()
    if output is not None:
        skip = store.prepare_output(output, store.TRADE, digest, resume=resume, overwrite=overwrite)
    items = [(i, c) for i, c in enumerate(combos) if i not in skip]
    new: list[PlanRow] = []
    study = defn.as_json()

    def on_batch(rows: list[PlanRow]) -> None:
        new.extend(rows)
        if output is not None and rows:
            store.append_batch(
                output,
                store.TRADE,
                study=study,
                digest=digest,
                records=[asdict(r) for r in rows],
                arrays={"sigma": np.array([r.sigma for r in rows], dtype=float)},
            )

    total = len(combos)
    prog = None if progress is None else (lambda done, _n: progress(len(skip) + done, total))
    if progress is not None and skip:
        progress(len(skip), total)
    engine.run_jobs(
        _evaluate, defn, items, on_batch=on_batch, workers=workers, scheduler=scheduler, batch=batch, progress=prog
    )
    if output is not None:
        _, rows = read_study(output)
        return rows
    return sorted(new, key=lambda r: r.index)


def varied_keys(rows: list[PlanRow]) -> tuple[str, ...]:
    """The keys that take more than one value among ``rows``, the one with the most values
    first (the x axis of a plot), then in study order."""
    keys = list(rows[0].values) if rows else []
    count = {k: len({json.dumps(r.values.get(k)) for r in rows}) for k in keys}
    return tuple(sorted((k for k in keys if count[k] > 1), key=lambda k: -count[k]))


def sigma_grid(rows: Sequence[PlanRow], element: str, keys: tuple[str, ...]) -> tuple[list, list, np.ndarray]:
    """σ of ``element`` over one or two varied keys: (values of key 1, of key 2 or [None],
    (n1, n2) array, the minimum over the other keys' values for each cell)."""
    k1 = keys[0]
    k2 = keys[1] if len(keys) > 1 else None
    v1 = list(dict.fromkeys(r.values.get(k1) for r in rows))
    v2 = list(dict.fromkeys(r.values.get(k2) for r in rows)) if k2 else [None]
    G = np.full((len(v1), len(v2)), math.inf)
    for r in rows:
        if r.status != "ok" or element not in r.elements:
            continue
        i, j = v1.index(r.values.get(k1)), v2.index(r.values.get(k2)) if k2 else 0
        s = r.sigma_of(element)
        if np.isfinite(s) or np.isinf(s):
            G[i, j] = min(G[i, j], s) if not math.isnan(s) else G[i, j]
    return v1, v2, G
