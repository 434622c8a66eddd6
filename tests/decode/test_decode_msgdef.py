"""Stored definitions as untrusted text: every value form a .msg allows decodes, no text runs."""

from __future__ import annotations

import json
import keyword
import math
import struct
import subprocess
import sys
from pathlib import Path
from typing import Any

import numpy as np
import pytest
from bagkit_runs import bagkit_in_process, bagkit_subprocess
from random_messages import JAZZY, random_message
from rosbags.interfaces import Nodetype as RosbagsNodetype
from rosbags.typesys.base import normalize_fieldname

from bagkit.bag import BagWriter, TopicInfo
from bagkit.decode import MessageTypes, flatten_message
from bagkit.decode.cdr import object_reader
from bagkit.decode.layout import CdrLayout
from bagkit.decode.msgdef import Nodetype, TypeDefinitions, member_name
from bagkit.stats import summarize

BAGKIT = str(Path(sys.executable).with_name("bagkit"))


def test_constants_and_defaults_of_every_form_are_values() -> None:
    text = "\n".join(
        [
            "float64 POS_INF=inf",
            "float64 NEG_INF=-inf",
            "float32 NOT_A_NUMBER=nan",
            "float64 HUGE=1e999",
            "float64 SMALL=1e-3",
            "int32 HEX=0x1F",
            "uint8 TOP=255",
            "bool YES=true",
            "bool NO=0",
            'string QUOTED="say \\"hi\\" \\\\ back"',
            "string BARE=it's # not a comment? it is",
            "wstring WIDE='wïde'",
            "float64 x 1.5e3",
            "string<=5 s 'ab'",
            'wstring<=4 w "ハロー"',
            "int16[2] pair [1, -2]",
            "string[] names ['a,b', \"c\"]",
        ]
    )
    types = MessageTypes.from_definitions({"pkg/msg/Forms": text})
    assert types.problems == {}
    cls = types.typestore.types["pkg/msg/Forms"]
    assert math.inf == cls.POS_INF and -math.inf == cls.NEG_INF and math.inf == cls.HUGE
    assert math.isnan(cls.NOT_A_NUMBER) and cls.SMALL == 0.001 and cls.HEX == 31
    assert (cls.YES, cls.NO, cls.TOP) == (True, False, 255)
    assert cls.QUOTED == 'say "hi" \\\\ back'
    assert cls.BARE == "it's" and cls.WIDE == "wïde"
    payload = (
        b"\x00\x01\x00\x00"
        + struct.pack("<d", 2.5)
        + struct.pack("<I", 3)
        + b"ab\x00\x00"
        + struct.pack("<I", 1)
        + struct.pack("<I", 0x30CF)
        + struct.pack("<hh", 7, -8)
        + struct.pack("<I", 0)
    )
    assert flatten_message(types.deserialize(payload, "pkg/msg/Forms"), types.typestore) == {
        "x": 2.5,
        "s": "ab",
        "w": "ハ",
        "pair[0]": 7,
        "pair[1]": -8,
        "names[]": [],
    }


HOSTILE = {
    "evil/msg/Constant": "int32 X=__import__('os').system('touch {sentinel}')\nint32 y\n",
    "evil/msg/Float": "float64 X=__import__('os').system('touch {sentinel}')\n",
    "evil/msg/Default": "int32 y __import__('os').system('touch {sentinel}')\n",
    "evil/msg/Dunder": "int32 __class__\n",
    "evil/msg/Field": "int32 x;__import__('os').system('touch {sentinel}')\n",
    "evil/msg/TypeRef": "evil/T'+__import__('os').system('touch {sentinel}')+' x\n",
    "evil/msg/Section": "int32 x\n" + "=" * 80 + "\nMSG: a\"b\n__import__('os')\n",
    "evil/msg/Name\nint32 z": "int32 x\n",
    "evil/msg/Quote'": "int32 x\n",
    "evil/msg/Twice": "int32 x\nint32 x\n",
    "evil/msg/Keyword": "int32 class\nint32 class_\n",
}


@pytest.mark.parametrize("name", sorted(HOSTILE))
def test_no_hostile_definition_runs_code_or_breaks_a_type(name: str, tmp_path: Path) -> None:
    sentinel = tmp_path / "pwned"
    text = HOSTILE[name].format(sentinel=sentinel)
    types = MessageTypes.from_definitions({name: text, "ok/msg/Fine": "float64 HUGE=1e999\n"})
    assert "cannot be parsed" in types.problems[name]
    assert types.resolve("ok/msg/Fine") == "ok/msg/Fine"
    assert not sentinel.exists()


def test_hostile_schemas_through_the_cli_are_one_line_each(tmp_path: Path) -> None:
    sentinel = tmp_path / "pwned"
    bag = tmp_path / "hostile"
    names = sorted(HOSTILE)
    with BagWriter(bag) as writer:
        for i, name in enumerate(names):
            writer.add_topic(
                TopicInfo(f"/t{i}", name), definition=HOSTILE[name].format(sentinel=sentinel)
            )
            writer.write(f"/t{i}", b"\x00\x01\x00\x00" + bytes(8), log_time=i)
        writer.add_topic(TopicInfo("/inf", "ok/msg/Inf"), definition="float64 A=inf\nfloat64 x\n")
        writer.write("/inf", b"\x00\x01\x00\x00" + struct.pack("<d", 1.25), log_time=99)
    run = [BAGKIT, "echo", str(bag), "/inf", "--format", "json"]
    result = subprocess.run(run, capture_output=True, text=True, timeout=60, check=False)
    assert result.returncode == 0, result.stderr
    assert json.loads(result.stdout)["data"] == {"x": 1.25}
    for i in range(len(names)):
        # The first a real process, the others in this one (tests/bagkit_runs.py).
        args: list[str | Path] = ["echo", bag, f"/t{i}"]
        result = bagkit_subprocess(args, tmp_path) if i == 0 else bagkit_in_process(args)
        assert result.returncode == 2, result.stderr
        assert result.stderr.startswith("error: ") and result.stderr.count("\n") == 1
    run = [BAGKIT, "export", str(bag), "-o", str(tmp_path / "out")]
    result = subprocess.run(run, capture_output=True, text=True, timeout=60, check=False)
    assert result.returncode == 0, result.stderr
    assert "internal error" not in result.stderr
    assert result.stderr.count("warning: topic ") == len(names)
    assert not sentinel.exists()


def test_member_names_are_rosbags_attribute_names() -> None:
    """The classes are bagkit's, the objects go to rosbags' serializers (migrate): a field
    named after a Python keyword must be the attribute rosbags reads."""
    names = [*keyword.kwlist, *keyword.softkwlist, "x", "class_", "data", "self", "type"]
    for name in names:
        assert member_name(name) == normalize_fieldname(name), name


def test_node_kinds_are_numbered_as_rosbags_numbers_them() -> None:
    """bagkit's definitions and rosbags' (its Jazzy types, its IDL parser's) mix."""
    assert {k.name: int(k) for k in Nodetype} == {
        k.name: int(k) for k in RosbagsNodetype if k.name in Nodetype.__members__
    }
    assert set(Nodetype.__members__) <= set(RosbagsNodetype.__members__)


@pytest.mark.parametrize("little", [True, False])
def test_bagkit_reader_builds_rosbags_objects_for_every_jazzy_type(little: bool) -> None:
    """bagkit's reader (every decoder's), held to rosbags' on every Jazzy type."""
    rng = np.random.default_rng(8)
    for typename in sorted(JAZZY.fielddefs):
        read = object_reader(JAZZY, typename, little=little)
        read_lists = object_reader(JAZZY, typename, little=little, lists=True)
        for _ in range(2):
            msg = random_message(JAZZY, typename, rng)
            try:
                payload = bytes(JAZZY.serialize_cdr(msg, typename, little_endian=little))
            except struct.error:  # rosbags packs byte as int8: an octet over 127 does not fit
                continue
            decoded, end, wide = read(memoryview(payload)[4:], 0)
            expected = JAZZY.deserialize_cdr(payload, typename)
            assert 0 <= len(payload) - 4 - end <= 3 and wide == 0
            assert bytes(JAZZY.serialize_cdr(decoded, typename, little_endian=little)) == payload
            assert repr(flatten_message(decoded, JAZZY)) == repr(
                flatten_message(expected, JAZZY)
            ), typename
            # The reader of lists (echo's): the same numbers, as Python's.
            listed, list_end, _ = read_lists(memoryview(payload)[4:], 0)
            assert list_end == end
            assert repr(_as_lists(listed, JAZZY, arrays=False)) == repr(
                _as_lists(decoded, JAZZY, arrays=True)
            ), typename


def _as_lists(value: Any, store: TypeDefinitions, *, arrays: bool) -> Any:
    """A message object as nested dicts of Python values; numpy arrays through ``tolist``
    where ``arrays``, else refused."""
    if isinstance(value, np.ndarray):
        assert arrays, "a numpy array from the reader of lists"
        return value.tolist()
    if isinstance(value, list):
        return [_as_lists(v, store, arrays=arrays) for v in value]
    if hasattr(value, "__msgtype__"):
        return {
            name: _as_lists(getattr(value, member_name(name)), store, arrays=arrays)
            for name, _ in store.fielddefs[value.__msgtype__][1]
        }
    return value


def test_wide_strings_as_rclpy_writes_them() -> None:
    """uint32 count of UTF-16 units, each as 4 bytes, no terminator; rclpy's payload may end
    4 bytes per wide string later (its size estimate)."""
    types = MessageTypes.from_definitions({"w/msg/W": "wstring<=8 a\nwstring[2] b\nwstring[] c\n"})

    def wide(text: str) -> bytes:
        units = np.frombuffer(text.encode("utf-16-le"), "<u2").astype("<u4")
        return struct.pack("<I", len(units)) + units.tobytes()

    body = wide("é😀") + wide("") + wide("ハ") + struct.pack("<I", 1) + wide("z")
    decoded = types.deserialize(b"\x00\x01\x00\x00" + body + bytes(16), "w/msg/W")
    assert flatten_message(decoded, types.typestore) == {
        "a": "é😀",
        "b[0]": "",
        "b[1]": "ハ",
        "c[]": ["z"],
    }
    read = types.value_reader("w/msg/W", ["a", "c[]"])
    assert read(b"\x00\x01\x00\x00" + body) == ["é😀", ["z"]]
    for broken in (
        struct.pack("<II", 1, 0x110000) + body[8:],  # not a UTF-16 unit
        struct.pack("<II", 1, 0xD800) + body[8:],  # a lone surrogate
        struct.pack("<I", 1000) + body[4:],  # more units than bytes
        body + bytes(40),  # more than 4 bytes per wide string after it
    ):
        with pytest.raises(Exception, match="does not decode"):
            types.deserialize(b"\x00\x01\x00\x00" + broken, "w/msg/W")
        with pytest.raises(Exception, match="does not decode"):
            read(b"\x00\x01\x00\x00" + broken)


def test_names_that_mean_something_to_python_are_plain_fields() -> None:
    """Keywords, builtins, dataclass and generated-code names, a class attribute (``mro``)."""
    names = ["self", "cls", "None", "class", "match", "mro", "values", "pos", "rawdata", "T"]
    text = "".join(f"int32 {name}\n" for name in names)
    types = MessageTypes.from_definitions(
        {"py/msg/Names": text, "py/msg/Wide": text + "wstring w\n"}
    )
    assert types.problems == {}
    numbers = b"".join(struct.pack("<i", 10 * i) for i in range(len(names)))
    for typename, tail in (("py/msg/Names", b""), ("py/msg/Wide", struct.pack("<II", 1, 65))):
        payload = b"\x00\x01\x00\x00" + numbers + tail
        flat = flatten_message(types.deserialize(payload, typename), types.typestore)
        assert [flat[name] for name in names] == [10 * i for i in range(len(names))]
        assert types.value_reader(typename, ["mro", "None"])(payload) == [50, 20]


def test_wide_string_types_take_the_general_path_in_statistics(tmp_path: Path) -> None:
    definition = "float64 x\nwstring label\nfloat32[] samples\n"
    types = MessageTypes.from_definitions({"w/msg/Reading": definition})
    assert CdrLayout.of(types.typestore, "w/msg/Reading") is None
    bag = tmp_path / "wide"
    with BagWriter(bag) as writer:
        writer.add_topic(TopicInfo("/r", "w/msg/Reading"), definition=definition)
        for i in range(10):
            payload = (
                b"\x00\x01\x00\x00"
                + struct.pack("<dII", i / 4, 1, 0x263A)
                + struct.pack("<Iff", 2, i, -i)
            )
            writer.write("/r", payload, log_time=i)
    [topic] = summarize([bag]).topics
    fields = {f.field: f for f in topic.fields}
    assert sorted(fields) == ["samples[]", "x"] and topic.undecodable == 0
    assert fields["x"].mean == pytest.approx(np.mean(np.arange(10) / 4))
    assert (fields["samples[]"].count, fields["samples[]"].min) == (20, -9)
