"""ROS 1 connections as ROS 2 topics: rosbags-convert's mapping, not a second one.

A ROS 1 connection record carries its ``.msg`` text; rosbags parses it into a type store
(types named ``pkg/msg/Name``, ``time``/``duration`` as ``builtin_interfaces``). As
``rosbags-convert`` does (:mod:`rosbags.convert.converter`), the ROS 2 side is that store with
ROS 2's ``std_msgs/msg/Header`` (no ``seq``) and the legacy renames
(``tf/msg/tfMessage`` -> ``tf2_msgs/msg/TFMessage``); payloads go from ROS 1's packed
serialization to CDR through rosbags' byte-level converter, definitions are the ROS 2
``ros2msg`` text rosbags generates, hashes its RIHS01. Latched connections get
rosbags-convert's transient-local QoS (:data:`LATCHED_QOS`). Imported only when a ROS 1
bag is opened.
"""

from __future__ import annotations

import contextlib
import functools
import sys
from collections.abc import Callable, Sequence
from dataclasses import dataclass, field
from typing import NamedTuple

from rosbags.interfaces import Connection
from rosbags.serde import SerdeError
from rosbags.typesys import Stores, get_types_from_msg, get_typestore
from rosbags.typesys.base import TypesysError
from rosbags.typesys.store import Typestore

_HEADER = "std_msgs/msg/Header"
# ROS 2's Header, which rosbags-convert takes from its Foxy store (loading a whole store costs
# more than reading a ROS 1 bag's index): the same fields, parsed by rosbags from its text.
_ROS2_HEADER = "builtin_interfaces/Time stamp\nstring frame_id\n"
# rosbags.convert.converter's STATIC_MSGTYPE_RENAMES and its LATCH profile as rosbag2's YAML
# (dump_qos_v9): importing that module (numpy, rosbags.highlevel) costs several times the
# reading of a large bag's index, so ``info`` uses these copies and the converter is imported
# when a message is converted. tests/bag/test_bag_rosbag1.py checks that they are rosbags'.
RENAMES = {"tf/msg/tfMessage": "tf2_msgs/msg/TFMessage"}
_FOREVER = "    sec: 2147483647\n    nsec: 4294967295\n"
LATCHED_QOS = (
    "- history: unknown\n  depth: 0\n  reliability: reliable\n  durability: transient_local\n"
    f"  deadline:\n{_FOREVER}  lifespan:\n{_FOREVER}  liveliness: automatic\n"
    f"  liveliness_lease_duration:\n{_FOREVER}  avoid_ros_namespace_conventions: false\n"
)
# What a broken definition text makes rosbags raise while it parses or generates code.
_TYPE_ERRORS = (TypesysError, SerdeError, KeyError, ValueError, AssertionError, RecursionError)


@dataclass(frozen=True)
class Ros2Type:
    """The ROS 2 face of one ROS 1 connection.

    Attributes:
        name: the ROS 2 type name (``pkg/msg/Name``).
        definition: its ``ros2msg`` text with dependencies, as rosbag2 stores it.
        type_hash: its RIHS01 hash.
        latched: the connection was latching (transient-local QoS).
        to_cdr: a ROS 1 payload to CDR (raises ``SerdeError`` and others on a bad payload).
    """

    name: str
    definition: str
    type_hash: str
    latched: bool
    converter: Callable[[], Callable[[bytes | memoryview], memoryview]] = field(repr=False)

    @functools.cached_property
    def to_cdr(self) -> Callable[[bytes | memoryview], memoryview]:
        """The converter, generated on first use (``info`` converts nothing)."""
        return self.converter()


class _Connection(NamedTuple):
    """What of a ROS 1 connection its ROS 2 type depends on."""

    id: int
    topic: str
    msgtype: str
    definition: str
    latched: bool


def ros2_types(connections: Sequence[Connection]) -> tuple[dict[int, Ros2Type], list[str]]:
    """The ROS 2 type of each connection (by connection id), and what could not be mapped.

    A connection whose definition does not parse is left out with one problem line; the
    others are mapped.
    """
    mapped, problems = _ros2_types(
        tuple(
            _Connection(
                c.id, c.topic, c.msgtype, c.msgdef.data, bool(getattr(c.ext, "latching", None))
            )
            for c in connections
        )
    )
    return dict(mapped), list(problems)


# The bags of one fleet (one recorder) share their connections: their types are parsed and
# their converters generated once, which costs more than reading a small bag's index.
@functools.lru_cache(maxsize=32)
def _ros2_types(
    connections: tuple[_Connection, ...],
) -> tuple[dict[int, Ros2Type], list[str]]:
    problems: list[str] = []
    typs: dict[str, object] = {}
    parsed: list[_Connection] = []
    for conn in connections:
        try:
            typs.update(get_types_from_msg(conn.definition, conn.msgtype))
        except _TYPE_ERRORS as exc:
            problems.append(f"definition of {conn.msgtype} on {conn.topic} unusable ({exc})")
            continue
        parsed.append(conn)
    src = get_typestore(Stores.EMPTY)
    dst = get_typestore(Stores.EMPTY)
    try:
        src.register(typs)  # type: ignore[arg-type]
        header = get_types_from_msg(_ROS2_HEADER, _HEADER)[_HEADER]
        dst.register({**typs, _HEADER: header})  # type: ignore[dict-item]
    except _TYPE_ERRORS as exc:
        return {}, [*problems, f"the definitions contradict each other ({exc})"]
    mapped: dict[int, Ros2Type] = {}
    cache: dict[str, object] = {}
    for conn in parsed:
        try:
            mapped[conn.id] = _map(src, dst, conn, cache)
        except _TYPE_ERRORS as exc:
            problems.append(f"{conn.msgtype} on {conn.topic} has no ROS 2 form ({exc})")
    return mapped, problems


def _map(src: Typestore, dst: Typestore, conn: _Connection, cache: dict[str, object]) -> Ros2Type:
    """One connection's ROS 2 type, as ``create_connections_converters`` of rosbags makes it."""
    name = RENAMES.get(conn.msgtype, conn.msgtype)
    if name not in dst.fielddefs:
        text = src.generate_msgdef(conn.msgtype, ros_version=2)[0]
        typs = get_types_from_msg(text, name)
        typs.pop(_HEADER, None)
        dst.register(typs)

    def converter() -> Callable[[bytes | memoryview], memoryview]:
        from rosbags.convert.converter import generate_message_converter

        # rosbags prints a note on stdout when a type is migrated: stdout is echo's output.
        with contextlib.redirect_stdout(sys.stderr):
            return generate_message_converter(
                src, dst, conn.msgtype, name, cache, src_is2=False, dst_is2=True
            )

    return Ros2Type(
        name=name,
        definition=dst.generate_msgdef(name, ros_version=2)[0],
        type_hash=dst.hash_rihs01(name),
        latched=conn.latched,
        converter=converter,
    )
