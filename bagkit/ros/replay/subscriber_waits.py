"""Waiting for the player's subscribers: before the first message, until every subscription the
graph knows on a replayed topic has matched (no lost first message); after the last, until the
subscribers of reliable topics hold every message (none lost in flight)."""

from __future__ import annotations

import os
import time
from collections.abc import Callable, Sequence

from rclpy.duration import Duration
from rclpy.node import Node
from rclpy.qos import QoSCompatibility, ReliabilityPolicy, qos_check_compatible

from bagkit.playback.options import SubscriberWaits
from bagkit.playback.report import SubscriberWait
from bagkit.ros.errors import SubscriberTimeoutError
from bagkit.ros.participants import all_discovered
from bagkit.ros.replay.publishers import TopicOutput
from bagkit.selection.times import NS_PER_S
from bagkit.words import counted

# Without a census, the graph counts as settled when it has not changed for this long.
GRAPH_SETTLE_S = 0.2
# A publisher sees a subscription match before the subscription sees the publisher; the first
# message is only safe once both sides have matched, which we cannot observe from here.
MATCH_GRACE_S = 0.1
# While the census counts a participant on this host that is not in the graph yet, the watch
# goes on this long past the discovery time: on a loaded machine the participant's periodic
# announcement, due within it, came after it, and the first message was lost.
CENSUS_OVERTIME_S = 1.0


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
    ``CENSUS_OVERTIME_S`` later with a census) and until it has been unchanged for
    ``GRAPH_SETTLE_S``, or until ``all_discovered`` says that every participant has been found
    with its nodes and their readers; every compatible subscription seen by then must match,
    then ``MATCH_GRACE_S`` more. Topics in ``wait_for`` additionally need at least one
    subscription.

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
        settled = found_all or (now >= watch_end and now >= last_change + GRAPH_SETTLE_S)
        pending = [
            f"{out.name} ({count} of {counted(expected, 'subscription')} matched)"
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


def before_first_message(
    node: Node, outputs: Sequence[TopicOutput], waits: SubscriberWaits, node_created: float
) -> SubscriberWait:
    """:func:`wait_until_matched` as ``waits`` asks, for ``node`` created at ``node_created``.

    The graph is watched for ``discovery_time`` seconds after the node was created (Fast DDS
    announces participants every 3 s), or, with discovery on this host only, until every
    participant on this host has been found (at most ``CENSUS_OVERTIME_S`` longer while one is
    missing); topics in ``wait_for`` additionally need a subscription.

    Raises:
        SubscriberTimeoutError: not matched within ``wait_timeout`` seconds.
    """
    return wait_until_matched(
        node,
        outputs,
        wait_for=list(waits.topics),
        settled_at=node_created + waits.discovery_ns / NS_PER_S,
        timeout=waits.timeout_ns / NS_PER_S,
        all_discovered=all_discovered(node, os.environ),
    )


def after_last_message(outputs: Sequence[TopicOutput], waits: SubscriberWaits) -> list[str]:
    """:func:`wait_until_acknowledged` within ``waits``' ``ack_timeout``."""
    return wait_until_acknowledged(outputs, waits.ack_timeout_ns / NS_PER_S)
