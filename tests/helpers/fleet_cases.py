"""A small simulated fleet and a local Dask cluster for the fleet tests (gcs_core.fleet)."""

from __future__ import annotations

import json
import logging
from contextlib import contextmanager
from pathlib import Path

#: a small fleet: 4 spacecraft (one with a hidden effect, one whose TAM bias moves on day 2,
#: one with a malformed file on day 2) × 2 days of 15 min
SMALL = {"n": 4, "days": 2, "duration_s": 900.0}


def small_fleet(root: Path, **kw) -> tuple[Path, dict]:
    """(manifest, truth) of a simulated small fleet under ``root``."""
    from gcs_core.fleet.simulate import simulate_fleet

    manifest = simulate_fleet(root, **{**SMALL, **kw})
    return manifest, json.loads((root / "truth.json").read_text())


@contextmanager
def local_cluster(workers: int = 2):
    """A LocalCluster of single-threaded worker processes on 127.0.0.1 (nannies restart a
    killed worker), and its client."""
    import dask
    from dask.distributed import Client, LocalCluster

    from gcs_core.trade.engine import PIN_ENV

    with dask.config.set({"distributed.nanny.pre-spawn-environ": dict(PIN_ENV)}):
        cluster = LocalCluster(
            n_workers=workers,
            threads_per_worker=1,
            processes=True,
            host="127.0.0.1",
            dashboard_address="127.0.0.1:0",
            silence_logs=logging.ERROR,
        )
    client = Client(cluster)
    try:
        yield cluster, client
    finally:
        client.close()
        cluster.close()
