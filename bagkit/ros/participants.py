"""Whether discovery has found every participant: a census of this host's DDS participants.

A participant in another process shows up in the graph when one of its discovery announcements
arrives; with Fast DDS that is often its periodic one (every 3 s), not the reply to ours, so a
player that must not lose a first message watches the graph for 3 s. Where discovery is limited
to this host, the participants there can be counted instead: each one binds the metatraffic
unicast port of its participant id (RTPS 9.6.1.1: 7400 + 250 * domain + 10 + 2 * id), and each
ROS participant publishes ``ros_discovery_info``. Once every bound port's participant has been
discovered, and each one's readers have arrived, no subscriber is still to come.
"""

from __future__ import annotations

import os
from collections.abc import Mapping
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
# A gid is a GUID: the participant's prefix, then the entity id.
_PREFIX = 12


class Census:
    """Whether ``node`` has discovered every participant on this host and their readers.

    A participant is in the graph once its ``ros_discovery_info`` writer has been discovered,
    but its readers come in a separate discovery stream: when that stream's first packet was
    lost, they came at its resend (1 s with Fast DDS), and a census of participants alone had
    ended the wait before the one subscriber was found. So a participant other than this one
    also needs a reader in the graph: the stream brings them together, and every ROS
    participant has one (it reads ``ros_discovery_info``).
    """

    def __init__(self, node: Node) -> None:
        self._node = node
        self._domain = node.context.get_domain_id()
        self._own: bytes | None = None

    def __call__(self) -> bool:
        """True once every participant on this host, and a reader of each other one, is found."""
        on_host = host_participants(self._domain)
        if on_host is None:
            return False
        participants = {gid[:_PREFIX] for gid in live_participant_gids(self._node)}
        if len(participants) < on_host:
            return False
        own = self._own_prefix()
        if own is None:
            return False
        with_readers = {gid[:_PREFIX] for gid in self._readers_in_graph()}
        return participants - {own} <= with_readers

    def _own_prefix(self) -> bytes | None:
        """The GUID prefix of ``node``'s participant, from one of its publishers in the graph."""
        if self._own is None:
            node = self._node
            me = (node.get_name(), node.get_namespace())
            for topic, _ in node.get_publisher_names_and_types_by_node(*me):
                for info in node.get_publishers_info_by_topic(topic):
                    if (info.node_name, info.node_namespace) == me:
                        self._own = bytes(info.endpoint_gid)[:_PREFIX]
                        return self._own
        return self._own

    def _readers_in_graph(self) -> set[bytes]:
        node = self._node
        return {
            bytes(info.endpoint_gid)
            for name, _ in node.get_topic_names_and_types(no_demangle=True)
            for info in node.get_subscriptions_info_by_topic(name, no_mangle=True)
        }


def all_discovered(node: Node, environ: Mapping[str, str]) -> Census | None:
    """A census of ``node``'s discovery, or None when one cannot be taken.

    None when discovery reaches beyond this host (``ROS_AUTOMATIC_DISCOVERY_RANGE`` other than
    LOCALHOST, or static peers): participants elsewhere cannot be counted. The census says
    False while the count cannot be trusted (:func:`host_participants`), a participant on this
    host is not in the graph yet (one that is no ROS participant never is), or its readers are
    not (:class:`Census`).
    """
    if not localhost_only(environ) or environ.get("ROS_STATIC_PEERS", "").strip():
        return None
    return Census(node)


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
    """The number of :func:`live_participant_gids`."""
    return len(live_participant_gids(node))


def live_participant_gids(node: Node) -> list[bytes]:
    """The gids of the live ROS participants' ``ros_discovery_info`` writers, ``node``'s own
    included.

    A participant whose process had exited a moment before this one started was seen in the
    graph (and the census then ended the wait before the one subscriber was found): Fast DDS
    writes the low 16 bits of its process id into its GUID prefix, and a participant with no
    process of those bits on this host is not counted.
    """
    infos = node.get_publishers_info_by_topic(_PARTICIPANT_TOPIC, no_mangle=True)
    gids = [bytes(info.endpoint_gid) for info in infos]
    return [gid for gid in gids if _process_may_live(gid)]


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
