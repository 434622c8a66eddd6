"""Leaf values straight from CDR bytes equal those of the decoded message, for every type."""

from __future__ import annotations

import struct

import numpy as np
import pytest
from random_messages import JAZZY, flat_equal, random_message

from bagkit.decode import DecodeError, MessageTypes, flatten_message, leaf_fields
from bagkit.decode.direct import value_reader


def _no_fallback(_data: bytes | memoryview) -> list[object]:
    raise AssertionError("the direct reader handed a little-endian payload to the object path")


def _serializable_message(typename: str, rng: np.random.Generator) -> tuple[object, bytes]:
    """A random message and its CDR bytes; rosbags packs ``byte`` as int8, so random octets
    over 127 are drawn again."""
    for _ in range(50):
        msg = random_message(JAZZY, typename, rng)
        try:
            return msg, bytes(JAZZY.serialize_cdr(msg, typename))
        except struct.error:
            continue
    raise AssertionError(f"no serializable random {typename}")


def test_every_jazzy_type_reads_like_its_decoded_message() -> None:
    """Random values, sequence lengths and strings; all paths, then every other path."""
    rng = np.random.default_rng(21)
    checked = 0
    for typename in sorted(JAZZY.fielddefs):
        paths = [leaf.path for leaf in leaf_fields(JAZZY, typename)]
        readers = {
            selection: value_reader(JAZZY, typename, selection, _no_fallback)
            for selection in (tuple(paths), tuple(paths[::2]))
        }
        for _ in range(3):
            msg, payload = _serializable_message(typename, rng)
            flat = flatten_message(msg, JAZZY)
            for selection, read in readers.items():
                values = read(memoryview(payload))
                assert len(values) == len(selection)
                for path, value in zip(selection, values, strict=True):
                    assert flat_equal(value, flat[path]), (typename, path, value, flat[path])
            checked += 1
    assert checked > 300


def test_byte_is_unsigned_as_ros_defines_it() -> None:
    """rosbags reads ``byte`` as int8; ROS 2 (and bulk decoding) as an unsigned octet."""
    typename = "diagnostic_msgs/msg/DiagnosticStatus"
    msg = random_message(JAZZY, typename, np.random.default_rng(5))
    msg.level = -56  # type: ignore[attr-defined]
    payload = bytes(JAZZY.serialize_cdr(msg, typename))
    assert value_reader(JAZZY, typename, ["level"], _no_fallback)(payload) == [200]


def test_other_encapsulations_take_the_object_path() -> None:
    typename = "sensor_msgs/msg/Temperature"
    msg = random_message(JAZZY, typename, np.random.default_rng(3))
    big_endian = bytes(JAZZY.serialize_cdr(msg, typename, little_endian=False))
    handed_over: list[bytes] = []

    def fallback(data: bytes | memoryview) -> list[object]:
        handed_over.append(bytes(data))
        return ["from the object path"]

    read = value_reader(JAZZY, typename, ["temperature"], fallback)
    assert read(big_endian) == ["from the object path"] and handed_over == [big_endian]


def test_bytes_that_do_not_match_the_type_are_a_decode_error() -> None:
    typename = "sensor_msgs/msg/NavSatFix"
    msg = random_message(JAZZY, typename, np.random.default_rng(4))
    payload = bytes(JAZZY.serialize_cdr(msg, typename))
    read = value_reader(JAZZY, typename, ["latitude"], _no_fallback)
    assert read(payload) == [msg.latitude]  # type: ignore[attr-defined]
    with pytest.raises(
        DecodeError, match="NavSatFix message does not decode: it ends past the pay"
    ):
        read(payload[:-12])
    with pytest.raises(DecodeError, match="bytes after"):
        read(payload + bytes(16))


def test_an_unknown_path_is_a_key_error() -> None:
    with pytest.raises(KeyError, match="no leaf"):
        value_reader(JAZZY, "sensor_msgs/msg/Temperature", ["pressure"], _no_fallback)


@pytest.mark.parametrize(
    ("typename", "offset", "paths"),
    [
        ("sensor_msgs/msg/Temperature", 12, ["temperature"]),  # header.frame_id's length
        ("sensor_msgs/msg/LaserScan", 52, ["ranges[]"]),  # ranges' count
        ("diagnostic_msgs/msg/DiagnosticArray", 24, ["status[].level"]),  # status' count
    ],
)
@pytest.mark.parametrize("length", [2**31, 2**32 - 1])
def test_a_length_prefix_larger_than_the_payload_is_a_decode_error(
    typename: str, offset: int, paths: list[str], length: int
) -> None:
    msg, _ = _serializable_message(typename, np.random.default_rng(6))
    msg.header.frame_id = "base"  # type: ignore[attr-defined]
    data = bytearray(JAZZY.serialize_cdr(msg, typename))
    data[offset : offset + 4] = struct.pack("<I", length)
    read = value_reader(JAZZY, typename, paths, _no_fallback)
    with pytest.raises(DecodeError, match="length prefix says more than the payload holds"):
        read(bytes(data))


def test_a_string_running_past_the_end_is_a_decode_error() -> None:
    """The last field a string whose length leaves the payload: not read short, refused."""
    typename = "std_msgs/msg/String"
    read = value_reader(JAZZY, typename, ["data"], _no_fallback)
    assert read(b"\x00\x01\x00\x00\x03\x00\x00\x00ab\x00") == ["ab"]
    with pytest.raises(DecodeError, match="length prefix"):
        read(b"\x00\x01\x00\x00\x09\x00\x00\x00ab\x00")
    types = MessageTypes.from_definitions({typename: "string data\n"})
    with pytest.raises(DecodeError, match="does not decode"):
        types.deserialize(b"\x00\x01\x00\x00\x09\x00\x00\x00ab\x00", typename)


def test_a_payload_error_says_what_is_wrong_with_the_bytes() -> None:
    """What the message-by-message decoder says of a short payload and of a string that is not
    UTF-8, rather than its reader's exception (``error('unpack_from requires ...')``)."""
    types = MessageTypes.from_definitions({})
    decode = types.decoder("std_msgs/msg/String")
    payload = bytes(
        JAZZY.serialize_cdr(JAZZY.types["std_msgs/msg/String"](data="abc"), "std_msgs/msg/String")
    )
    assert decode(payload).data == "abc"  # type: ignore[attr-defined]
    with pytest.raises(
        DecodeError, match="String message does not decode: it ends past the payload"
    ):
        decode(payload[:6])
    with pytest.raises(DecodeError, match="a string is not UTF-8"):
        decode(payload.replace(b"abc", b"a\xffc"))
