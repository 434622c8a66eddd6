"""``fusion summary``: call the data logger's ``/logger/get_summary`` and return its answer."""

from __future__ import annotations

import time
from collections.abc import Iterator

import rclpy
from rclpy.context import Context
from rclpy.executors import SingleThreadedExecutor
from rclpy.node import Node
from std_srvs.srv import Trigger

from fusion import topics
from fusion.errors import FusionError


class SummaryUnavailableError(FusionError):
    """The data logger did not answer (not running, or too slow)."""

    exit_code = 1


def request_summary(timeout_s: float = 10.0) -> Trigger.Response:
    """Call ``/logger/get_summary`` once, from a node of its own.

    Raises:
        SummaryUnavailableError: no service within ``timeout_s``, or no answer within it.
    """
    context = Context()
    rclpy.init(context=context)
    node = Node("fusion_summary_client", context=context)
    executor = SingleThreadedExecutor(context=context)
    executor.add_node(node)
    try:
        client = node.create_client(Trigger, topics.LOGGER_GET_SUMMARY)
        if not client.wait_for_service(timeout_sec=timeout_s):
            raise SummaryUnavailableError(
                f"{topics.LOGGER_GET_SUMMARY} is not available (is the data logger running?)"
            )
        future = client.call_async(Trigger.Request())
        executor.spin_until_future_complete(future, timeout_sec=timeout_s)
        response = future.result()
        if response is None:
            raise SummaryUnavailableError(f"{topics.LOGGER_GET_SUMMARY} did not answer")
        return response
    finally:
        executor.shutdown()
        node.destroy_node()
        context.try_shutdown()


def request_summaries(period_s: float, timeout_s: float) -> Iterator[str]:
    """Ask every ``period_s`` seconds until Ctrl-C; yield each answer (or why there is none).

    What ``fusion summary --every`` prints, and what a golden recording of fusion calls
    (fixtures/nominal/spec.yaml, ``record_launch``).
    """
    try:
        while True:
            started = time.monotonic()
            try:
                yield request_summary(timeout_s).message
            except SummaryUnavailableError as exc:
                yield f"no answer: {exc}"
            time.sleep(max(0.0, period_s - (time.monotonic() - started)))
    except KeyboardInterrupt:
        return
