"""Run many independent jobs serially or on a Dask cluster, handing results to the caller.

Trade studies and Monte Carlo are embarrassingly parallel: each plan or run is computed
from its own definition. :func:`run_jobs` cuts the items into batches, computes each batch
with ``func(payload, batch)``, and calls ``on_batch(results)`` in the *calling* process as
batches finish, so only the client ever writes the results file.

* serial (``workers`` None or 0, no ``scheduler``): no Dask import at all; results are
  handed over at least every :data:`SERIAL_FLUSH_S` seconds;
* ``workers = N``: a ``dask.distributed.LocalCluster`` of N single-threaded worker
  processes, each with its BLAS pinned to one thread (the environment of the spawned
  workers), started and closed here;
* ``scheduler = "tcp://host:port"``: an existing cluster (its workers must have GCS
  importable; pin their BLAS threads where they are started).

Batches are sized so each task takes well over Dask's per-task overhead (about a
millisecond of scheduling and a few of pickling a batch and its results; the payload is
scattered once) and the load still balances: :data:`TASKS_PER_WORKER` tasks per worker.
A plan takes ~0.1 s, so a 200-plan study on two workers runs tasks of ~7 plans (~0.7 s,
a hundred times the overhead), and the worker that finishes last waits at most one
such task for the other (with 4 tasks per worker it was a quarter of the study's time). Ctrl-C cancels the
tasks still pending and re-raises; every batch already handed over stays with the caller.
"""

from __future__ import annotations

import logging
import math
import os
import time
from collections.abc import Callable, Sequence
from typing import Any

log = logging.getLogger(__name__)

#: tasks per worker: enough to balance uneven plans and a loaded machine, few enough that
#: each task stays far over the per-task overhead (module docstring)
TASKS_PER_WORKER = 16
#: the serial path hands results over at least this often [s]
SERIAL_FLUSH_S = 1.0
#: environment of every worker process: one BLAS/OpenMP thread (small matrices; threads
#: would only contend for the cores)
PIN_ENV = {"OPENBLAS_NUM_THREADS": "1", "OMP_NUM_THREADS": "1", "MKL_NUM_THREADS": "1", "NUMBA_NUM_THREADS": "1"}


def batch_size(n: int, workers: int, requested: int | None = None) -> int:
    """Items per task: the requested size, else about ``TASKS_PER_WORKER`` tasks per worker."""
    if requested:
        return max(1, int(requested))
    return max(1, math.ceil(n / max(1, workers * TASKS_PER_WORKER)))


def batches(items: Sequence, size: int) -> list[list]:
    return [list(items[i : i + size]) for i in range(0, len(items), size)]


def run_jobs(
    func: Callable[[Any, list], list],
    payload: Any,
    items: Sequence,
    *,
    on_batch: Callable[[list], None],
    workers: int | None = None,
    scheduler: str | None = None,
    batch: int | None = None,
    progress: Callable[[int, int], None] | None = None,
) -> None:
    """Compute ``func(payload, batch)`` over ``items`` (module docstring).

    ``progress(done, total)`` is called in the calling process after each handed-over
    batch. Raises ``KeyboardInterrupt`` after cancelling pending tasks on Ctrl-C.
    """
    total = len(items)
    done = 0
    if total == 0:
        return
    if not workers and not scheduler:
        pending: list = []
        last = time.monotonic()
        for item in items:
            pending.extend(func(payload, [item]))
            if time.monotonic() - last >= SERIAL_FLUSH_S:
                on_batch(pending)
                done += len(pending)
                pending, last = [], time.monotonic()
                if progress:
                    progress(done, total)
        if pending:
            on_batch(pending)
            done += len(pending)
            if progress:
                progress(done, total)
        return
    client, cluster = connect(workers, scheduler)
    try:
        n_workers = max(1, len(client.scheduler_info().get("workers", {})) or (workers or 1))
        size = batch_size(total, n_workers, batch)
        from dask.distributed import as_completed

        remote = client.scatter(payload, broadcast=True)
        futures = [client.submit(func, remote, b, pure=False) for b in batches(list(items), size)]
        log.info("%d tasks of up to %d items on %d workers", len(futures), size, n_workers)
        try:
            for fut in as_completed(futures):
                res = fut.result()
                on_batch(res)
                done += len(res)
                if progress:
                    progress(done, total)
        except BaseException:
            client.cancel(futures)
            raise
    finally:
        client.close()
        if cluster is not None:
            cluster.close()


def connect(workers: int | None, scheduler: str | None):
    """(client, cluster or None): a new LocalCluster of ``workers`` pinned processes, or a
    client of the existing ``scheduler``."""
    try:
        import dask
        from dask.distributed import Client, LocalCluster
    except ImportError:  # pragma: no cover - an optional extra
        from gcs_core.errors import InputError

        raise InputError(
            "--workers and --scheduler need dask and distributed (pip install 'gcs[scale]')", key="workers"
        ) from None
    if scheduler:
        return Client(scheduler, timeout="20s"), None
    for k, v in PIN_ENV.items():
        os.environ.setdefault(k, v)
    dask.config.set({"distributed.nanny.pre-spawn-environ": dict(PIN_ENV), "distributed.worker.daemon": False})
    assert workers is not None  # without a scheduler the caller gives a count
    cluster = LocalCluster(  # scheduler and dashboard on the loopback only: nothing served to the network
        n_workers=int(workers),
        threads_per_worker=1,
        processes=True,
        host="127.0.0.1",
        dashboard_address="127.0.0.1:0",
        silence_logs=logging.ERROR,
    )
    return Client(cluster), cluster
