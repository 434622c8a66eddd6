"""The local cluster: loopback only, dashboard on 127.0.0.1, workers configured for bagkit."""

from __future__ import annotations

import os
import signal

from distributed import Client


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
