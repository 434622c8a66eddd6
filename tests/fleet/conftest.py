"""One local Dask cluster (2 single-threaded worker processes on 127.0.0.1) for every fleet
test, and generated bags; every worker process the cluster starts is checked gone at teardown."""

from __future__ import annotations

from collections.abc import Iterator
from pathlib import Path

import psutil
import pytest
from distributed import Client
from fleet_bags import T0, running, worker_pids, write_bag

from bagkit.fleet import local_cluster


@pytest.fixture(scope="session")
def client() -> Iterator[Client]:
    """A client of the shared cluster; its worker processes are checked gone afterwards."""
    cluster = local_cluster(2)
    with Client(cluster) as shared:
        yield shared
        pids = list(worker_pids(shared).values())
    cluster.close()
    alive = [pid for pid in pids if psutil.pid_exists(pid) and running(pid)]
    assert not alive, f"processes of the cluster left running: {alive}"


@pytest.fixture(scope="session")
def fleet_dir(tmp_path_factory: pytest.TempPathFactory) -> Path:
    """Six bags under one root (two in a sub-directory), hours apart, different spreads."""
    root = tmp_path_factory.mktemp("fleet")
    for i in range(6):
        where = root / "day2" if i >= 4 else root
        where.mkdir(exist_ok=True)
        write_bag(where / f"flight_{i}", seed=i, n=400 + 50 * i, t0=T0 + i * 3_600 * 10**9)
    return root


@pytest.fixture(scope="session")
def fleet_bags(fleet_dir: Path) -> list[Path]:
    from bagkit.fleet import expand_bags

    return expand_bags([fleet_dir])
