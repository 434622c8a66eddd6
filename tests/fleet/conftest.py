"""One local Dask cluster (2 single-threaded worker processes on 127.0.0.1) for the fleet tests
that run one after another, and generated bags; every worker process the cluster starts is
checked gone when it closes."""

from __future__ import annotations

from pathlib import Path

import psutil
import pytest
from distributed import Client, LocalCluster
from fleet_bags import T0, worker_pids, write_bag
from waiting import running

from bagkit.fleet import local_cluster


class SharedCluster:
    """The cluster, started for the first test that needs it and closed after the last of a
    run of fleet tests: idle, its scheduler and workers still take CPU (heartbeats, ticks) from
    the rest of the session."""

    def __init__(self) -> None:
        self.cluster: LocalCluster | None = None
        self.client: Client | None = None

    def get(self) -> Client:
        if self.client is None:
            self.cluster = local_cluster(2)
            self.client = Client(self.cluster)
        return self.client

    def close(self) -> None:
        """Close the cluster; its worker processes must be gone then."""
        if self.client is None or self.cluster is None:
            return
        pids = list(worker_pids(self.client).values())
        self.client.close()
        self.cluster.close()
        self.client = self.cluster = None
        alive = [pid for pid in pids if psutil.pid_exists(pid) and running(pid)]
        assert not alive, f"processes of the cluster left running: {alive}"


SHARED = SharedCluster()


@pytest.fixture
def client() -> Client:
    """A client of the shared cluster."""
    return SHARED.get()


def pytest_runtest_teardown(item: pytest.Item, nextitem: pytest.Item | None) -> None:
    """After the last of a run of fleet tests, close the cluster (a later one starts it again)."""
    if nextitem is None or not nextitem.path.is_relative_to(Path(__file__).parent):
        SHARED.close()


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
