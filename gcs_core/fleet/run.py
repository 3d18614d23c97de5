"""The submitter: one fleet run over days and spacecraft, tasks on ``dask.distributed``.

For each spacecraft-day, in day order, the submitting process

1. builds the config (manifest template + overrides), reads the mission into memory
   (:func:`gcs_core.io.importer.load_mission`: the checks of ``gcs import``), checks the
   config against it, and forms the input hash (:func:`gcs_core.fleet.store.input_hash`).
   A bad file gives that spacecraft-day its one-line error and nothing else stops;
2. skips it when the store already holds its hash (re-running a finished day adds
   nothing; a partial day resumes where it stopped);
3. submits :func:`gcs_core.fleet.task.run_job` with the mission *in the task* (the task
   carries its data: a worker never opens a path of this machine, and when a worker dies
   the scheduler still has what it needs to run the task elsewhere). At most
   ``window`` tasks are in flight, so memory stays bounded on a large fleet;
4. appends each outcome to the spacecraft's SCDS and ASF (:meth:`FleetStore.append`),
   here, one append at a time, a spacecraft's days in order.

Workers: a ``LocalCluster`` of ``workers`` single-threaded processes on 127.0.0.1 (their BLAS
pinned to one thread, :data:`gcs_core.trade.engine.PIN_ENV`), or the cluster at
``scheduler`` (its workers must import GCS). A worker that dies has its tasks re-run by
the scheduler on another (``distributed``'s ``allowed-failures``); a task that fails that
often is that spacecraft-day's error.
"""

from __future__ import annotations

import logging
import time
from collections.abc import Callable, Iterator
from dataclasses import dataclass, field
from pathlib import Path

from gcs_core.errors import GcsError
from gcs_core.fleet.manifest import Manifest
from gcs_core.fleet.store import Done, FleetStore, input_hash
from gcs_core.fleet.task import Job, Outcome, one_line, run_job, warm_up

log = logging.getLogger(__name__)

__all__ = ["Entry", "FleetRun", "run_fleet", "connect"]

#: tasks in flight per worker (a few, so a worker never waits for the submitter)
IN_FLIGHT_PER_WORKER = 2
#: Dask's own polling, slowed for a local cluster: with its defaults the scheduler and the
#: nannies, which run in the submitting process, take 34 ms of CPU per second doing nothing
#: (an event-loop health tick every 20 ms, each nanny reading its worker's memory every
#: 100 ms, the system monitor every 0.5 s): on 2 cores that is taken from the 2 workers.
#: With these, 6 ms/s. A worker is still restarted past its memory limit, within 1 s.
QUIET_CLUSTER = {
    "distributed.admin.tick.interval": "1s",
    "distributed.worker.memory.monitor-interval": "1s",
    "distributed.admin.system-monitor.interval": "5s",
}


@dataclass
class Entry:
    """One spacecraft-day of a run: ``state`` is ``calibrated`` (computed and appended),
    ``already done`` (the store held its hash), ``completed`` (only the ASF solution was
    missing) or ``error`` (``error`` says why, in one line)."""

    spacecraft: str
    day: str
    state: str
    error: str | None = None
    input_hash: str = ""
    scds_version: int | None = None
    asf_solution: int | None = None
    worker: str = ""
    seconds: float = 0.0
    cpu_s: float = 0.0


@dataclass
class FleetRun:
    """What a run did: one :class:`Entry` per spacecraft-day, the number of workers, the
    wall time [s] (``compute_s``: from the cluster being up to the last append), each
    worker's resident and peak memory [MB] at the end, and the CPU time [s] spent over
    ``compute_s``: ``client_cpu_s`` by this process (reading missions, appending, the
    Dask client; for a local cluster also its scheduler and nannies, which run here) and
    ``worker_cpu_s`` by each worker process (its tasks and Dask's work around them);
    ``warm_up_cpu_s``: each worker's import of GCS as the cluster started (before
    ``compute_s``, :func:`gcs_core.fleet.task.warm_up`)."""

    entries: list[Entry] = field(default_factory=list)
    workers: int = 0
    wall_s: float = 0.0
    compute_s: float = 0.0
    worker_memory_mb: dict = field(default_factory=dict)
    client_cpu_s: float = 0.0
    worker_cpu_s: dict = field(default_factory=dict)
    warm_up_cpu_s: dict = field(default_factory=dict)

    def entry(self, spacecraft: str, day: str) -> Entry:
        for e in self.entries:
            if e.spacecraft == spacecraft and e.day == day:
                return e
        raise KeyError((spacecraft, day))


@dataclass
class _Prepared:
    entry: Entry
    job: Job | None = None
    done: Done | None = None


ProgressFn = Callable[[Entry, str], None]


def _prepare(m: Manifest, store: FleetStore, sc, day: str) -> _Prepared:
    from gcs_core.config_checks import check_against_mission
    from gcs_core.io.importer import load_mission

    e = Entry(sc.name, day, "error")
    try:
        cfg = m.config(sc, day)
        if not Path(cfg.mission).is_dir():
            raise GcsError(f"no mission directory at {cfg.mission}")
        mission = load_mission(cfg.mission)
        check_against_mission(cfg, mission.spec)
        e.input_hash = input_hash(mission, cfg)
        done = store.done(sc.name, e.input_hash)
    except GcsError as err:
        e.error = one_line(err)
        return _Prepared(e)
    except OSError as err:
        e.error = one_line(f"{getattr(err, 'filename', '') or ''}: {err.strerror or err}")
        return _Prepared(e)
    if done.complete:
        e.state, e.scds_version, e.asf_solution = "already done", done.scds_version, done.asf_solution
        return _Prepared(e, done=done)
    job = Job(sc.name, day, e.input_hash, cfg, mission, m.discover, m.max_steps, note=f"gcs fleet {m.name} {day}")
    return _Prepared(e, job=job, done=done)


def connect(workers: int, scheduler: str | None):
    """(client, cluster or None): a LocalCluster of ``workers`` pinned processes on
    127.0.0.1, or a client of the cluster at ``scheduler``, reached and checked as the trade
    studies do it (:func:`gcs_core.trade.engine.connect`: one line, exit 2, within seconds,
    when nothing Dask answers there)."""
    import dask

    from gcs_core.trade.engine import connect as dask_connect

    with dask.config.set(QUIET_CLUSTER):  # read when the scheduler, nannies and workers start
        return dask_connect(workers, scheduler)


def _process_cpu_s() -> float:
    """CPU time [s] of this process so far (run on each worker)."""
    return time.process_time()


def _worker_memory() -> dict:
    """This worker's resident and peak memory [MB] (run on each worker)."""
    import resource

    import psutil

    rss = psutil.Process().memory_info().rss / 2**20
    peak = resource.getrusage(resource.RUSAGE_SELF).ru_maxrss / 1024.0  # Linux: kB
    return {"rss_mb": rss, "peak_mb": peak}


class _Ordered:
    """Appends outcomes one at a time, each spacecraft's days in manifest order."""

    def __init__(self, store: FleetStore, days: list[str], run: FleetRun, progress: ProgressFn | None):
        self.store, self.days, self.run, self.progress = store, days, run, progress
        self.next: dict[str, int] = {}
        self.waiting: dict[tuple[str, str], tuple[Entry, Outcome | None, Done | None]] = {}

    def settle(self, entry: Entry, outcome: Outcome | None = None, done: Done | None = None) -> None:
        self.waiting[(entry.spacecraft, entry.day)] = (entry, outcome, done)
        sc = entry.spacecraft
        i = self.next.get(sc, 0)
        while i < len(self.days) and (sc, self.days[i]) in self.waiting:
            self._write(*self.waiting.pop((sc, self.days[i])))
            i += 1
        self.next[sc] = i

    def _write(self, entry: Entry, outcome: Outcome | None, done: Done | None) -> None:
        if outcome is not None:
            entry.worker, entry.seconds, entry.cpu_s = outcome.worker, outcome.seconds, outcome.cpu_s
            if outcome.error:
                entry.state, entry.error = "error", outcome.error
            else:
                try:
                    had = done or Done(None, None)
                    now = self.store.append(outcome, done=had)
                    entry.state = "completed" if had.scds_version is not None else "calibrated"
                    entry.scds_version, entry.asf_solution = now.scds_version, now.asf_solution
                except (GcsError, ValueError) as err:  # a locked/corrupt file, a record the writer refuses
                    entry.state, entry.error = "error", one_line(err)
        self.run.entries.append(entry)
        if self.progress:
            self.progress(entry, _describe(entry, outcome))


def _describe(e: Entry, outcome: Outcome | None) -> str:
    if e.state == "error":
        return f"error: {e.error}"
    if e.state == "already done":
        return f"already done (SCDS version {e.scds_version}, ASF solution {e.asf_solution})"
    s = outcome.summary if outcome else {}
    flag = s.get("flag")
    ver = "not verified" if flag is None else ("§4.4 FLAG" if flag else "§4.4 ok")
    found = s.get("discovered") or []
    disc = f"; discovered {', '.join(found)}" if found else ""
    fit = "consistent with noise" if s.get("adequate") else "model inadequate"
    return (
        f"{e.state} in {e.seconds:.1f} s on {e.worker}: {s.get('status', '?')}, {fit}, {ver}{disc} "
        f"(SCDS version {e.scds_version})"
    )


def _items(m: Manifest, store: FleetStore, days: list[str], names: list[str]) -> Iterator[_Prepared]:
    for day in days:
        for name in names:
            yield _prepare(m, store, m.spacecraft_named(name), day)


def run_fleet(
    m: Manifest,
    *,
    days: list[str] | None = None,
    spacecraft: list[str] | None = None,
    workers: int = 2,
    scheduler: str | None = None,
    progress: ProgressFn | None = None,
    on_client: Callable[[object], None] | None = None,
) -> FleetRun:
    """Run the fleet's days (module docstring). ``on_client(client)`` is called once the
    cluster is up (tests use it to reach the workers)."""
    t0 = time.perf_counter()
    days = list(days or m.days)
    names = list(spacecraft or [sc.name for sc in m.spacecraft])
    store = FleetStore(m.output)
    run = FleetRun()
    order = _Ordered(store, days, run, progress)
    items = _items(m, store, days, names)
    pending: list[_Prepared] = []
    for p in items:  # no cluster until some spacecraft-day needs computing
        if p.job is not None:
            pending.append(p)
            break
        order.settle(p.entry)
    if pending:
        _compute(pending, items, order, run, workers, scheduler, on_client)
    run.wall_s = time.perf_counter() - t0
    return run


def _compute(pending, items, order: _Ordered, run: FleetRun, workers, scheduler, on_client) -> None:
    import dask
    from dask.distributed import as_completed

    client, cluster = connect(workers, scheduler)
    try:
        if on_client:
            on_client(client)
        try:  # part of starting a worker: importing GCS (a worker restarted later imports in its first task)
            run.warm_up_cpu_s = client.run(warm_up)
        except Exception as err:  # noqa: BLE001 — a worker that cannot import GCS fails its tasks, one line each
            log.debug("workers not warmed up: %s", err)
        t_up, cpu_up = time.perf_counter(), time.process_time()
        cpu_workers = _cpu_of(client)
        n = max(1, len(client.scheduler_info().get("workers", {})) or workers)
        run.workers = n
        window = IN_FLIGHT_PER_WORKER * n
        live: dict = {}  # key -> (future, prepared)
        ac = as_completed()
        # a mission in a task is a few MB; that is the point (the task carries its data)
        with dask.config.set({"distributed.admin.large-graph-warning-threshold": "2GB"}):

            def submit(p: _Prepared) -> None:
                job = p.job
                assert job is not None  # only prepared jobs are submitted
                key = f"fleet-{job.spacecraft}-{job.day}-{job.input_hash[:12]}"
                fut = client.submit(run_job, job, key=key, pure=False, retries=1)
                live[fut.key] = (fut, p)
                ac.add(fut)

            for p in pending:
                submit(p)
            exhausted = False

            def refill() -> None:
                nonlocal exhausted
                while not exhausted and len(live) < window:
                    nxt = next(items, None)
                    if nxt is None:
                        exhausted = True
                    elif nxt.job is None:
                        order.settle(nxt.entry)
                    else:
                        submit(nxt)

            refill()
            for fut in ac:
                _, p = live.pop(fut.key)
                try:
                    outcome = fut.result()
                except Exception as err:  # noqa: BLE001 — a task lost for good (KilledWorker...) is its one line
                    outcome = Outcome(p.entry.spacecraft, p.entry.day, p.entry.input_hash)
                    outcome.error = one_line(f"task failed: {type(err).__name__}: {err}")
                fut.release()
                refill()  # the workers' queues first: the append below runs while they compute
                order.settle(p.entry, outcome, p.done)
            for p2 in items:  # anything left (only skips and errors once the window is empty)
                order.settle(p2.entry) if p2.job is None else order.settle(p2.entry, _not_run(p2))
        run.compute_s, run.client_cpu_s = time.perf_counter() - t_up, time.process_time() - cpu_up
        run.worker_cpu_s = {w: c - cpu_workers.get(w, 0.0) for w, c in _cpu_of(client).items()}
        try:
            run.worker_memory_mb = client.run(_worker_memory)
        except Exception as err:  # noqa: BLE001 — memory figures are a nicety
            log.debug("no worker memory figures: %s", err)
    except BaseException:
        client.cancel([f for f, _ in live.values()] if "live" in locals() else [])
        raise
    finally:
        client.close()
        if cluster is not None:
            cluster.close()


def _cpu_of(client) -> dict:
    """Each worker's CPU time so far [s] ({} when the workers cannot say)."""
    try:
        return client.run(_process_cpu_s)
    except Exception as err:  # noqa: BLE001 — CPU figures are a nicety
        log.debug("no worker CPU figures: %s", err)
        return {}


def _not_run(p: _Prepared) -> Outcome:
    o = Outcome(p.entry.spacecraft, p.entry.day, p.entry.input_hash)
    o.error = "not run (the submission loop ended first)"
    return o
