"""ROS domains a process holds for itself: free of other processes' participants and sockets.

A domain is held with an exclusive ``flock`` on a file of its own under the temp directory,
for as long as the process lives (the lock goes with it, also when it is killed), so that
concurrent sessions on this machine never share one; a domain whose ports some other process
has bound (a session that did not take a lock, a benchmark, ``ros2`` by hand) is passed over.
Needs no ROS runtime: the pytest plugin reserves domains at pytest's start.
"""

from __future__ import annotations

import fcntl
import tempfile
from pathlib import Path
from typing import IO

from bagkit.ros.errors import RosError

# RTPS well-known ports (spec 9.6.1.1, the defaults every DDS uses): a domain's ports are
# PORT_BASE + DOMAIN_GAIN * domain + offsets, below 65536: domains 0 - 232.
PORT_BASE = 7400
DOMAIN_GAIN = 250
# Domains of automatic choice, above the ones people set by hand (the demo uses 77 and 78).
FIRST, LAST = 100, 231
SOCKET_TABLES = (Path("/proc/net/udp"), Path("/proc/net/udp6"))
_LOCKS = Path(tempfile.gettempdir()) / "bagkit-ros-domains"
_held: list[IO[bytes]] = []  # open for the process's life: the locks go with it


def udp_sockets() -> list[tuple[int, int]]:
    """(local port, socket inode) of every UDP socket on this machine, IPv4 and IPv6.

    Raises:
        OSError, ValueError, IndexError: a socket table that cannot be read or parsed.
    """
    sockets = []
    for table in SOCKET_TABLES:
        if not table.exists():
            continue
        for line in table.read_text().splitlines()[1:]:
            fields = line.split()
            sockets.append((int(fields[1].rsplit(":", 1)[1], 16), int(fields[9])))
    return sockets


def _in_use(domain: int, bound: set[int]) -> bool:
    first = PORT_BASE + DOMAIN_GAIN * domain
    return any(first <= port < first + DOMAIN_GAIN for port in bound)


def _lock(domain: int) -> IO[bytes] | None:
    try:
        lock = (_LOCKS / f"{domain}.lock").open("wb")
    except OSError:  # another user's lock file: theirs
        return None
    try:
        fcntl.flock(lock, fcntl.LOCK_EX | fcntl.LOCK_NB)
    except BlockingIOError:
        lock.close()
        return None
    return lock


def reserve(count: int, seed: int) -> int:
    """The first of ``count`` consecutive domains held by this process from now on.

    ``seed`` (a pid) picks where the search starts, so that sessions rarely contend.

    Raises:
        RosError: every run of ``count`` domains in ``FIRST`` - ``LAST`` is held or bound, or
            the lock directory cannot be made.
    """
    try:
        _LOCKS.mkdir(exist_ok=True)
    except OSError as exc:
        raise RosError(f"cannot hold ROS domains in {_LOCKS}: {exc}: set ROS_DOMAIN_ID") from None
    starts = list(range(FIRST, LAST - count + 2, count))
    try:
        bound = {port for port, _ in udp_sockets()}
    except (OSError, ValueError, IndexError):
        bound = set()  # the locks alone still keep this machine's sessions apart
    at = seed % len(starts)
    for first in starts[at:] + starts[:at]:
        domains = range(first, first + count)
        if any(_in_use(domain, bound) for domain in domains):
            continue
        locks = [lock for domain in domains if (lock := _lock(domain)) is not None]
        if len(locks) == count:
            _held.extend(locks)
            return first
        for lock in locks:
            lock.close()
    raise RosError(f"no {count} free ROS domains in {FIRST} - {LAST}: set ROS_DOMAIN_ID")
