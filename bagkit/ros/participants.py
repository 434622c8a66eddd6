"""Whether discovery has found every participant: a census of this host's DDS participants.

A participant in another process shows up in the graph when one of its discovery announcements
arrives; with Fast DDS that is often its periodic one (every 3 s), not the reply to ours, so a
player that must not lose a first message watches the graph for 3 s. Where discovery is limited
to this host, the participants there can be counted instead: each one binds the metatraffic
unicast port of its participant id (RTPS 9.6.1.1: 7400 + 250 * domain + 10 + 2 * id), and each
ROS participant publishes ``ros_discovery_info``. Once every bound port's participant has been
discovered, its nodes named and their readers arrived (:func:`settled`), no subscriber is
still to come.
"""

from __future__ import annotations

import os
import time
from collections.abc import Iterable, Mapping, Set
from dataclasses import dataclass

from rclpy.node import Node

from bagkit.ros.domains import DOMAIN_GAIN, PORT_BASE, udp_sockets
from bagkit.ros.fastdds import localhost_only

# RTPS well-known ports (spec 9.6.1.1): a participant's, PG and d1.
_PARTICIPANT_GAIN = 2
_METATRAFFIC_UNICAST = 10
# Participant ids whose discovery port lies within their domain's ports.
PARTICIPANT_IDS = (DOMAIN_GAIN - _METATRAFFIC_UNICAST) // _PARTICIPANT_GAIN
# rmw_dds_common's topic: one publisher per ROS participant (not a ROS name: not mangled).
_PARTICIPANT_TOPIC = "ros_discovery_info"
# A GUID prefix from Fast DDS: vendor 1.15, host id (2 bytes), process id (low 2 bytes, little
# endian), then random and per-process bytes (Fast DDS 2.x GuidUtils).
_FAST_DDS_VENDOR = bytes([1, 15])
_PID_LIMIT = 1 << 22  # Linux's largest pid_max
# A gid is a GUID: the participant's prefix, then the entity id.
_PREFIX = 12
# The node name rmw gives an endpoint that no participant's entities message has named yet.
_UNKNOWN_NODE = "_NODE_NAME_UNKNOWN_"
# A new participant that heard the answers to its first announcement has found every other
# participant on this host within this: the answers and the endpoint exchange take milliseconds.
ANSWERS_WITHIN_S = 0.15


class Census:
    """Whether ``node`` has discovered every participant on this host and their readers.

    A participant is in the graph once its ``ros_discovery_info`` writer has been discovered,
    but its readers come in a separate discovery stream, and its nodes' names in a message on
    that topic: each may come a resend later (1 s with Fast DDS) on a loaded machine. A census
    of participants alone, and then one that took the participant's first reader for all of
    them, had ended the wait before the one subscriber was found. So each other participant
    must also be settled (:func:`settled`): its nodes named and each node's readers arriving.
    """

    def __init__(self, node: Node) -> None:
        self._node = node
        self._domain = node.context.get_domain_id()
        self._own: bytes | None = None

    def __call__(self) -> bool:
        """True once every participant on this host is found and settled (:func:`settled`)."""
        on_host = host_participants(self._domain)
        if on_host is None:
            return False
        participants = {gid[:_PREFIX] for gid in live_participant_gids(self._node)}
        if len(participants) < on_host:
            return False
        own = self._own_prefix()
        if own is None:
            return False
        node = self._node
        nodes = {(name, namespace) for name, namespace in node.get_node_names_and_namespaces()}
        return settled(participants - {own}, self._endpoints(), nodes - {_name(node)})

    def _own_prefix(self) -> bytes | None:
        """The GUID prefix of ``node``'s participant, from one of its publishers in the graph."""
        if self._own is None:
            node = self._node
            me = _name(node)
            for topic, _ in node.get_publisher_names_and_types_by_node(*me):
                for info in node.get_publishers_info_by_topic(topic):
                    if (info.node_name, info.node_namespace) == me:
                        self._own = bytes(info.endpoint_gid)[:_PREFIX]
                        return self._own
        return self._own

    def _endpoints(self) -> list[Endpoint]:
        """Every reader and writer in the graph."""
        node = self._node
        endpoints = []
        for topic, _ in node.get_topic_names_and_types(no_demangle=True):
            for reader, infos in (
                (True, node.get_subscriptions_info_by_topic(topic, no_mangle=True)),
                (False, node.get_publishers_info_by_topic(topic, no_mangle=True)),
            ):
                for info in infos:
                    named = info.node_name != _UNKNOWN_NODE
                    owner = (info.node_name, info.node_namespace) if named else None
                    endpoints.append(Endpoint(bytes(info.endpoint_gid), owner, reader=reader))
        return endpoints


@dataclass(frozen=True, slots=True)
class Endpoint:
    """A reader or writer in the graph: its gid, and its node (None while unnamed)."""

    gid: bytes
    node: tuple[str, str] | None
    reader: bool


def settled(others: Set[bytes], endpoints: Iterable[Endpoint], nodes: Set[tuple[str, str]]) -> bool:
    """Whether the participants ``others`` (GUID prefixes) have shown what they subscribe to.

    Each needs a reader in the graph and an endpoint named after one of its nodes (the message
    that names its nodes and their endpoints has arrived), and every node in ``nodes`` (the
    graph's, this participant's excepted) needs a reader of its own in the graph: a node
    whose name arrived before its readers, or a participant whose discovery writer and first
    reader arrived before the rest, is not settled. A node without any reader keeps the
    census at False, and the watch then ends at the discovery time.
    """
    with_reader: set[bytes] = set()
    named: set[bytes] = set()
    reading: set[tuple[str, str]] = set()
    for endpoint in endpoints:
        prefix = endpoint.gid[:_PREFIX]
        if endpoint.reader:
            with_reader.add(prefix)
        if endpoint.node is not None:
            named.add(prefix)
            if endpoint.reader:
                reading.add(endpoint.node)
    return others <= with_reader and others <= named and nodes <= reading


def _name(node: Node) -> tuple[str, str]:
    return (node.get_name(), node.get_namespace())


def all_discovered(node: Node, environ: Mapping[str, str]) -> Census | None:
    """A census of ``node``'s discovery, or None when one cannot be taken.

    None when discovery reaches beyond this host (``ROS_AUTOMATIC_DISCOVERY_RANGE`` other than
    LOCALHOST, or static peers): participants elsewhere cannot be counted. The census says
    False while the count cannot be trusted (:func:`host_participants`), a participant on this
    host is not in the graph yet (one that is no ROS participant never is), or one is not
    settled (:func:`settled`).
    """
    if not countable(environ):
        return None
    return Census(node)


def countable(environ: Mapping[str, str]) -> bool:
    """Whether the participants that discovery can find are all on this host (and can be
    counted there): discovery is limited to this host, without static peers."""
    return localhost_only(environ) and not environ.get("ROS_STATIC_PEERS", "").strip()


def heard_the_answers(node: Node, within_s: float = ANSWERS_WITHIN_S) -> bool:
    """Whether ``node``'s new participant finds every participant on this host within
    ``within_s`` (True also when they cannot be counted).

    Fast DDS 2.14 sends a new participant's first announcement before it listens
    (``RTPSParticipantImpl::enable``): the answers that arrive in between are dropped, and the
    participants that sent them are found at their next periodic announcement, up to 3 s later.
    About half of all new participants lose an answer so here; a participant that did is best
    replaced by a new one, which has the same chance again.
    """
    domain = node.context.get_domain_id()
    deadline = time.monotonic() + within_s
    while True:
        on_host = host_participants(domain)
        if on_host is None or discovered_participants(node) >= on_host:
            return True
        if time.monotonic() >= deadline:
            return False
        time.sleep(0.01)


def host_participants(domain_id: int) -> int | None:
    """The DDS participants of ``domain_id`` on this host, this process's included.

    None when the count cannot be trusted: the socket tables are not readable, or this
    process's own participant is not among them (a transport without UDP).
    """
    base = discovery_port(domain_id, 0)
    ports: set[int] = set()
    own: set[int] = set()
    mine = _own_socket_inodes()
    try:
        sockets = udp_sockets()
    except (OSError, ValueError, IndexError):
        return None
    for port, inode in sockets:
        offset = port - base
        if 0 <= offset < PARTICIPANT_IDS * _PARTICIPANT_GAIN and offset % _PARTICIPANT_GAIN == 0:
            ports.add(port)
            if inode in mine:
                own.add(port)
    return len(ports) if own else None


def discovery_port(domain_id: int, participant_id: int) -> int:
    """The metatraffic unicast port that participant ``participant_id`` of ``domain_id`` binds."""
    return (
        PORT_BASE
        + DOMAIN_GAIN * domain_id
        + _METATRAFFIC_UNICAST
        + _PARTICIPANT_GAIN * participant_id
    )


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
