"""Decoding from stored definitions: typestore building, flattening, CDR layouts in bulk."""

from __future__ import annotations

from pathlib import Path
from typing import Any

import numpy as np
import pytest
from reference_flatten import reference_flatten
from rosbags.interfaces import Nodetype
from rosbags.typesys import Stores, get_typestore
from rosbags.typesys.store import Typestore

from bagkit.bag import BagReader, message_definition
from bagkit.decode import MessageTypes, SchemaError, field_getter, flatten_message, leaf_fields
from bagkit.decode.layout import CdrLayout
from bagkit.stats.bulk import MAX_GROUPS, decode_bulk

JAZZY = get_typestore(Stores.ROS2_JAZZY)
_NUMPY = {
    "bool": np.bool_,
    "byte": np.uint8,
    "char": np.uint8,
    "int8": np.int8,
    "uint8": np.uint8,
    "int16": np.int16,
    "uint16": np.uint16,
    "int32": np.int32,
    "uint32": np.uint32,
    "int64": np.int64,
    "uint64": np.uint64,
    "float32": np.float32,
    "float64": np.float64,
}


def _random_primitives(rng: np.random.Generator, base: str, n: int) -> np.ndarray:
    dtype = np.dtype(_NUMPY[base])
    if dtype.kind == "b":
        return rng.integers(0, 2, n).astype(bool)
    if dtype.kind == "f":
        values = rng.normal(0, 1e3, n).astype(dtype)
        values[rng.random(n) < 0.1] = np.nan
        return values
    info = np.iinfo(dtype)
    return rng.integers(info.min, info.max, n, dtype=dtype, endpoint=True)


def _random_string(rng: np.random.Generator) -> str:
    return "".join(chr(c) for c in rng.integers(97, 123, int(rng.integers(0, 13))))


def _random_value(ts: Typestore, desc: Any, rng: np.random.Generator) -> Any:
    kind, rest = desc
    if kind == Nodetype.BASE:
        if rest[0] == "string":
            return _random_string(rng)
        value = _random_primitives(rng, rest[0], 1)[0]
        return bool(value) if rest[0] == "bool" else value.item()
    if kind == Nodetype.NAME:
        return random_message(ts, rest, rng)
    sub, bound = rest
    n = bound if kind == Nodetype.ARRAY else int(rng.integers(0, (bound or 6) + 1))
    if sub[0] == Nodetype.BASE and sub[1][0] != "string":
        return _random_primitives(rng, sub[1][0], n)
    return [_random_value(ts, sub, rng) for _ in range(n)]


def random_message(ts: Typestore, typename: str, rng: np.random.Generator) -> object:
    """A message of ``typename`` with random values, strings and sequence lengths."""
    fields = {name: _random_value(ts, desc, rng) for name, desc in ts.fielddefs[typename][1]}
    return ts.types[typename](**fields)


def _same(a: Any, b: Any) -> bool:
    return bool(
        np.array_equal(np.asarray(a, dtype=float), np.asarray(b, dtype=float), equal_nan=True)
    )


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
    rng = np.random.default_rng(abs(hash(typename)) % 2**32)
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
    for group in groups:
        for row, index in zip(group.values, group.indexes.tolist(), strict=True):
            flat = flatten_message(messages[index], JAZZY, numeric_only=True)
            decoded: dict[str, Any] = {}
            for slot_index in group.layout.slot_indexes:
                slot = layout.slots[slot_index]
                value = row[str(slot_index)]
                if slot.array:
                    decoded.update({f"{slot.path}[{i}]": v for i, v in enumerate(value)})
                else:
                    decoded[slot.path] = value
            assert decoded.keys() == flat.keys()
            for path, value in flat.items():
                assert _same(decoded[path], value), (typename, path)


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


def test_flatten_paths_and_values() -> None:
    ts = JAZZY
    status = ts.types["diagnostic_msgs/msg/DiagnosticStatus"]
    key_value = ts.types["diagnostic_msgs/msg/KeyValue"]
    msg = ts.types["diagnostic_msgs/msg/DiagnosticArray"](
        header=ts.types["std_msgs/msg/Header"](
            stamp=ts.types["builtin_interfaces/msg/Time"](sec=3, nanosec=4), frame_id="base"
        ),
        status=[
            status(level=2, name="a", message="m", hardware_id="h", values=[key_value("k", "v")]),
            status(level=0, name="b", message="", hardware_id="", values=[]),
        ],
    )
    flat = flatten_message(msg, ts)
    assert flat == {
        "header.stamp.sec": 3,
        "header.stamp.nanosec": 4,
        "header.frame_id": "base",
        "status[].level": [2, 0],
        "status[].name": ["a", "b"],
        "status[].message": ["m", ""],
        "status[].hardware_id": ["h", ""],
        "status[].values[].key": ["k"],
        "status[].values[].value": ["v"],
    }
    assert [leaf.path for leaf in leaf_fields(ts, msg.__msgtype__)] == list(flat)
    numeric = flatten_message(msg, ts, numeric_only=True)
    assert numeric == {"header.stamp.sec": 3, "header.stamp.nanosec": 4, "status[].level": [2, 0]}

    flag = flatten_message(ts.types["std_msgs/msg/Bool"](data=True), ts)
    assert flag == {"data": 1} and isinstance(flag["data"], int)
    imu = random_message(ts, "sensor_msgs/msg/Imu", np.random.default_rng(3))
    flat_imu = flatten_message(imu, ts)
    assert _same(flat_imu["orientation_covariance[8]"], imu.orientation_covariance[8])  # type: ignore[attr-defined]
    assert len(flat_imu) == 3 + 4 + 9 + 3 + 9 + 3 + 9


def test_types_from_installed_definitions_decode_like_rosbags() -> None:
    typename = "nav_msgs/msg/Odometry"
    types = MessageTypes.from_definitions({typename: message_definition(typename)})
    msg = random_message(JAZZY, typename, np.random.default_rng(4))
    data = bytes(JAZZY.serialize_cdr(msg, typename))
    decoded = types.deserialize(data, typename)
    assert bytes(types.typestore.serialize_cdr(decoded, typename)) == data


def test_definition_problems_are_recorded_not_raised() -> None:
    types = MessageTypes.from_definitions(
        {
            "pkg/msg/Broken": "int64 a\n---\nint64 sum\n",  # .srv text under a msg name
            "pkg/msg/Partial": "other_pkg/Missing m\n",
        }
    )
    assert "cannot be parsed" in types.problems["pkg/msg/Broken"]
    assert "other_pkg/msg/Missing" in types.problems["pkg/msg/Partial"]
    with pytest.raises(SchemaError, match="cannot be parsed"):
        types.resolve("pkg/msg/Broken")
    with pytest.raises(SchemaError, match="no message definition"):
        types.resolve("pkg/msg/Unknown")
    # No stored definition, but rosbags ships the type (older .db3 bags store none).
    assert types.resolve("std_msgs/msg/String") == "std_msgs/msg/String"


def test_interop_types_decode_and_reserialize_exactly(interop_dir: Path) -> None:
    """Non-canonical names and service events (raw .srv text) decode to the stored bytes."""
    bags = [
        interop_dir / "rosbag2_transport/test/resources/mcap/test_bag_for_seek",
        interop_dir / "rosbag2_cpp/test/rosbag2_cpp/bags/only_services.mcap",
        interop_dir / "rosbag2_tests/resources/mcap/cdr_test",
    ]
    for path in bags:
        with BagReader(path) as bag:
            types = MessageTypes.from_definitions(bag.definitions)
            assert types.problems == {}
            for message in bag.messages():
                type_name = bag.topics[message.topic].type
                decoded = types.deserialize(message.data, type_name)
                canonical = types.resolve(type_name)
                again = bytes(types.typestore.serialize_cdr(decoded, canonical))
                # Writers may pad the payload to a multiple of 4 bytes.
                assert message.data[: len(again)] == again
                assert len(message.data) - len(again) <= 3
    with BagReader(bags[1]) as bag:
        types = MessageTypes.from_definitions(bag.definitions)
        msg = types.deserialize(
            next(iter(bag.messages())).data, "example_interfaces/srv/AddTwoInts_Event"
        )
        flat = flatten_message(msg, types.typestore, numeric_only=True)
        assert {"info.event_type", "request[].a", "request[].b", "response[].sum"} <= flat.keys()


def _flat_equal(a: Any, b: Any) -> bool:
    if type(a) is not type(b):
        return False
    if isinstance(a, np.ndarray):
        return a.dtype == b.dtype and bool(np.array_equal(a, b, equal_nan=True))
    if isinstance(a, list):
        return len(a) == len(b) and all(_flat_equal(x, y) for x, y in zip(a, b, strict=True))
    if isinstance(a, float):
        return a == b or (np.isnan(a) and np.isnan(b))
    return bool(a == b)


def test_generated_flattener_equals_a_plain_recursive_walk() -> None:
    """Every Jazzy type rosbags ships, with random values, sequence lengths and strings."""
    rng = np.random.default_rng(11)
    for typename in sorted(JAZZY.fielddefs):
        for _ in range(3):
            msg = random_message(JAZZY, typename, rng)
            for numeric_only in (False, True):
                ours = flatten_message(msg, JAZZY, numeric_only=numeric_only)
                reference = reference_flatten(msg, JAZZY, numeric_only=numeric_only)
                assert list(ours) == list(reference), typename
                for path, value in ours.items():
                    assert _flat_equal(value, reference[path]), (typename, path)


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
    assert _same(group.values[pressure], expected)


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


@pytest.mark.parametrize(
    "typename",
    ["sensor_msgs/msg/Imu", "nav_msgs/msg/Odometry", "diagnostic_msgs/msg/DiagnosticArray"],
)
def test_field_getter_returns_the_flattened_values_of_its_paths(typename: str) -> None:
    rng = np.random.default_rng(12)
    paths = [leaf.path for leaf in leaf_fields(JAZZY, typename)]
    selections = [
        tuple(paths),  # whole arrays in order: read with one unpacking
        tuple(p for p in paths if not p.endswith(("[3]", "[7]"))),  # arrays with holes
        tuple(rng.permutation(paths)[: len(paths) // 2]),
    ]
    for selection in selections:
        get = field_getter(JAZZY, typename, selection)
        for _ in range(5):
            msg = random_message(JAZZY, typename, rng)
            flat = flatten_message(msg, JAZZY)
            values = get(msg)
            assert len(values) == len(selection)
            for path, value in zip(selection, values, strict=True):
                assert _flat_equal(value, flat[path]), (typename, path)
