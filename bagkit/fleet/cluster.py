"""Where a fleet run executes: in this process, on a local Dask cluster, or on a scheduler.

A local cluster listens on 127.0.0.1 only (scheduler, workers and dashboard) and runs one
single-threaded worker process per core: decoding holds the GIL, so threads would not help.
It is closed on every way out of the ``with`` block, Ctrl-C included, and its worker processes
with it.
"""

from __future__ import annotations

import importlib.util
import os
from collections.abc import Callable, Iterator
from contextlib import contextmanager
from dataclasses import dataclass
from typing import TYPE_CHECKING

from bagkit.fleet.errors import FleetError, SchedulerError
from bagkit.words import counted

if TYPE_CHECKING:
    from distributed import Client, LocalCluster

LOOPBACK = "127.0.0.1"


# Each local worker is a process of its own (about 100 MB): more than a few per core only
# share the cores, and a mistyped count must not start thousands of processes.
MAX_WORKERS_PER_CORE = 4


# In-process work from which a local cluster pays for its start: its start-up and speed-up are
# measured in benchmarks/README.md, "Dask only when it pays", with a margin for a busy machine.
CLUSTER_PAYS_FROM_S = 4.0


@dataclass(frozen=True, slots=True)
class WorkRate:
    """What a fleet command costs in one process, measured (benchmarks/README.md).

    Attributes:
        per_bag_s: seconds per bag, whatever its size (opening it, its summary).
        per_mib_s: seconds per MiB of bag files.
    """

    per_bag_s: float
    per_mib_s: float

    def seconds(self, bags: int, size_bytes: int) -> float:
        """The estimated time of ``bags`` bags of ``size_bytes`` in all, in one process."""
        return self.per_bag_s * bags + self.per_mib_s * size_bytes / 2**20


# What each fleet command costs in one process, from its in-process runs over 40 bags of 30 MB
# and 1,000 bags of 6 kB (catalog), and the repository's fixtures (golden check).
SUMMARY_RATE = WorkRate(per_bag_s=0.005, per_mib_s=0.0025)
FIND_RATE = WorkRate(per_bag_s=0.005, per_mib_s=0.002)
EXPORT_RATE = WorkRate(per_bag_s=0.01, per_mib_s=0.0055)
CATALOG_RATE = WorkRate(per_bag_s=0.0005, per_mib_s=0.0007)
# check reads each topic's columns once, as a summary does: 1.0-1.3x stats summary's time on
# 1M Imu (benchmarks/README.md, check), and a little more per bag (the contract's topics).
CHECK_RATE = WorkRate(per_bag_s=0.01, per_mib_s=0.003)
LOCKSTEP_RATE = WorkRate(per_bag_s=0.3, per_mib_s=0.5)


def cluster_pays(rate: WorkRate, bags: int, size_bytes: int, cores: int) -> bool:
    """Whether a local cluster on ``cores`` cores finishes this work sooner than one process."""
    return bags > 1 and cores > 1 and rate.seconds(bags, size_bytes) >= CLUSTER_PAYS_FROM_S


def default_workers() -> int:
    """One worker per core this process may run on."""
    return len(os.sched_getaffinity(0)) if hasattr(os, "sched_getaffinity") else os.cpu_count() or 1


def dashboard_available() -> bool:
    """The Dask dashboard needs bokeh; without it the cluster runs without a dashboard."""
    return importlib.util.find_spec("bokeh") is not None


def local_cluster(n_workers: int) -> LocalCluster:
    """A started LocalCluster of ``n_workers`` single-threaded processes on 127.0.0.1."""
    import logging  # here: a command that decides against a cluster starts without it

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


def _fleet_installed() -> bool:
    """Whether the fleet extra (Dask) is installed; bagkit.extras is imported only then."""
    from bagkit.extras import FLEET, installed

    return installed(FLEET)


@contextmanager
def fleet_client(
    *,
    workers: int | None,
    scheduler: str | None,
    bags: int,
    size_bytes: int,
    rate: WorkRate,
    announce: Callable[[str], None] | None = None,
) -> Iterator[Client | None]:
    """The Dask client of a run over ``bags`` bags, or None to run in this process.

    Args:
        workers: local worker processes; None: one per core where :func:`cluster_pays` says a
            cluster is worth its start, else in this process; 0: in this process.
        scheduler: the address of an existing ``dask.distributed`` scheduler (``workers`` is
            then ignored).
        bags: how many bags the run reads; ``size_bytes``: their files' bytes in all.
        rate: what the command costs in one process.
        announce: told where the dashboard of a local cluster is.

    Raises:
        SchedulerError: ``scheduler`` cannot be reached.
        FleetError: more local workers than MAX_WORKERS_PER_CORE per core (field ``workers``).
    """
    # In this process, without importing distributed (slow to import); also by default where
    # the fleet extra is not installed (looked for only when a cluster would pay: one bag
    # starts without searching the path for Dask).
    local = workers == 0 or (
        workers is None
        and not (cluster_pays(rate, bags, size_bytes, default_workers()) and _fleet_installed())
    )
    if scheduler is None and local:
        yield None
        return
    from bagkit.extras import FLEET, require

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
            f"{workers}: a local cluster runs at most {MAX_WORKERS_PER_CORE} worker processes "
            f"per core ({MAX_WORKERS_PER_CORE * default_workers()} here)",
            "workers",
        )
    cluster = local_cluster(workers or default_workers())
    try:
        if announce is not None:
            link = cluster.dashboard_link if dashboard_available() else ""
            size = counted(len(cluster.workers), "worker")
            announce(
                f"local Dask cluster of {size}, dashboard {link}"
                if link
                else f"local Dask cluster of {size} (no dashboard: bokeh is not installed)"
            )
        with Client(cluster) as client:
            yield client
    finally:
        cluster.close()
