"""A worker process killed by a signal mid-run: the run completes, its tasks are re-run on
the restarted or other worker, and no SCDS entry is lost or duplicated."""

from __future__ import annotations

import os
import signal
import time

import pytest
from fleet_cases import local_cluster, small_fleet

from gcs_core.fleet.manifest import read_manifest
from gcs_core.fleet.run import run_fleet
from gcs_core.fleet.store import FleetStore

#: a stress run (a LocalCluster, a worker killed, its tasks re-run), ~25 s on idle cores:
#: marked slow (CI runs it; make quick skips it)
pytestmark = pytest.mark.slow


def _alive(pid: int) -> bool:
    try:
        os.kill(pid, 0)
    except ProcessLookupError:
        return False
    return True


@pytest.mark.skipif(not hasattr(signal, "SIGKILL"), reason="needs POSIX signals")
def test_a_worker_killed_mid_run_loses_and_duplicates_nothing(tmp_path):
    manifest, truth = small_fleet(tmp_path, discover=False, duration_s=600.0)
    m = read_manifest(manifest)
    killed: list[int] = []
    in_flight: list[str] = []  # the task keys the killed worker was computing
    with local_cluster(2) as (cluster, client):
        pids = client.run(os.getpid)  # worker address -> pid

        def progress(entry, text):
            if entry.state == "calibrated" and not killed:
                busy = {a: keys for a, keys in client.processing().items() if keys}
                if not busy:  # between tasks: try again at the next result
                    return
                addr = max(busy, key=lambda a: len(busy[a]))  # a worker computing now
                in_flight.extend(str(k) for k in busy[addr])
                os.kill(pids[addr], signal.SIGKILL)
                killed.append(pids[addr])

        run = run_fleet(m, scheduler=cluster.scheduler_address, progress=progress)
        deadline = time.monotonic() + 10
        while _alive(killed[0]) and time.monotonic() < deadline:
            time.sleep(0.1)
        after = client.run(os.getpid)
    assert killed and not _alive(killed[0])
    assert set(after.values()) != set(pids.values())  # the nanny started a new worker process
    bad = {(sc, d) for sc, r in truth["spacecraft"].items() for d, rec in r["days"].items() if rec["malformed"]}
    states = {(e.spacecraft, e.day): e.state for e in run.entries}
    assert len(states) == 8
    assert {k for k, s in states.items() if s == "error"} == bad
    assert all(s == "calibrated" for k, s in states.items() if k not in bad)
    # the tasks the dead worker held were computed again, by another worker process
    assert in_flight
    for key in in_flight:
        e = next(e for e in run.entries if key.startswith(f"fleet-{e.spacecraft}-{e.day}-"))
        assert e.state == "calibrated" and e.worker.rsplit(":", 1)[-1] != str(killed[0])
    store = FleetStore(m.output)
    for sc in m.spacecraft:
        days = [p["fleet"]["day"] for _, p in store.calibrations(sc.name)]
        want = [d for d in m.days if (sc.name, d) not in bad]
        assert days == want  # each good day once, in order: none lost, none duplicated
        assert [p["fleet"]["day"] for _, p in store.attitudes(sc.name)] == want
    # and the run after the fault has nothing left to do
    again = run_fleet(m, scheduler=None, workers=1)
    assert {e.state for e in again.entries} == {"already done", "error"}
