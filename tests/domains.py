"""ROS domains for the test processes: two per process, held while it runs, unused elsewhere.

Every pytest process (the session, or each xdist worker: they all import the conftest) takes a
pair of domains (bagkit.ros.domains, as the pytest plugin does for a user's session): the first
for its tests, the second for a test that needs a domain of its own.
"""

from __future__ import annotations

import contextlib
import os
import socket
from collections.abc import Iterator

from bagkit.ros.domains import reserve


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
        first = reserve(2, os.getpid())
    os.environ["ROS_DOMAIN_ID"] = str(first)
    os.environ["BAGKIT_TEST_SPARE_DOMAIN_ID"] = str(first + 1)


@contextlib.contextmanager
def silent_participant(domain: int) -> Iterator[int]:
    """A socket on the discovery port of a participant id nobody uses in ``domain``, yielded:
    to bagkit's census (bagkit.ros.participants), a participant on this host that never
    answers."""
    # Not at the top: every test process imports this module, and the census imports rclpy.
    from bagkit.ros.participants import PARTICIPANT_IDS, discovery_port

    # The highest first: Fast DDS takes the lowest free.
    for participant in range(PARTICIPANT_IDS - 1, 0, -1):
        port = socket.socket(socket.AF_INET, socket.SOCK_DGRAM)
        try:
            port.bind(("127.0.0.1", discovery_port(domain, participant)))
        except OSError:
            port.close()
            continue
        with port:
            yield participant
        return
    raise RuntimeError(f"every participant port of domain {domain} is bound")
