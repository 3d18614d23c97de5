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
  importable; pin their BLAS threads where they are started). The address is checked
  like any other input (:func:`check_scheduler`): a port nobody listens on, a service
  that is not a Dask scheduler, or a scheduler without workers is one line naming
  ``--scheduler`` within :data:`CONNECT_TIMEOUT_S` (twice that with no worker), never a
  hang. The work itself (the config and the mission read on this machine) travels
  with the tasks: workers read no file of the submitting machine.

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


#: seconds to reach a scheduler and complete Dask's handshake
CONNECT_TIMEOUT_S = 3.0
#: seconds to wait for a scheduler's first worker
WORKER_WAIT_S = 4.0


def _scheduler_error(address: str, why: str):
    from gcs_core.errors import InputError

    return InputError(f"cannot use the Dask scheduler at {address}: {why}", key="--scheduler")


def check_scheduler(address: str) -> tuple[str, int]:
    """(host, port) of ``tcp://host:port`` (or ``host:port``), after a plain TCP connection
    within :data:`CONNECT_TIMEOUT_S`; one-line :class:`~gcs_core.errors.InputError` otherwise."""
    import socket
    from urllib.parse import urlsplit

    text = address.strip()
    url = urlsplit(text if "://" in text else f"tcp://{text}")
    if url.scheme != "tcp":
        raise _scheduler_error(address, f"only tcp:// addresses are supported, not {url.scheme}://")
    try:
        host, port = url.hostname, url.port
    except ValueError:
        host, port = None, None
    if not host or port is None:
        raise _scheduler_error(address, "give tcp://HOST:PORT")
    deadline = time.monotonic() + CONNECT_TIMEOUT_S
    try:
        with socket.create_connection((host, port), timeout=CONNECT_TIMEOUT_S) as sock:
            why = _dask_greeting(sock, deadline)
    except TimeoutError:
        raise _scheduler_error(address, f"not a Dask scheduler (no greeting within {CONNECT_TIMEOUT_S:g} s)") from None
    except OSError as err:
        raise _scheduler_error(address, err.strerror or type(err).__name__) from None
    if why:
        raise _scheduler_error(address, f"not a Dask scheduler ({why})")
    return host, port


#: the largest greeting a Dask peer sends (its handshake is a few dozen bytes)
MAX_GREETING_BYTES = 65536


def _read_exactly(sock, n: int, deadline: float) -> bytes:
    buf = b""
    while len(buf) < n:
        sock.settimeout(max(deadline - time.monotonic(), 0.01))
        chunk = sock.recv(n - len(buf))
        if not chunk:
            raise ConnectionError("closed the connection")
        buf += chunk
    return buf


def _dask_greeting(sock, deadline: float) -> str:
    """Why the peer is not a Dask server ("" if it is): a Dask listener first sends its
    handshake (``distributed.comm.core.Listener.on_connection``), a length-prefixed
    message (``distributed.comm.tcp``: 8-byte length, then packed frames) holding a dict
    with its ``python`` version. Read within ``deadline``, bounded in size, decoded by
    ``distributed.protocol`` — never a blind allocation of whatever length a stranger sends."""
    import struct

    from distributed.protocol.core import loads
    from distributed.protocol.utils import unpack_frames

    try:
        (n,) = struct.unpack("Q", _read_exactly(sock, 8, deadline))
        if not 0 < n <= MAX_GREETING_BYTES:
            return f"a first message of {n} bytes"
        frames, more = unpack_frames(_read_exactly(sock, n, deadline), partial=True)
        if more:
            return "a greeting with extra buffers"
        msg = loads(frames)
    except ConnectionError as err:
        return str(err)
    except TimeoutError:  # socket.timeout too
        raise
    except Exception as err:  # noqa: BLE001 — any undecodable greeting: not Dask
        return f"an undecodable greeting: {type(err).__name__}"
    if not isinstance(msg, dict) or "python" not in msg:
        return "a greeting without Dask's handshake"
    return ""


def _client(client_cls, address: str):
    """A Dask client of a checked scheduler that has at least one worker (module docstring).

    Dask's own connection is bounded by :data:`CONNECT_TIMEOUT_S`; whatever a service that
    is not a Dask scheduler makes it raise (a timeout, a closed stream, an absurd frame
    length read from its bytes) is that service's answer, not a bug here.
    """
    host, port = check_scheduler(address)
    try:
        client = client_cls(f"tcp://{host}:{port}", timeout=f"{CONNECT_TIMEOUT_S}s")
    except Exception as err:  # noqa: BLE001 — any failure of the handshake means "not a Dask scheduler"
        raise _scheduler_error(address, f"not a Dask scheduler ({type(err).__name__})") from None
    try:
        client.wait_for_workers(1, timeout=WORKER_WAIT_S)
    except Exception:  # noqa: BLE001 — a timeout however Dask spells it
        client.close()
        raise _scheduler_error(address, f"no worker joined within {WORKER_WAIT_S:g} s") from None
    return client


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
        return _client(Client, scheduler), None
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
