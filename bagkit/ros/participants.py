"""Whether discovery has found every participant: a census of this host's DDS participants.

A participant in another process shows up in the graph when one of its discovery announcements
arrives; with Fast DDS that is often its periodic one (every 3 s), not the reply to ours, so a
player that must not lose a first message watches the graph for 3 s. Where discovery is limited
to this host, the participants there can be counted instead: each one binds the metatraffic
unicast port of its participant id (RTPS 9.6.1.1: 7400 + 250 * domain + 10 + 2 * id), and each
ROS participant publishes ``ros_discovery_info``. Once every bound port's participant has been
discovered, no subscriber is still to come.
"""

from __future__ import annotations

import os
from collections.abc import Callable, Mapping
from pathlib import Path

from rclpy.node import Node

from bagkit.ros.fastdds import localhost_only

# RTPS well-known ports (spec 9.6.1.1, the defaults every DDS uses): PB, DG, PG, d1.
_PORT_BASE = 7400
_DOMAIN_GAIN = 250
_PARTICIPANT_GAIN = 2
_METATRAFFIC_UNICAST = 10
# rmw_dds_common's topic: one publisher per ROS participant (not a ROS name: not mangled).
_PARTICIPANT_TOPIC = "ros_discovery_info"
_SOCKET_TABLES = (Path("/proc/net/udp"), Path("/proc/net/udp6"))
# A GUID prefix from Fast DDS: vendor 1.15, host id (2 bytes), process id (low 2 bytes, little
# endian), then random and per-process bytes (Fast DDS 2.x GuidUtils).
_FAST_DDS_VENDOR = bytes([1, 15])
_PID_LIMIT = 1 << 22  # Linux's largest pid_max


def all_discovered(node: Node, environ: Mapping[str, str]) -> Callable[[], bool] | None:
    """A test of whether ``node`` has discovered every participant it can, or None.

    None when discovery reaches beyond this host (``ROS_AUTOMATIC_DISCOVERY_RANGE`` other than
    LOCALHOST, or static peers): participants elsewhere cannot be counted. The test is False
    while the count cannot be trusted (:func:`host_participants`) or a participant on this host
    is not in the graph yet (one that is no ROS participant never is).
    """
    if not localhost_only(environ) or environ.get("ROS_STATIC_PEERS", "").strip():
        return None
    domain = node.context.get_domain_id()

    def test() -> bool:
        on_host = host_participants(domain)
        return on_host is not None and discovered_participants(node) >= on_host

    return test


def host_participants(domain_id: int) -> int | None:
    """The DDS participants of ``domain_id`` on this host, this process's included.

    None when the count cannot be trusted: the socket tables are not readable, or this
    process's own participant is not among them (a transport without UDP).
    """
    base = _PORT_BASE + _DOMAIN_GAIN * domain_id + _METATRAFFIC_UNICAST
    ports: set[int] = set()
    own: set[int] = set()
    mine = _own_socket_inodes()
    try:
        for table in _SOCKET_TABLES:
            if not table.exists():
                continue
            for line in table.read_text().splitlines()[1:]:
                fields = line.split()
                port = int(fields[1].rsplit(":", 1)[1], 16)
                offset = port - base
                if 0 <= offset < _DOMAIN_GAIN - _METATRAFFIC_UNICAST and offset % 2 == 0:
                    ports.add(port)
                    if int(fields[9]) in mine:
                        own.add(port)
    except (OSError, ValueError, IndexError):
        return None
    return len(ports) if own else None


def discovered_participants(node: Node) -> int:
    """The live ROS participants in ``node``'s graph, its own included.

    A participant whose process had exited a moment before this one started was seen in the
    graph (and the census then ended the wait before the one subscriber was found): Fast DDS
    writes the low 16 bits of its process id into its GUID prefix, and a participant with no
    process of those bits on this host is not counted.
    """
    infos = node.get_publishers_info_by_topic(_PARTICIPANT_TOPIC, no_mangle=True)
    return sum(1 for info in infos if _process_may_live(bytes(info.endpoint_gid)))


def _process_may_live(gid: bytes) -> bool:
    """False only for a Fast DDS participant none of whose possible processes exists here."""
    if gid[:2] != _FAST_DDS_VENDOR:
        return True
    low = int.from_bytes(gid[4:6], "little")
    return any(os.path.exists(f"/proc/{pid}") for pid in range(low, _PID_LIMIT, 1 << 16))


def _own_socket_inodes() -> set[int]:
    """Inodes of this process's sockets (``/proc/self/fd`` links ``socket:[INODE]``)."""
    inodes = set()
    try:
        for fd in os.listdir("/proc/self/fd"):
            with_target = _readlink(f"/proc/self/fd/{fd}")
            if with_target.startswith("socket:["):
                inodes.add(int(with_target[8:-1]))
    except OSError:
        return set()
    return inodes


def _readlink(path: str) -> str:
    try:
        return os.readlink(path)
    except OSError:  # closed since the listing
        return ""
