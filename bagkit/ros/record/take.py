"""Take serialized messages from a subscription in batches, as columns.

rclpy's ``take_message(raw=True)`` builds a tuple and a dict of the message info for each
message; :func:`take_serialized` takes up to a count or byte budget in one call, through the
``_take`` extension, for less than half of that per message (benchmarks/README.md,
"Measurements behind the code"), and returns what :meth:`bagkit.bag.BagWriter.write_batch`
takes.
"""

from __future__ import annotations

import ctypes
from functools import cache

from rclpy.subscription import Subscription

from bagkit.recording.handoff import TakenMessages
from bagkit.ros.record import _take


@cache
def _rcl_take_serialized_message() -> int:
    """Address of ``rcl_take_serialized_message`` in the librcl that rclpy has loaded."""
    # The ROS wheels' start-up hook puts their lib directory on LD_LIBRARY_PATH, so this finds
    # the same file rclpy linked against: the dynamic loader returns the loaded copy.
    address = ctypes.cast(ctypes.CDLL("librcl.so").rcl_take_serialized_message, ctypes.c_void_p)
    assert address.value is not None
    return address.value


def take_serialized(subscription: Subscription, *, max_count: int, max_bytes: int) -> TakenMessages:
    """Take what ``subscription`` holds, up to ``max_count`` messages or ``max_bytes``.

    The message that crosses ``max_bytes`` is still taken. An empty result means nothing
    was waiting.

    Raises:
        RuntimeError: the middleware failed (not: nothing to take).
    """
    with subscription.handle:  # rclpy must not destroy the subscription during the call
        payloads, received, sources, sequences, nbytes = _take.take_serialized(
            _rcl_take_serialized_message(), subscription.handle.pointer, max_count, max_bytes
        )
    return TakenMessages(payloads, received, sources, sequences, nbytes)
