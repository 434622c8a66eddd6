"""The local cluster: loopback only, dashboard on 127.0.0.1, workers configured for bagkit."""

from __future__ import annotations

import os
import signal

import pytest
from distributed import Client

from bagkit.fleet.cluster import (
    CLUSTER_PAYS_FROM_S,
    WorkRate,
    cluster_pays,
    default_workers,
    fleet_client,
)


def _worker_setup() -> tuple[str | None, object]:
    return os.environ.get("MALLOC_TRIM_THRESHOLD_"), signal.getsignal(signal.SIGINT)


def test_everything_listens_on_loopback(client: Client) -> None:
    info = client.scheduler_info()
    assert info["address"].startswith("tcp://127.0.0.1:")
    assert len(info["workers"]) == 2
    assert all(address.startswith("tcp://127.0.0.1:") for address in info["workers"])
    assert client.dashboard_link.startswith("http://127.0.0.1:")


def test_workers_ignore_ctrl_c_and_keep_glibc_defaults(client: Client) -> None:
    # Ctrl-C is the driver's to handle; Dask's malloc trim threshold slows numpy down 1.6-2x.
    for trim, handler in client.run(_worker_setup).values():
        assert trim is None
        assert handler == signal.SIG_IGN


@pytest.mark.parametrize(
    ("bags", "mib", "cores", "pays"),
    [
        (1, 10_000, 2, False),  # one bag: nothing to share out
        (40, 10_000, 1, False),  # one core: the workers would take turns
        (10, 3, 2, False),  # 10 small bags: the start costs more than the work
        (40, 1_200, 2, False),  # 40 x 30 MB: 2.6 s in one process, below the threshold
        (40, 4_000, 2, True),
        (2_000, 0, 2, True),  # many bags: the per-bag cost alone
    ],
)
def test_a_cluster_starts_only_when_it_pays(bags: int, mib: int, cores: int, pays: bool) -> None:
    rate = WorkRate(per_bag_s=0.002, per_mib_s=0.0025)
    assert cluster_pays(rate, bags, mib * 2**20, cores) is pays


def test_default_runs_in_process_unless_the_work_pays() -> None:
    cheap = WorkRate(per_bag_s=0.0, per_mib_s=0.0)
    with fleet_client(workers=None, scheduler=None, bags=10, size_bytes=1, rate=cheap) as client:
        assert client is None
    costly = WorkRate(per_bag_s=CLUSTER_PAYS_FROM_S, per_mib_s=0.0)
    with fleet_client(workers=None, scheduler=None, bags=2, size_bytes=1, rate=costly) as client:
        assert client is not None
        assert len(client.scheduler_info()["workers"]) == default_workers()
    with fleet_client(workers=0, scheduler=None, bags=2, size_bytes=1, rate=costly) as client:
        assert client is None
