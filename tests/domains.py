"""ROS domains for the test processes: two per process, held while it runs, unused elsewhere.

Every pytest process (the session, or each xdist worker: they all import the conftest) takes a
pair of domains: the first for its tests, the second for a test that needs a domain of its own.
A pair is held with an exclusive ``flock`` on a file under the temp directory, so concurrent
sessions on this machine never share one, and a pair whose ports some other process has bound
(a session started another way, a benchmark) is passed over.
"""

from __future__ import annotations

import fcntl
import os
import tempfile
from pathlib import Path
from typing import IO

# Fast DDS derives a domain's ports as 7400 + 250 * domain + offsets, below 65536: domains
# 0 - 232. The demo and `make golden` use 77 and 78; the tests keep to 100 - 231.
FIRST, LAST = 100, 231
_PORT_BASE, _PORTS_PER_DOMAIN = 7400, 250
_LOCKS = Path(tempfile.gettempdir()) / "bagkit-test-domains"
_held: list[IO[bytes]] = []  # open for the process's life: the lock goes with it


def _bound_udp_ports() -> set[int]:
    """The local UDP ports bound on this machine (IPv4 and IPv6)."""
    ports = set()
    for table in ("/proc/net/udp", "/proc/net/udp6"):
        try:
            lines = Path(table).read_text().splitlines()[1:]
        except OSError:
            continue
        ports.update(int(line.split()[1].rsplit(":", 1)[1], 16) for line in lines)
    return ports


def _in_use(domain: int, bound: set[int]) -> bool:
    first = _PORT_BASE + _PORTS_PER_DOMAIN * domain
    return any(first <= port < first + _PORTS_PER_DOMAIN for port in bound)


def reserve_pair(seed: int) -> int:
    """The first of two consecutive domains held by this process from now on.

    ``seed`` (the pid) picks where the search starts, so that sessions rarely contend.
    """
    _LOCKS.mkdir(exist_ok=True)
    pairs = list(range(FIRST, LAST, 2))
    bound = _bound_udp_ports()
    start = seed % len(pairs)
    for first in pairs[start:] + pairs[:start]:
        if _in_use(first, bound) or _in_use(first + 1, bound):
            continue
        lock = (_LOCKS / f"{first}.lock").open("wb")
        try:
            fcntl.flock(lock, fcntl.LOCK_EX | fcntl.LOCK_NB)
        except BlockingIOError:
            lock.close()
            continue
        _held.append(lock)
        return first
    raise RuntimeError(f"no free pair of ROS domains in {FIRST} - {LAST}")


def assign() -> None:
    """Set ``ROS_DOMAIN_ID`` and ``BAGKIT_TEST_SPARE_DOMAIN_ID`` for this process.

    ``BAGKIT_TEST_DOMAIN_ID`` set by the user fixes the first domain instead: each xdist worker
    then takes two from it on (gw0 the given one and the next, gw1 the two after, ...).
    """
    given = os.environ.get("BAGKIT_TEST_DOMAIN_ID")
    if given is not None:
        worker = os.environ.get("PYTEST_XDIST_WORKER", "gw0")
        first = int(given) + 2 * int(worker.removeprefix("gw"))
    else:
        first = reserve_pair(os.getpid())
    os.environ["ROS_DOMAIN_ID"] = str(first)
    os.environ["BAGKIT_TEST_SPARE_DOMAIN_ID"] = str(first + 1)
