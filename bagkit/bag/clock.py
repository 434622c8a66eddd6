"""``/clock``: the one place that encodes and decodes ``rosgraph_msgs/msg/Clock`` (no rclpy).

The recorder reads the clock (``--use-sim-time``) and the player publishes it (``--clock``);
both handle the serialized message directly, an 8-byte CDR body after the encapsulation header.
"""

from __future__ import annotations

import struct

CLOCK_TOPIC = "/clock"
CLOCK_TYPE = "rosgraph_msgs/msg/Clock"

_CDR_LE_HEADER = b"\x00\x01\x00\x00"
_HEADER_SIZE = len(_CDR_LE_HEADER)
_TIME_LE = struct.Struct("<iI")
_TIME_BE = struct.Struct(">iI")


def clock_message(bag_ns: int) -> bytes:
    """Serialized ``rosgraph_msgs/msg/Clock`` (CDR, little endian) holding ``bag_ns``."""
    sec, nanosec = divmod(bag_ns, 1_000_000_000)
    return _CDR_LE_HEADER + _TIME_LE.pack(sec, nanosec)


def clock_ns(data: bytes) -> int:
    """Serialized ``rosgraph_msgs/msg/Clock`` (either byte order) -> ns.

    Raises:
        ValueError: ``data`` is too short to hold a clock.
    """
    if len(data) < _HEADER_SIZE + _TIME_LE.size:
        raise ValueError(f"a Clock message holds 12 bytes, got {len(data)}")
    # Encapsulation kind 0x0001 is little endian (CDR_LE), 0x0000 big endian.
    layout = _TIME_LE if data[1] & 1 else _TIME_BE
    sec, nanosec = layout.unpack_from(data, _HEADER_SIZE)
    return sec * 1_000_000_000 + nanosec
