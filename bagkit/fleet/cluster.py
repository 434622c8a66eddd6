"""Where a fleet run executes: in this process, on a local Dask cluster, or on a scheduler.

A local cluster listens on 127.0.0.1 only (scheduler, workers and dashboard) and runs one
single-threaded worker process per core: decoding holds the GIL, so threads would not help.
It is closed on every way out of the ``with`` block, Ctrl-C included, and its worker processes
with it.
"""

from __future__ import annotations

import importlib.util
import logging
import os
from collections.abc import Callable, Iterator
from contextlib import contextmanager
from typing import TYPE_CHECKING

from bagkit.extras import FLEET, installed, require
from bagkit.fleet.errors import FleetError, SchedulerError

if TYPE_CHECKING:
    from distributed import Client, LocalCluster

LOOPBACK = "127.0.0.1"


# Each local worker is a process of its own (about 100 MB): more than a few per core only
# share the cores, and a mistyped count must not start thousands of processes.
MAX_WORKERS_PER_CORE = 4


def default_workers() -> int:
    """One worker per core this process may run on."""
    return len(os.sched_getaffinity(0)) if hasattr(os, "sched_getaffinity") else os.cpu_count() or 1


def dashboard_available() -> bool:
    """The Dask dashboard needs bokeh; without it the cluster runs without a dashboard."""
    return importlib.util.find_spec("bokeh") is not None


def local_cluster(n_workers: int) -> LocalCluster:
    """A started LocalCluster of ``n_workers`` single-threaded processes on 127.0.0.1."""
    import dask
    from distributed import LocalCluster

    settings = {
        # Dask sets MALLOC_TRIM_THRESHOLD_ in its workers to give memory back sooner; with it
        # glibc maps and unmaps every large buffer afresh, and summaries run 1.6-2x slower.
        "distributed.nanny.pre-spawn-environ.MALLOC_TRIM_THRESHOLD_": None,
        # The dashboard's statistical profiler samples each worker's stack every 10 ms, in a
        # thread that takes the GIL from the task (benchmarks/README.md, find on 2 workers).
        "distributed.worker.profile.enabled": False,
    }
    with dask.config.set(settings):
        return LocalCluster(
            host=LOOPBACK,
            dashboard_address=f"{LOOPBACK}:0" if dashboard_available() else None,
            processes=True,
            n_workers=n_workers,
            threads_per_worker=1,
            # CRITICAL: a worker's failed heartbeat while the cluster closes is logged as an
            # ERROR with a traceback; bagkit reports every task's failure itself.
            silence_logs=logging.CRITICAL,
            preload=["bagkit.fleet.worker"],
        )


@contextmanager
def fleet_client(
    *,
    workers: int | None,
    scheduler: str | None,
    bags: int,
    announce: Callable[[str], None] | None = None,
) -> Iterator[Client | None]:
    """The Dask client of a run over ``bags`` bags, or None to run in this process.

    Args:
        workers: local worker processes; None: one per core when there is more than one bag,
            in this process for one; 0: in this process.
        scheduler: the address of an existing ``dask.distributed`` scheduler (``workers`` is
            then ignored).
        bags: how many bags the run reads.
        announce: told where the dashboard of a local cluster is.

    Raises:
        SchedulerError: ``scheduler`` cannot be reached.
        FleetError: more local workers than MAX_WORKERS_PER_CORE per core.
    """
    # In this process, without importing distributed (slow to import); also by default where
    # the fleet extra is not installed.
    local = workers == 0 or (workers is None and (bags <= 1 or not installed(FLEET)))
    if scheduler is None and local:
        yield None
        return
    require(FLEET, "running on Dask (--workers, --scheduler)")
    from distributed import Client

    if scheduler is not None:
        try:
            # Waits up to Dask's connect timeout (distributed.comm.timeouts.connect, 30 s).
            client = Client(scheduler)
        except (OSError, TimeoutError) as exc:
            raise SchedulerError(f"cannot reach the Dask scheduler at {scheduler}: {exc}") from None
        with client:
            yield client
        return
    if workers is not None and workers > MAX_WORKERS_PER_CORE * default_workers():
        raise FleetError(
            f"--workers {workers}: a local cluster runs at most {MAX_WORKERS_PER_CORE} worker "
            f"processes per core ({MAX_WORKERS_PER_CORE * default_workers()} here); for more, "
            "start a cluster and give --scheduler"
        )
    cluster = local_cluster(workers or default_workers())
    try:
        if announce is not None:
            link = cluster.dashboard_link if dashboard_available() else ""
            announce(
                f"local Dask cluster of {len(cluster.workers)} workers, dashboard {link}"
                if link
                else f"local Dask cluster of {len(cluster.workers)} workers (no dashboard: "
                "bokeh is not installed)"
            )
        with Client(cluster) as client:
            yield client
    finally:
        cluster.close()
