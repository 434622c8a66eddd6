"""Every ROS 2 IDL shape, published with rclpy and recorded over DDS, decodes as rclpy decodes it.

test_msgs holds every primitive (wstring included) as a field, fixed array, bounded and
unbounded sequence, nested messages and arrays of them, bounded strings, constants and
defaults. Messages of each type are published, recorded by ``bagkit record``, and the bag's
``echo``, ``read_dataframe``, ``export`` (Parquet, CSV), ``stats summary``, ``compare`` and
``replay`` are held to rclpy's own deserialization of the recorded bytes.
"""

from __future__ import annotations

import importlib
import json
import math
import signal
import subprocess
import time
from pathlib import Path
from typing import Any

import numpy as np
import pandas as pd
import pytest
import test_msgs.msg
from rclpy.node import Node
from rclpy.qos import QoSProfile, ReliabilityPolicy
from rclpy.serialization import deserialize_message, serialize_message
from replay_harness import CLI_KNOWN, Listener, bagkit_cli
from rosidl_parser.definition import (
    AbstractGenericString,
    AbstractSequence,
    AbstractWString,
    Array,
    BasicType,
    BoundedSequence,
    NamespacedType,
)
from waiting import wait_for

import bagkit
from bagkit.bag import BagReader

pytestmark = pytest.mark.ros

TYPES = [
    "BasicTypes",
    "Arrays",
    "BoundedPlainSequences",
    "BoundedSequences",
    "UnboundedSequences",
    "Strings",
    "WStrings",
    "Constants",
    "Defaults",
    "Nested",
    "MultiNested",
    "Builtins",
    "Empty",
]
PER_TYPE = 4
_INTEGERS = {
    f"{sign}int{bits}": (0, 2**bits - 1) if sign else (-(2 ** (bits - 1)), 2 ** (bits - 1) - 1)
    for sign in ("", "u")
    for bits in (8, 16, 32, 64)
}
TEXT_PATHS: set[str] = set()  # leaves that are strings (no statistics), seen in _leaf
_FLOATS = [1.5, -0.0, math.inf, -3.25e-5, -math.inf, 1e30]
_TEXTS = ["", "plain", 'quote " and \\ backslash', "ünïcödé ハロー", "astral 😀 pair"]


def _value(slot: Any, i: int) -> Any:
    """A value of IDL type ``slot`` that varies with ``i`` (extremes included)."""
    if isinstance(slot, BasicType):
        name = slot.typename
        if name == "boolean":
            return i % 2 == 1
        if name == "octet":
            return bytes([(97 * i + 200) % 256])
        if name in ("float", "double"):
            return _FLOATS[i % len(_FLOATS)] * (1 if name == "float" else 1.0000000001)
        low, high = _INTEGERS[name]
        return [low, high, (low + high) // 3, 0][i % 4]
    if isinstance(slot, AbstractGenericString):
        limit = getattr(slot, "maximum_size", None) or 100
        text = _TEXTS[i % len(_TEXTS)] if isinstance(slot, AbstractWString) else _TEXTS[i % 4]
        return text[:limit]
    if isinstance(slot, NamespacedType):
        module = importlib.import_module(".".join(slot.namespaces))
        return _filled(getattr(module, slot.name)(), i)
    if isinstance(slot, Array):
        return [_value(slot.value_type, i + k) for k in range(slot.size)]
    assert isinstance(slot, AbstractSequence)
    bound = slot.maximum_size if isinstance(slot, BoundedSequence) else 5
    return [_value(slot.value_type, i + k) for k in range((i * 2 + 1) % (bound + 1))]


def _filled(msg: Any, i: int) -> Any:
    for name, slot in zip(msg.get_fields_and_field_types(), msg.SLOT_TYPES, strict=True):
        setattr(msg, name, _value(slot, i))
    return msg


def _plain(value: Any) -> Any:
    """An rclpy value as echo prints it: octets as integers, arrays as lists."""
    if hasattr(value, "get_fields_and_field_types"):
        return {name: _plain(getattr(value, name)) for name in value.get_fields_and_field_types()}
    if isinstance(value, bytes):
        return value[0]
    if isinstance(value, np.ndarray):
        return [_plain(v) for v in value.tolist()]
    if isinstance(value, (list, tuple)) or type(value).__name__ == "array":
        return [_plain(v) for v in value]
    return value


def _same(a: Any, b: Any) -> bool:
    return _difference(a, b) is None


def _difference(a: Any, b: Any, where: str = "") -> str | None:
    """Where ``a`` and ``b`` first differ (floats equal as numbers, -0.0 included), or None."""
    if isinstance(a, dict) and isinstance(b, dict):
        if a.keys() != b.keys():
            return f"{where}: keys {sorted(a)} != {sorted(b)}"
        found = (_difference(a[k], b[k], f"{where}.{k}") for k in a)
        return next((d for d in found if d), None)
    if isinstance(a, list) and isinstance(b, list):
        if len(a) != len(b):
            return f"{where}: {len(a)} != {len(b)} elements"
        found = (
            _difference(x, y, f"{where}[{i}]") for i, (x, y) in enumerate(zip(a, b, strict=True))
        )
        return next((d for d in found if d), None)
    if isinstance(a, float) or isinstance(b, float):
        same = float(a) == float(b) and math.copysign(1, a) == math.copysign(1, b)
    else:
        same = bool(a == b) and type(a) is type(b)
    return None if same else f"{where}: {a!r} != {b!r}"


def _leaves(plain: Any, slot_types: Any, prefix: str, out: dict[str, Any], pooled: bool) -> None:
    """``plain`` flattened by bagkit's path rules (``a.b``, ``a[0]``, pooled ``a[]``)."""
    for (name, value), slot in zip(plain.items(), slot_types, strict=True):
        _leaf(f"{prefix}{name}", value, slot, out, pooled)


def _leaf(path: str, value: Any, slot: Any, out: dict[str, Any], pooled: bool) -> None:
    if isinstance(slot, NamespacedType):
        module = importlib.import_module(".".join(slot.namespaces))
        _leaves(value, getattr(module, slot.name).SLOT_TYPES, f"{path}.", out, pooled)
    elif isinstance(slot, Array):
        for k, item in enumerate(value):
            _leaf(f"{path}[{k}]", item, slot.value_type, out, pooled)
    elif isinstance(slot, AbstractSequence):
        if not pooled:
            _prepare(f"{path}[]", slot.value_type, out)
        for item in value:
            _leaf(f"{path}[]", item, slot.value_type, out, True)
    elif isinstance(slot, AbstractGenericString) and path not in TEXT_PATHS:
        TEXT_PATHS.add(path)
        _leaf(path, value, slot, out, pooled)
    elif pooled:
        out.setdefault(path, []).append(value)
    else:
        out[path] = value


def _prepare(path: str, slot: Any, out: dict[str, Any]) -> None:
    """Pooled leaves exist (empty) even when the sequence is."""
    if isinstance(slot, NamespacedType):
        module = importlib.import_module(".".join(slot.namespaces))
        cls = getattr(module, slot.name)
        for name, sub in zip(cls.get_fields_and_field_types(), cls.SLOT_TYPES, strict=True):
            _prepare(f"{path}.{name}", sub, out)
    elif isinstance(slot, Array):
        for k in range(slot.size):
            _prepare(f"{path}[{k}]", slot.value_type, out)
    elif isinstance(slot, AbstractSequence):
        _prepare(f"{path}[]", slot.value_type, out)
    else:
        if isinstance(slot, AbstractGenericString):
            TEXT_PATHS.add(path)
        out.setdefault(path, [])


def _topic(name: str) -> str:
    return f"/idl/{name.lower()}"


def _reference(bag: Path) -> dict[str, list[tuple[bytes, dict[str, Any]]]]:
    """Per topic: each recorded payload and rclpy's decoding of it (as plain data)."""
    found: dict[str, list[tuple[bytes, dict[str, Any]]]] = {}
    with BagReader(bag) as reader:
        for message in reader.messages():
            cls = getattr(test_msgs.msg, _NAMES[message.topic])
            decoded = _plain(deserialize_message(message.data, cls))
            found.setdefault(message.topic, []).append((bytes(message.data), decoded))
    return found


_NAMES = {_topic(name): name for name in TYPES}


def _record(node: Node, processes: Any, bag: Path) -> dict[str, list[Any]]:
    reliable = QoSProfile(depth=100, reliability=ReliabilityPolicy.RELIABLE)
    publishers = {
        name: node.create_publisher(getattr(test_msgs.msg, name), _topic(name), reliable)
        for name in TYPES
    }
    proc = processes.start(
        ["bagkit", "record", *map(_topic, TYPES), "-o", str(bag)],
        stdout=subprocess.PIPE,
        stderr=subprocess.PIPE,
    )
    wait_for(lambda: all(p.get_subscription_count() > 0 for p in publishers.values()), 20.0)
    sent: dict[str, list[Any]] = {}
    for i in range(PER_TYPE):
        for name, publisher in publishers.items():
            msg = _filled(getattr(test_msgs.msg, name)(), i)
            publisher.publish(msg)
            # As rclpy's own serialization round trip gives it (float32 rounded).
            again = deserialize_message(serialize_message(msg), type(msg))
            sent.setdefault(_topic(name), []).append(_plain(again))
        time.sleep(0.02)
    time.sleep(0.5)
    proc.send_signal(signal.SIGINT)
    _, stderr = proc.communicate(timeout=20)
    assert proc.returncode == 130, stderr.decode()
    return sent


def test_every_idl_shape_decodes_as_rclpy_decodes_it(
    node: Node, processes: Any, tmp_path: Path, listener_factory: type[Listener]
) -> None:
    bag = tmp_path / "idl"
    sent = _record(node, processes, bag)
    reference = _reference(bag)
    assert {t: len(r) for t, r in reference.items()} == {_topic(n): PER_TYPE for n in TYPES}
    for topic, recorded in reference.items():
        # What was recorded is what rclpy published (DDS kept every value).
        assert all(_same(d, s) for (_, d), s in zip(recorded, sent[topic], strict=True)), topic
    _check_echo(bag, reference)
    _check_tables(bag, tmp_path, reference)
    _check_stats(bag, reference)
    _check_compare(bag)
    _check_replay(bag, reference, listener_factory)


def _without_padding_member(data: Any) -> Any:
    # A message without fields is one uint8 in CDR; rosidl names it, rclpy hides it.
    if isinstance(data, list):
        return [_without_padding_member(v) for v in data]
    if not isinstance(data, dict):
        return data
    return {
        k: _without_padding_member(v)
        for k, v in data.items()
        if k != "structure_needs_at_least_one_member"
    }


def _check_echo(bag: Path, reference: dict[str, list[tuple[bytes, dict[str, Any]]]]) -> None:
    for topic, recorded in reference.items():
        result = bagkit_cli("echo", str(bag), topic, "--format", "json")
        assert result.returncode == 0 and result.stderr == "", (topic, result.stderr)
        lines = [json.loads(line) for line in result.stdout.splitlines()]
        assert len(lines) == len(recorded)
        for line, (_, expected) in zip(lines, recorded, strict=True):
            difference = _difference(_without_padding_member(line["data"]), expected)
            assert difference is None, (topic, difference)


def _flat_reference(topic: str, plain: dict[str, Any]) -> dict[str, Any]:
    out: dict[str, Any] = {}
    cls = getattr(test_msgs.msg, _NAMES[topic])
    _leaves(plain, cls.SLOT_TYPES, "", out, False)
    return out


def _check_tables(
    bag: Path, tmp_path: Path, reference: dict[str, list[tuple[bytes, dict[str, Any]]]]
) -> None:
    out = tmp_path / "export"
    for file_format in ("parquet", "csv"):
        target = str(out / file_format)
        result = bagkit_cli("export", str(bag), "-o", target, "--format", file_format)
        assert result.returncode == 0 and "warning" not in result.stderr, result.stderr
    for topic, recorded in reference.items():
        if _NAMES[topic] == "Empty":
            continue
        frame = bagkit.read_dataframe(bag, topic).reset_index(drop=True)
        name = topic.rsplit("/", 1)[1]
        parquet = pd.read_parquet(out / "parquet" / "idl" / f"{name}.parquet")
        csv = pd.read_csv(out / "csv" / "idl" / f"{name}.csv", keep_default_na=False)
        for row, (_, plain) in enumerate(recorded):
            for path, expected in _flat_reference(topic, plain).items():
                for table, cell in (
                    ("read_dataframe", frame.at[row, path]),
                    ("parquet", parquet.at[row, path]),
                    ("csv", _csv_cell(csv.at[row, path], expected)),
                ):
                    assert _same(_cell(cell, expected), expected), (table, topic, row, path)


def _cell(cell: Any, expected: Any) -> Any:
    if isinstance(cell, np.ndarray):
        cell = cell.tolist()
    if isinstance(cell, np.generic):
        cell = cell.item()
    if isinstance(expected, bool):
        return bool(cell)
    if isinstance(expected, list):
        return [bool(v) if isinstance(e, bool) else v for v, e in zip(cell, expected, strict=False)]
    return cell


def _csv_cell(cell: Any, expected: Any) -> Any:
    if isinstance(expected, list):
        return json.loads(cell)
    if isinstance(expected, str):
        return str(cell)
    if isinstance(expected, float):
        # CSV writes a float32 column with float32's shortest digits.
        value = float(cell)
        return expected if math.isclose(value, expected, rel_tol=1e-7) else value
    return cell


def _check_stats(bag: Path, reference: dict[str, list[tuple[bytes, dict[str, Any]]]]) -> None:
    result = bagkit_cli("stats", "summary", str(bag), "--format", "json")
    assert result.returncode == 0 and "warning" not in result.stderr, result.stderr
    topics = {t["topic"]: t for t in json.loads(result.stdout)["topics"]}
    for topic, recorded in reference.items():
        assert topics[topic]["count"] == len(recorded)
        assert topics[topic]["undecodable"] == 0, topic
        flats = [_flat_reference(topic, plain) for _, plain in recorded]
        numeric = [p for p in flats[0] if p not in TEXT_PATHS]
        fields = {
            f["field"]: f
            for f in topics[topic]["fields"]
            if not f["field"].endswith("structure_needs_at_least_one_member")
        }
        assert sorted(fields) == sorted(numeric), topic
        for path in numeric:
            values = [float(v) for flat in flats for v in _as_list(flat[path])]
            assert fields[path]["count"] == len(values), (topic, path)
            for key, expected in (
                ("min", min(values, default=None)),
                ("max", max(values, default=None)),
            ):
                if expected is not None and math.isfinite(expected):
                    assert fields[path][key] == pytest.approx(expected), (topic, path, key)


def _as_list(value: Any) -> list[Any]:
    return value if isinstance(value, list) else [value]


def _check_compare(bag: Path) -> None:
    result = bagkit_cli("compare", str(bag), str(bag))
    assert result.returncode == 0, result.stdout + result.stderr
    assert "warning" not in result.stderr and "byte" not in result.stderr, result.stderr


def _check_replay(
    bag: Path,
    reference: dict[str, list[tuple[bytes, dict[str, Any]]]],
    listener_factory: type[Listener],
) -> None:
    listener = listener_factory({t: getattr(test_msgs.msg, _NAMES[t]) for t in reference})
    waits = [arg for topic in reference for arg in ("--wait-for", topic)]
    result = bagkit_cli("replay", str(bag), *CLI_KNOWN, *waits)
    assert result.returncode == 0, result.stderr
    total = sum(len(r) for r in reference.values())
    got = listener.wait_for_count(total)
    assert len(got) == total
    for topic, recorded in reference.items():
        replayed = [r.data for r in got if r.topic == topic]
        cls = getattr(test_msgs.msg, _NAMES[topic])
        decoded = [_plain(deserialize_message(data, cls)) for data in replayed]
        assert all(_same(a, b) for a, (_, b) in zip(decoded, recorded, strict=True)), topic
