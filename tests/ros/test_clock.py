"""``/clock`` encoding and decoding against rclpy's own serialization (no middleware)."""

from __future__ import annotations

import pytest
from rclpy.serialization import serialize_message
from rosgraph_msgs.msg import Clock

from bagkit.bag.clock import clock_message, clock_ns


@pytest.mark.parametrize("stamp_ns", [0, 1, 1_700_000_000_123_456_789, 2**31 * 10**9 - 1])
def test_clock_round_trip_matches_rclpy(stamp_ns: int) -> None:
    expected = Clock()
    expected.clock.sec, expected.clock.nanosec = divmod(stamp_ns, 1_000_000_000)
    assert clock_message(stamp_ns) == serialize_message(expected)
    assert clock_ns(serialize_message(expected)) == stamp_ns


def test_big_endian_clock_and_short_data() -> None:
    big_endian = b"\x00\x00\x00\x00" + (7).to_bytes(4, "big") + (9).to_bytes(4, "big")
    assert clock_ns(big_endian) == 7_000_000_009
    with pytest.raises(ValueError, match="12 bytes"):
        clock_ns(b"\x00\x01\x00\x00\x01")
