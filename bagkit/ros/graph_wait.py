"""Before a replay starts: wait for the subscriptions it needs, and set the nodes' clock."""

from __future__ import annotations

import time
from collections.abc import Callable, Mapping

import rclpy
from rclpy.context import Context
from rosgraph_msgs.msg import Clock

from bagkit.bag.clock import CLOCK_TOPIC
from bagkit.ros.errors import SubscriberTimeoutError
from bagkit.ros.qos import CLOCK_QOS
from bagkit.words import counted

POLL_S = 0.1
CLOCK_PERIOD_S = 0.02


def wait_for_subscriptions(
    counts: Mapping[str, int], *, timeout: float, alive: Callable[[], bool]
) -> None:
    """Wait until each topic has at least its count of subscriptions in the ROS graph.

    Args:
        counts: topic -> the number of subscriptions to wait for.
        timeout: seconds before giving up.
        alive: called while waiting; returning False stops the wait (a process died).

    Raises:
        SubscriberTimeoutError: ``timeout`` passed (the message names the topics short of
            their count).
        ChildProcessError: ``alive()`` returned False.
    """
    context = Context()
    rclpy.init(context=context)
    try:
        node = rclpy.create_node("bagkit_graph_wait", context=context)
        deadline = time.monotonic() + timeout
        while True:
            short = {t: n for t, n in counts.items() if node.count_subscribers(t) < n}
            if not short:
                return
            if not alive():
                raise ChildProcessError("a process exited while waiting for subscriptions")
            if time.monotonic() > deadline:
                named = ", ".join(
                    f"{t} ({node.count_subscribers(t)} of {n})" for t, n in short.items()
                )
                raise SubscriberTimeoutError(f"no subscription after {timeout:.0f} s on {named}")
            time.sleep(POLL_S)
    finally:
        rclpy.shutdown(context=context)


def hold_clock(time_ns: int, *, subscriptions: int, seconds: float, timeout: float) -> None:
    """Publish ``/clock`` = ``time_ns`` until ``subscriptions`` have matched, then ``seconds``
    more (best effort: repeated, so that a lost sample does not matter).

    A replay publishes its first clock and its first message at once, on two topics whose
    relative order DDS does not keep: a node could see its first input at time 0. With the
    clock already at the bag's start, every input arrives on the time lockstep gives it.

    Raises:
        SubscriberTimeoutError: fewer than ``subscriptions`` matched within ``timeout``.
    """
    context = Context()
    rclpy.init(context=context)
    try:
        node = rclpy.create_node("bagkit_clock_hold", context=context)
        publisher = node.create_publisher(Clock, CLOCK_TOPIC, CLOCK_QOS)
        msg = Clock()
        msg.clock.sec, msg.clock.nanosec = divmod(time_ns, 1_000_000_000)
        deadline = time.monotonic() + timeout
        while publisher.get_subscription_count() < subscriptions:
            if time.monotonic() > deadline:
                raise SubscriberTimeoutError(
                    f"/clock did not match {counted(subscriptions, 'subscription')}"
                )
            publisher.publish(msg)
            time.sleep(CLOCK_PERIOD_S)
        until = time.monotonic() + seconds
        while time.monotonic() < until:
            publisher.publish(msg)
            time.sleep(CLOCK_PERIOD_S)
    finally:
        rclpy.shutdown(context=context)
