"""Recursive, deep and huge type definitions: a SchemaError for that type, never RecursionError."""

from __future__ import annotations

import numpy as np
import pytest
from rosbags.typesys import get_types_from_msg
from rosbags.typesys.store import Typestore

from bagkit.decode import MessageTypes, SchemaError, flatten_message, leaf_fields
from bagkit.decode.layout import CdrLayout
from bagkit.decode.typegraph import (
    MAX_DECLARED_FIELDS,
    MAX_LEAF_FIELDS,
    MAX_TYPE_DEPTH,
    check_registered,
)

SEPARATOR = "=" * 80 + "\n"


def _chain(package: str, depth: int, *, sequence: bool = False) -> str:
    """The stored text of ``package/msg/T0``: ``depth`` types, each holding the next."""
    suffix = "[]" if sequence else ""
    parts = []
    for i in range(depth):
        text = f"{package}/T{i + 1}{suffix} next\n" if i < depth - 1 else ""
        text += f"float64 v{i}\n"
        parts.append(text if i == 0 else f"{SEPARATOR}MSG: {package}/T{i}\n{text}")
    return "".join(parts)


HOSTILE = {
    "a/msg/Self": "a/Self child\nfloat64 x\n",
    "b/msg/Kids": "float64 x\nb/Kids[] kids\n",
    "c/msg/Ping": f"c/Pong pong\n{SEPARATOR}MSG: c/Pong\nc/Ping[<=2] ping\n",
    "d/msg/T0": _chain("d", 5000),
    "e/msg/Wide": f"e/Row[1000] rows\n{SEPARATOR}MSG: e/Row\nfloat64[1000] cells\n",
    "f/msg/Many": "".join(f"float64 f{i}\n" for i in range(MAX_DECLARED_FIELDS - 1))
    + f"f/Two two\n{SEPARATOR}MSG: f/Two\nfloat64 a\nfloat64 b\n",
}
WHY = {
    "a/msg/Self": "a/msg/Self is recursive (a/msg/Self -> a/msg/Self)",
    "b/msg/Kids": "b/msg/Kids is recursive (b/msg/Kids -> b/msg/Kids)",
    "c/msg/Ping": "c/msg/Ping is recursive (c/msg/Ping -> c/msg/Pong -> c/msg/Ping)",
    "d/msg/T0": f"d/msg/T0 nests types more than {MAX_TYPE_DEPTH} deep",
    "e/msg/Wide": f"e/msg/Wide has more than {MAX_LEAF_FIELDS:,} leaf fields",
    "f/msg/Many": (
        f"f/msg/Many declares more than {MAX_DECLARED_FIELDS:,} fields with the types it uses"
    ),
}


def test_hostile_definitions_cost_their_own_type_only() -> None:
    types = MessageTypes.from_definitions({**HOSTILE, "ok/msg/Fine": "float64 x\n"})
    assert types.problems == {
        name: f"definition of {name} cannot be used ({why})" for name, why in WHY.items()
    }
    for name in HOSTILE:
        with pytest.raises(SchemaError, match="cannot be used"):
            types.resolve(name)
    assert types.deserialize(b"\x00\x01\x00\x00" + np.float64(2.5).tobytes(), "ok/msg/Fine")


@pytest.mark.parametrize("sequence", [False, True])
def test_types_as_deep_as_the_limit_go_through_every_walk(sequence: bool) -> None:
    """MAX_TYPE_DEPTH nested types: listed, laid out, decoded, flattened and read directly."""
    name = "deep/msg/T0"
    types = MessageTypes.from_definitions({name: _chain("deep", MAX_TYPE_DEPTH, sequence=sequence)})
    assert types.problems == {}
    store = types.typestore
    paths = [leaf.path for leaf in leaf_fields(store, name)]
    assert len(paths) == MAX_TYPE_DEPTH
    assert (CdrLayout.of(store, name) is None) == sequence
    message = None
    for i in reversed(range(MAX_TYPE_DEPTH)):
        cls = store.types[f"deep/msg/T{i}"]
        inner = {} if message is None else {"next": [message] if sequence else message}
        message = cls(**inner, **{f"v{i}": float(i)})
    data = bytes(types.rosbags_typestore().serialize_cdr(message, name))
    flat = flatten_message(types.deserialize(data, name), store)
    direct = types.value_reader(name, paths)(data)
    # v<i> holds i; inside the sequences (one element each), pooled as a list.
    numbers = [int(path.rpartition("v")[2]) for path in paths]
    assert sorted(numbers) == list(range(MAX_TYPE_DEPTH))
    expected = [[float(i)] if sequence and i else float(i) for i in numbers]
    assert [_plain(flat[p]) for p in paths] == expected
    assert [_plain(v) for v in direct] == expected


def _plain(value: object) -> object:
    return value.tolist() if isinstance(value, np.ndarray) else value


def test_walks_check_a_typestore_registered_elsewhere() -> None:
    """rosbags registers a recursive type; our walks refuse it instead of recursing."""
    store = Typestore()
    store.register(get_types_from_msg("x/Loop next\nfloat64 v\n", "x/msg/Loop"))
    for walk in (leaf_fields, CdrLayout.of, check_registered):
        with pytest.raises(SchemaError, match="recursive"):
            walk(store, "x/msg/Loop")
