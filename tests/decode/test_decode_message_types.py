"""MessageTypes: a typestore from stored definitions; problems recorded per type, not raised."""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest
from random_messages import JAZZY, random_message

from bagkit.bag import BagReader, message_definition
from bagkit.decode import MessageTypes, SchemaError, flatten_message


def test_types_from_installed_definitions_decode_like_rosbags() -> None:
    typename = "nav_msgs/msg/Odometry"
    types = MessageTypes.from_definitions({typename: message_definition(typename)})
    msg = random_message(JAZZY, typename, np.random.default_rng(4))
    data = bytes(JAZZY.serialize_cdr(msg, typename))
    decoded = types.deserialize(data, typename)
    assert bytes(types.rosbags_typestore().serialize_cdr(decoded, typename)) == data


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
                again = bytes(types.rosbags_typestore().serialize_cdr(decoded, canonical))
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
