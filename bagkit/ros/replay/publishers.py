"""The player's publishers: one per replayed topic and ``/clock``, and the other nodes that
publish on its topics (its waits for their subscribers: :mod:`.subscriber_waits`)."""

from __future__ import annotations

import time
from collections.abc import Callable, Sequence
from dataclasses import dataclass

from rclpy.exceptions import InvalidTopicNameException
from rclpy.node import Node
from rclpy.publisher import Publisher
from rclpy.qos import (
    QoSProfile,
)
from rosgraph_msgs.msg import Clock

from bagkit.bag import TopicInfo
from bagkit.bag.clock import CLOCK_TOPIC, CLOCK_TYPE
from bagkit.ros.errors import PlayerError
from bagkit.ros.qos import CLOCK_QOS

# How long other publishers' node names are awaited once their endpoints are in the graph.
NODE_NAME_WAIT_S = 1.0
# The name rmw gives an endpoint whose node's name has not arrived, and how we print it.
_RMW_UNKNOWN_NAME = "_NODE_NAME_UNKNOWN_"
UNKNOWN_NODE = "a node whose name has not arrived"


@dataclass(slots=True)
class TopicOutput:
    """A replayed topic's publisher and how many messages went out on it."""

    info: TopicInfo
    publisher: Publisher
    publish: Callable[[bytes], None]
    """The publisher's raw publish, without ``Publisher.publish``'s per-call checks."""
    count: int = 0

    @property
    def name(self) -> str:
        """The name it is published under (after remapping)."""
        return str(self.publisher.topic_name)


def create_output(
    node: Node, info: TopicInfo, message_class: object, name: str, qos: QoSProfile
) -> TopicOutput:
    """A publisher of ``info``'s messages under ``name``.

    Raises:
        PlayerError: ``name`` is not a valid topic name.
    """
    try:
        publisher = node.create_publisher(message_class, name, qos)
    except InvalidTopicNameException as exc:
        # rclpy's message goes on with the name and a caret under the bad character.
        reason = str(exc).splitlines()[0].rstrip(":")
        raise PlayerError(f"cannot publish {info.name} as {name!r}: {reason}") from None
    return TopicOutput(info, publisher, publisher.handle.publish_raw)


def create_clock_output(node: Node) -> TopicOutput:
    """The ``/clock`` publisher, with the QoS sim-time nodes subscribe with."""
    publisher = node.create_publisher(Clock, CLOCK_TOPIC, CLOCK_QOS)
    return TopicOutput(TopicInfo(CLOCK_TOPIC, CLOCK_TYPE), publisher, publisher.handle.publish_raw)


def other_publishers(node: Node, outputs: Sequence[TopicOutput]) -> dict[str, list[str]]:
    """Published topic -> the other nodes publishing it (replaying it too would double it).

    A publisher's endpoint can be in the graph before its node's name is (the names travel on
    their own topic): the names are awaited for up to ``NODE_NAME_WAIT_S``.
    """
    deadline = time.monotonic() + NODE_NAME_WAIT_S
    while True:
        found = _other_publishers_now(node, outputs)
        named = all(UNKNOWN_NODE not in nodes for nodes in found.values())
        if named or time.monotonic() >= deadline:
            return found
        time.sleep(0.02)


def _other_publishers_now(node: Node, outputs: Sequence[TopicOutput]) -> dict[str, list[str]]:
    own = (node.get_name(), node.get_namespace())
    found = {}
    for output in outputs:
        others = sorted(
            {
                _node_path(p.node_namespace, p.node_name)
                for p in node.get_publishers_info_by_topic(output.name)
                if (p.node_name, p.node_namespace) != own
            }
        )
        if others:
            found[output.name] = others
    return found


def _node_path(namespace: str, name: str) -> str:
    if name == _RMW_UNKNOWN_NAME:
        return UNKNOWN_NODE
    return f"{namespace.rstrip('/')}/{name}"
