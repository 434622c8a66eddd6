"""Wait until the ROS graph shows the subscriptions a replay needs before it starts."""

from __future__ import annotations

import time
from collections.abc import Callable, Mapping

import rclpy
from rclpy.context import Context

from bagkit.ros.errors import SubscriberTimeoutError

POLL_S = 0.1


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
