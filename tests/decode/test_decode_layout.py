"""CDR layouts; PaddingZeroer: one encoding per message, whatever a writer left in the padding."""

from __future__ import annotations

import struct
from typing import Any

import numpy as np
import pytest
from rclpy.serialization import serialize_message
from rosbags.typesys import Stores, get_typestore

from bagkit.decode import DecodeError
from bagkit.decode.layout import CdrLayout, PaddingZeroer
from bagkit.ros.message_classes import import_message_type

JAZZY = get_typestore(Stores.ROS2_JAZZY)


def _padding_positions(data: bytes, typename: str) -> list[int]:
    """Bytes whose value does not change the decoded message, found by flipping each one."""
    reference = JAZZY.deserialize_cdr(data, typename)
    positions = []
    for index in range(4, len(data)):
        flipped = bytearray(data)
        flipped[index] ^= 0xA5
        try:
            same = _equal(JAZZY.deserialize_cdr(bytes(flipped), typename), reference)
        except Exception:  # a flipped length prefix may not decode at all
            same = False
        if same:
            positions.append(index)
    return positions


def _equal(a: Any, b: Any) -> bool:
    if isinstance(a, np.ndarray):
        return bool(np.array_equal(a, b))
    if hasattr(a, "__dataclass_fields__"):
        return all(_equal(getattr(a, f), getattr(b, f)) for f in a.__dataclass_fields__)
    return bool(a == b)


def _messages() -> list[tuple[str, Any]]:
    """rclpy messages whose strings and sequences shift the alignment of what follows."""
    odometry_class = import_message_type("nav_msgs/msg/Odometry")
    scan_class = import_message_type("sensor_msgs/msg/LaserScan")
    fix_class = import_message_type("sensor_msgs/msg/NavSatFix")
    messages: list[tuple[str, Any]] = []
    for length in range(8):
        odometry = odometry_class()
        odometry.header.frame_id = "m" * length
        odometry.child_frame_id = "b" * (7 - length)
        odometry.pose.pose.position.z = 1.5 + length
        odometry.twist.covariance[35] = -2.0
        messages.append(("nav_msgs/msg/Odometry", odometry))
        scan = scan_class()
        scan.header.frame_id = "l" * length
        scan.ranges = [float(i) for i in range(length)]
        scan.intensities = [0.5] * (length % 3)
        scan.range_max = 30.0
        messages.append(("sensor_msgs/msg/LaserScan", scan))
    fix = fix_class()
    fix.status.status = -1
    fix.altitude = 120.25
    messages.append(("sensor_msgs/msg/NavSatFix", fix))
    return messages


@pytest.mark.parametrize(("typename", "message"), _messages())
def test_garbage_in_the_padding_is_zeroed(typename: str, message: Any) -> None:
    data = serialize_message(message)
    layout = CdrLayout.of(JAZZY, typename)
    assert layout is not None
    zero = PaddingZeroer(layout)
    padding = _padding_positions(data, typename)
    dirty = bytearray(data)
    for index in padding:
        dirty[index] = 0xEE

    canonical = zero(bytes(dirty))

    assert canonical == zero(data)
    assert all(canonical[i] == 0 for i in padding)
    # Only the padding changed: the message is the same, and so is every other byte.
    assert _equal(JAZZY.deserialize_cdr(canonical, typename), JAZZY.deserialize_cdr(data, typename))
    assert [i for i in range(len(data)) if canonical[i] != dirty[i]] == [
        i for i in padding if dirty[i] != 0
    ]
    # rosbags writes padding as zeros: the same bytes (up to the trailing padding it omits).
    reencoded = bytes(JAZZY.serialize_cdr(JAZZY.deserialize_cdr(data, typename), typename))
    assert canonical[: len(reencoded)] == reencoded
    assert not any(canonical[len(reencoded) :])


def test_types_with_sequences_of_messages_have_no_fixed_layout() -> None:
    assert CdrLayout.of(JAZZY, "diagnostic_msgs/msg/DiagnosticArray") is None


@pytest.mark.parametrize("length", [9, 2**31, 2**32 - 1])
def test_a_length_prefix_larger_than_the_payload_is_a_decode_error(length: int) -> None:
    """Nothing is sized from the prefix (a mask of 2**31 bytes would take 2 GiB)."""
    scan = import_message_type("sensor_msgs/msg/LaserScan")()
    scan.header.frame_id = "lidar"
    data = bytearray(serialize_message(scan))
    layout = CdrLayout.of(JAZZY, "sensor_msgs/msg/LaserScan")
    assert layout is not None
    data[12:16] = struct.pack("<I", length)  # header.frame_id's length
    with pytest.raises(DecodeError, match="length prefix"):
        PaddingZeroer(layout)(bytes(data))
    with pytest.raises(DecodeError, match="length prefix"):
        PaddingZeroer(layout)(bytes(data[:14]))


def test_lockstep_keeps_wide_string_payloads_as_written() -> None:
    """No CDR writer knows wstring: lockstep keeps such outputs' bytes instead of failing."""
    from bagkit.regression.lockstep import _canonicalizer

    canonical = _canonicalizer("my_msgs/msg/Wide", "wstring name\nwstring[2] pair\nint32 x\n")
    payload = bytes(range(40))
    assert canonical(payload) == payload
