"""Bulk decoding: groups of one layout read with numpy, as columns per leaf, equal rosbags';
what does not fit (other encapsulations, impossible lengths, spans outside the buffer) left over."""

from __future__ import annotations

import struct
import zlib

import numpy as np
import pytest
from random_messages import JAZZY, random_message, same

from bagkit.decode import flatten_message, leaf_fields
from bagkit.decode.bulk import MAX_GROUPS, decode_bulk, read_at
from bagkit.decode.layout import CdrLayout

BULK_TYPES = [
    "sensor_msgs/msg/Imu",
    "sensor_msgs/msg/NavSatFix",
    "sensor_msgs/msg/LaserScan",
    "sensor_msgs/msg/Temperature",
    "sensor_msgs/msg/FluidPressure",
    "nav_msgs/msg/Odometry",
    "geometry_msgs/msg/PoseWithCovarianceStamped",
    "std_msgs/msg/Bool",
    "sensor_msgs/msg/JointState",  # string[] name: not a fixed layout
]


@pytest.mark.parametrize("typename", BULK_TYPES)
def test_bulk_decoding_equals_rosbags(typename: str) -> None:
    # A seed of the name's own (hash() of a str changes with each process): with some seeds a
    # type of three sequences draws more layouts than MAX_GROUPS, whose rest is left over.
    rng = np.random.default_rng(zlib.crc32(typename.encode()))
    layout = CdrLayout.of(JAZZY, typename)
    if typename == "sensor_msgs/msg/JointState":
        assert layout is None
        return
    assert layout is not None
    messages = [random_message(JAZZY, typename, rng) for _ in range(300)]
    payloads = [bytes(JAZZY.serialize_cdr(m, typename)) for m in messages]
    # Payloads at unaligned, uneven offsets in one buffer, as messages sit in an MCAP chunk.
    buffer = bytearray()
    starts = []
    for payload in payloads:
        buffer += bytes(int(rng.integers(0, 40)))
        starts.append(len(buffer))
        buffer += payload
    groups, leftover = decode_bulk(
        np.frombuffer(bytes(buffer), np.uint8),
        np.array(starts, dtype=np.int64),
        np.array([len(p) for p in payloads], dtype=np.int64),
        layout,
    )
    assert len(leftover) == 0
    assert sorted(i for g in groups for i in g.indexes.tolist()) == list(range(len(messages)))
    paths = [leaf.path for leaf in leaf_fields(JAZZY, typename)]
    for group in groups:
        columns = group.columns(paths)
        for row, index in enumerate(group.indexes.tolist()):
            flat = flatten_message(messages[index], JAZZY)
            assert columns.keys() <= flat.keys()
            for path, value in flat.items():
                if isinstance(value, str):  # S bytes; an empty string has no column
                    got = columns[path][row].decode() if path in columns else ""
                    assert got == value, (typename, path)
                else:
                    assert same(columns[path][row], value), (typename, path)


def test_bulk_leaves_other_encapsulations_to_the_general_decoder() -> None:
    typename = "sensor_msgs/msg/Temperature"
    layout = CdrLayout.of(JAZZY, typename)
    assert layout is not None
    payload = bytes(
        JAZZY.serialize_cdr(random_message(JAZZY, typename, np.random.default_rng(1)), typename)
    )
    big_endian = bytes(
        JAZZY.serialize_cdr(
            random_message(JAZZY, typename, np.random.default_rng(2)), typename, little_endian=False
        )
    )
    buffer = np.frombuffer(payload + big_endian + payload[:10], np.uint8)
    starts = np.array([0, len(payload), len(payload) + len(big_endian)])
    lengths = np.array([len(payload), len(big_endian), 10])
    groups, leftover = decode_bulk(buffer, starts, lengths, layout)
    assert [g.indexes.tolist() for g in groups] == [[0]]
    assert leftover.tolist() == [1, 2]


def test_bulk_decoding_of_evenly_spaced_messages_reads_in_place() -> None:
    """One topic alone in a chunk, same frame_id: a strided view, no copy, same values."""
    typename = "sensor_msgs/msg/FluidPressure"
    layout = CdrLayout.of(JAZZY, typename)
    assert layout is not None
    rng = np.random.default_rng(8)
    messages = []
    for _ in range(50):
        msg = random_message(JAZZY, typename, rng)
        msg.header.frame_id = "baro"  # type: ignore[attr-defined]
        messages.append(msg)
    payloads = [bytes(JAZZY.serialize_cdr(m, typename)) for m in messages]
    record = len(payloads[0]) + 31  # as in a chunk: a fixed-size record header before each
    buffer = np.frombuffer(b"".join(bytes(31) + p for p in payloads), np.uint8)
    starts = np.arange(len(payloads), dtype=np.int64) * record + 31
    lengths = np.full(len(payloads), len(payloads[0]), dtype=np.int64)
    (group,), leftover = decode_bulk(buffer, starts, lengths, layout)
    assert len(leftover) == 0 and np.shares_memory(group.values, buffer)
    pressure = str(next(i for i, s in enumerate(layout.slots) if s.path == "fluid_pressure"))
    expected = [m.fluid_pressure for m in messages]  # type: ignore[attr-defined]
    assert same(group.values[pressure], expected)


def test_too_many_layouts_go_to_the_general_decoder() -> None:
    """A frame_id of a different length in every message: bulk decoding would not pay."""
    typename = "sensor_msgs/msg/Temperature"
    layout = CdrLayout.of(JAZZY, typename)
    assert layout is not None
    rng = np.random.default_rng(9)
    payloads = []
    for i in range(MAX_GROUPS + 20):
        msg = random_message(JAZZY, typename, rng)
        msg.header.frame_id = "f" * i  # type: ignore[attr-defined]
        payloads.append(bytes(JAZZY.serialize_cdr(msg, typename)))
    starts = np.cumsum([0] + [len(p) for p in payloads[:-1]]).astype(np.int64)
    buffer = np.frombuffer(b"".join(payloads), np.uint8)
    groups, leftover = decode_bulk(
        buffer, starts, np.array([len(p) for p in payloads], dtype=np.int64), layout
    )
    assert groups == [] and leftover.tolist() == list(range(len(payloads)))


def _scan_payload(count: int, ranges: list[float]) -> bytes:
    """A LaserScan payload (frame_id "ab") whose ranges prefix says ``count``."""
    head = b"\x00\x01\x00\x00" + struct.pack("<iII", 1, 2, 3) + b"ab\x00\x00"
    fields = struct.pack("<7f", *range(7))
    body = struct.pack("<I", count) + struct.pack(f"<{len(ranges)}f", *ranges)
    return head + fields + body + struct.pack("<I", 0)


@pytest.mark.parametrize("count", [3, 2**31, 2**32 - 1])
def test_a_length_prefix_larger_than_the_payload_is_left_over(count: int) -> None:
    """The prefix is checked against the bytes left before a layout (a dtype) is built."""
    layout = CdrLayout.of(JAZZY, "sensor_msgs/msg/LaserScan")
    assert layout is not None
    good = _scan_payload(2, [1.0, 2.0])
    bad = _scan_payload(count, [1.0, 2.0])
    assert len(good) == len(bad)
    if count == 3:  # one float more than the payload holds: no layout of that size fits
        bad = bad[:-4]
    buffer = np.frombuffer(good + bad + good, np.uint8)
    starts = np.array([0, len(good), len(good) + len(bad)], dtype=np.int64)
    lengths = np.array([len(good), len(bad), len(good)], dtype=np.int64)
    (group,), leftover = decode_bulk(buffer, starts, lengths, layout)
    assert group.indexes.tolist() == [0, 2] and leftover.tolist() == [1]
    assert group.columns(["ranges[]"])["ranges[]"].tolist() == [[1.0, 2.0], [1.0, 2.0]]


def test_a_string_length_of_2_31_is_left_over() -> None:
    layout = CdrLayout.of(JAZZY, "sensor_msgs/msg/Temperature")
    assert layout is not None
    msg = random_message(JAZZY, "sensor_msgs/msg/Temperature", np.random.default_rng(5))
    good = bytes(JAZZY.serialize_cdr(msg, "sensor_msgs/msg/Temperature"))
    bad = bytearray(good)
    bad[12:16] = struct.pack("<I", 2**31)  # header.frame_id's length
    buffer = np.frombuffer(good + bytes(bad), np.uint8)
    groups, leftover = decode_bulk(
        buffer, np.array([0, len(good)]), np.array([len(good), len(good)]), layout
    )
    assert [g.indexes.tolist() for g in groups] == [[0]] and leftover.tolist() == [1]


def test_spans_outside_the_buffer_are_left_over() -> None:
    """Offsets past the end or negative, lengths past the end: never an IndexError."""
    layout = CdrLayout.of(JAZZY, "std_msgs/msg/Bool")
    assert layout is not None
    payload = b"\x00\x01\x00\x00\x01"
    buffer = np.frombuffer(payload * 2, np.uint8)
    starts = np.array([0, 5, 8, 2**40, -3, 5], dtype=np.int64)
    lengths = np.array([5, 5, 5, 5, 5, 2**62], dtype=np.int64)
    (group,), leftover = decode_bulk(buffer, starts, lengths, layout)
    assert group.indexes.tolist() == [0, 1] and leftover.tolist() == [2, 3, 4, 5]
    assert group.columns(["data"])["data"].tolist() == [1, 1]


@pytest.mark.parametrize(("dtype", "code"), [("<u2", "<H"), ("<u4", "<I"), ("<u8", "<Q")])
def test_numbers_read_at_any_byte(dtype: str, code: str) -> None:
    """Unaligned positions, the last number that fits, a buffer that starts inside another."""
    data = bytes(range(7, 250)) * 3
    buf = np.frombuffer(data, np.uint8)[5:]
    size = struct.calcsize(code)
    positions = np.array([0, 1, 3, 7, 100, len(buf) - size], np.int64)
    expected = [struct.unpack_from(code, data, 5 + p)[0] for p in positions.tolist()]
    assert read_at(buf, positions, dtype).tolist() == expected
    with pytest.raises(IndexError):
        read_at(buf, np.array([len(buf) - size + 1]), dtype)
    assert read_at(buf[: size - 1], np.array([], np.int64), dtype).tolist() == []


@pytest.mark.parametrize(("dtype", "code"), [("<u2", "<H"), ("<u4", "<I"), ("<u8", "<Q")])
def test_numbers_read_at_evenly_spaced_positions(dtype: str, code: str) -> None:
    """Evenly spaced positions (one strided copy) read what any positions read, up to the last
    number that fits; a run that reaches past the buffer or starts before it is refused or
    wraps as numpy's indexing does, and the numbers read stay when the buffer changes."""
    data = bytearray(bytes(range(3, 251)) * 4)
    buf = np.frombuffer(data, np.uint8)[5:]
    size = struct.calcsize(code)
    step = 37
    positions = np.arange(3, len(buf) - size + 1, step, dtype=np.int64)
    last = np.array([len(buf) - size - 2 * step, len(buf) - size - step, len(buf) - size])
    for wanted in (positions, last):
        expected = [struct.unpack_from(code, data, 5 + p)[0] for p in wanted.tolist()]
        read = read_at(buf, wanted, dtype)
        assert read.tolist() == expected
        data[5 + int(wanted[0])] ^= 0xFF
        assert read.tolist() == expected  # a copy, not a view of the buffer
        data[5 + int(wanted[0])] ^= 0xFF
    with pytest.raises(IndexError):
        read_at(buf, last + 1, dtype)
    behind = np.array([-3, -3 + step, -3 + 2 * step], np.int64)
    assert read_at(buf, behind, dtype).tolist() == [
        struct.unpack_from(code, data, 5 + (p % (len(buf) - size + 1)))[0] for p in behind.tolist()
    ]
