"""The player's publishers: one per replayed topic and ``/clock``; matching, acknowledgement."""

from __future__ import annotations

import time
from collections.abc import Callable, Sequence
from dataclasses import dataclass

from rclpy.duration import Duration
from rclpy.exceptions import InvalidTopicNameException
from rclpy.node import Node
from rclpy.publisher import Publisher
from rclpy.qos import (
    QoSCompatibility,
    QoSProfile,
    ReliabilityPolicy,
    qos_check_compatible,
)
from rosgraph_msgs.msg import Clock

from bagkit.bag import TopicInfo
from bagkit.bag.clock import CLOCK_TOPIC, CLOCK_TYPE
from bagkit.playback.report import SubscriberWait
from bagkit.ros.errors import PlayerError, SubscriberTimeoutError
from bagkit.ros.qos import CLOCK_QOS

# The graph counts as settled when it has not changed for this long.
GRAPH_SETTLE_S = 0.2
# A publisher sees a subscription match before the subscription sees the publisher; the first
# message is only safe once both sides have matched, which we cannot observe from here.
MATCH_GRACE_S = 0.1
# While the census counts a participant on this host that is not in the graph yet, the watch
# goes on this long past the discovery time: on a loaded machine the participant's periodic
# announcement, due within it, came after it, and the first message was lost.
CENSUS_OVERTIME_S = 1.0
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


def wait_until_matched(
    node: Node,
    outputs: Sequence[TopicOutput],
    *,
    wait_for: Sequence[str],
    settled_at: float,
    timeout: float,
    all_discovered: Callable[[], bool] | None = None,
) -> SubscriberWait:
    """Block until the subscriptions the graph knows on ``outputs`` have matched.

    A subscription in another process shows up in the graph only when its participant's
    discovery announcement arrives, so the graph is watched until ``settled_at`` (monotonic;
    ``CENSUS_OVERTIME_S`` later with a census), or until ``all_discovered`` says that every
    participant has been found, and until it has been unchanged for ``GRAPH_SETTLE_S``; every
    compatible subscription seen by then must match, then ``MATCH_GRACE_S`` more. Topics in
    ``wait_for`` additionally need at least one subscription.

    Returns:
        How long it waited, and for what.

    Raises:
        SubscriberTimeoutError: not matched within ``timeout`` seconds.
    """
    required = sorted(set(wait_for))
    start = now = time.monotonic()
    deadline = now + timeout
    last_change = now
    last_graph: dict[str, int] = {}
    found_all = False
    # A census that still misses a participant at the discovery time waits a little longer.
    watch_end = settled_at if all_discovered is None else settled_at + CENSUS_OVERTIME_S
    while True:
        graph = {out.name: node.count_subscribers(out.name) for out in outputs}
        graph.update({topic: node.count_subscribers(topic) for topic in required})
        matched = [out.publisher.get_subscription_count() for out in outputs]
        now = time.monotonic()
        if graph != last_graph:
            last_graph = graph
            last_change = now
        if not found_all and now < watch_end and all_discovered is not None:
            found_all = all_discovered()
            if found_all:  # the last participant's endpoints may still be arriving
                last_change = now
        settled = now >= last_change + GRAPH_SETTLE_S and (found_all or now >= watch_end)
        pending = [
            f"{out.name} ({count} of {expected} subscriptions matched)"
            for out, count in zip(outputs, matched, strict=True)
            for expected in [_compatible_subscriptions(node, out)]
            if count < expected
        ]
        pending += [f"a subscriber on {topic}" for topic in required if not graph[topic]]
        if not pending and settled:
            break
        if now >= deadline:
            raise SubscriberTimeoutError(
                f"timed out after {timeout:g} s waiting for {', '.join(pending)}",
                "waits.before_start",
            )
        time.sleep(0.02)
    time.sleep(MATCH_GRACE_S)
    matched = [out.publisher.get_subscription_count() for out in outputs]
    return SubscriberWait(
        seconds=time.monotonic() - start,
        subscriptions=sum(matched),
        topics=sum(1 for count in matched if count),
        all_discovered=found_all,
    )


def wait_until_acknowledged(outputs: Sequence[TopicOutput], timeout: float) -> list[str]:
    """Wait until the subscribers of reliable topics have every message; return the others.

    A fast replay ends while messages are still in flight; destroying the publishers then
    would lose them. Waits at most ``timeout`` seconds in all.
    """
    deadline = time.monotonic() + timeout
    pending = []
    for output in outputs:
        publisher = output.publisher
        if publisher.qos_profile.reliability != ReliabilityPolicy.RELIABLE:
            continue
        remaining = max(deadline - time.monotonic(), 0.0)
        if not publisher.wait_for_all_acked(Duration(seconds=remaining)):
            pending.append(output.name)
    return pending


def _compatible_subscriptions(node: Node, output: TopicOutput) -> int:
    """Subscriptions on ``output``'s topic in the graph whose QoS can match the publisher's."""
    count = 0
    for endpoint in node.get_subscriptions_info_by_topic(output.name):
        compatibility, _ = qos_check_compatible(output.publisher.qos_profile, endpoint.qos_profile)
        if compatibility != QoSCompatibility.ERROR:
            count += 1
    return count


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
