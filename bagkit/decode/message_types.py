"""A rosbags typestore built from the message definitions stored in a bag, no ROS install needed.

rosbag2 stores each type's ``.msg`` text followed by its dependencies, each after a line of 80
``=`` and ``MSG: pkg/Type``; rosbags' msg parser reads that whole text at once. Each type is
registered on its own so that one unparseable definition only costs its own topics.

Two gaps are filled: service-event topics (``pkg/srv/Name_Event``) store the raw ``.srv`` text,
from which the event type is rebuilt as rosidl generates it; and older ``.db3`` bags store no
definitions (or incomplete ones), for which rosbags' own Jazzy types are used where it has them.
"""

from __future__ import annotations

from collections import ChainMap
from collections.abc import Callable, Mapping, Sequence
from dataclasses import dataclass, field
from typing import Any

from rosbags.interfaces import Nodetype
from rosbags.typesys import Stores, TypesysError, get_types_from_msg, get_typestore
from rosbags.typesys.store import Typestore

from bagkit.bag.definitions import canonical_type_name
from bagkit.decode.direct import ValueReader, value_reader
from bagkit.decode.errors import DecodeError, SchemaError
from bagkit.decode.flatten import FlatValue, field_getter
from bagkit.decode.typegraph import check_type_graph

_SERVICE_EVENT_INFO = "service_msgs/msg/ServiceEventInfo"


@dataclass(slots=True)
class MessageTypes:
    """The message types of one or more bags, decodable from their stored definitions.

    Attributes:
        typestore: the rosbags typestore holding every type that parsed.
        problems: bag type name -> why it cannot be decoded.
    """

    typestore: Typestore = field(default_factory=Typestore)
    problems: dict[str, str] = field(default_factory=dict)

    @classmethod
    def from_definitions(cls, definitions: Mapping[str, str]) -> MessageTypes:
        """Parse ``definitions`` (bag type name -> ros2msg text) into a typestore."""
        types = cls()
        for name, text in definitions.items():
            types.add(name, text)
        return types

    def add(self, name: str, text: str) -> None:
        """Register one stored definition; a failure is recorded in ``problems``, not raised.

        A type already registered is kept: use one ``MessageTypes`` per bag.
        """
        canonical = canonical_type_name(name)
        if canonical in self.typestore.fielddefs:
            return
        try:
            if "/srv/" in canonical and canonical.endswith("_Event"):
                parsed = _service_event_types(canonical, text)
            else:
                parsed = dict(get_types_from_msg(text, canonical))
            self._register(parsed)
        except (TypesysError, ValueError, SyntaxError) as exc:
            detail = str(exc).strip().splitlines()[0] if str(exc).strip() else type(exc).__name__
            self.problems[name] = f"definition of {name} cannot be parsed ({detail})"
        except KeyError as exc:
            missing = exc.args[0] if exc.args else exc
            self.problems[name] = f"definition of {name} is incomplete (no definition of {missing})"
        except SchemaError as exc:
            self.problems[name] = f"definition of {name} cannot be used ({exc})"

    def _register(self, parsed: dict[str, Any]) -> None:
        """Register ``parsed`` plus the dependencies it names but does not define."""
        missing = [
            dep
            for dep in _references(parsed)
            if dep not in self.typestore.fielddefs and dep not in parsed
        ]
        if missing:  # rosbags' own Jazzy types load only then (they take 0.1-0.2 s to import)
            builtin = get_typestore(Stores.ROS2_JAZZY).fielddefs
            for dep in missing:
                if dep not in parsed:
                    if dep not in builtin:
                        raise KeyError(dep)
                    parsed[dep] = builtin[dep]
                    missing.extend(d for d in _references({dep: builtin[dep]}) if d not in parsed)
        # Before rosbags sees them: its code generation recurses through the types.
        check_type_graph(ChainMap(parsed, self.typestore.fielddefs), parsed)
        self.typestore.register(parsed)

    def resolve(self, name: str) -> str:
        """The typestore name of bag type ``name``.

        A type with no stored definition is taken from rosbags' Jazzy types when it has it.

        Raises:
            SchemaError: the type's definition is missing or did not parse.
        """
        canonical = canonical_type_name(name)
        if canonical in self.typestore.fielddefs:
            return canonical
        if name not in self.problems:
            builtin = get_typestore(Stores.ROS2_JAZZY).fielddefs
            if canonical in builtin:
                self._register({canonical: builtin[canonical]})
                return canonical
        raise SchemaError(self.problems.get(name, f"no message definition stored for {name}"))

    def deserialize(self, data: bytes | memoryview, name: str) -> object:
        """Decode one CDR message of bag type ``name`` into a rosbags message object.

        Raises:
            SchemaError: the type cannot be decoded.
            DecodeError: the data does not match the definition.
        """
        return self.decoder(name)(data)

    def decoder(self, name: str) -> Callable[[bytes | memoryview], object]:
        """``deserialize`` for one type, resolved once (for many messages of a topic).

        Calls rosbags' generated deserializer directly: given a memoryview (of a chunk), the
        payload is not copied; arrays in the message may then be views of that buffer.

        Raises:
            SchemaError: the type cannot be decoded.
        """
        canonical = self.resolve(name)
        msgdef = self.typestore.get_msgdef(canonical)
        little, big = msgdef.deserialize_cdr_le, msgdef.deserialize_cdr_be
        cls, store = msgdef.cls, self.typestore

        def decode(data: bytes | memoryview) -> object:
            try:
                if len(data) < 4 or data[0] != 0 or data[1] > 1:
                    raise ValueError("not a plain CDR encapsulation")
                message, end = (little if data[1] else big)(data[4:], 0, cls, store)
                # rosbags cuts a string that runs past the end short instead of failing.
                if end + 4 > len(data):
                    raise ValueError("the message ends past the payload")
                # CDR writers pad to 4 bytes at most (rosbags' own check).
                if end + 4 + 3 < len(data):
                    raise ValueError(f"{len(data) - 4 - end} bytes after the message")
            except Exception as exc:  # rosbags raises struct/index/unicode errors on bad bytes
                raise DecodeError(f"{name} message does not decode: {exc!r}") from exc
            return message

        return decode

    def value_reader(self, name: str, paths: Sequence[str]) -> ValueReader:
        """A function returning the values of leaf ``paths`` of one payload of type ``name``.

        The same values as ``field_getter(typestore, name, paths)(decoder(name)(payload))``,
        read straight from the bytes where it can (see :mod:`bagkit.decode.direct`).

        Raises:
            SchemaError: the type cannot be decoded.
            KeyError: a path that the type does not have.
        """
        canonical = self.resolve(name)
        getter = field_getter(self.typestore, canonical, tuple(paths))
        decode = self.decoder(name)

        def through_objects(data: bytes | memoryview) -> list[FlatValue]:
            return getter(decode(data))

        return value_reader(self.typestore, canonical, paths, through_objects)


def _references(parsed: Mapping[str, Any]) -> list[str]:
    """The message types that the fields of ``parsed`` use."""
    found: list[str] = []

    def visit(desc: Any) -> None:
        kind, rest = desc
        if kind == Nodetype.NAME:
            found.append(rest)
        elif kind in (Nodetype.ARRAY, Nodetype.SEQUENCE):
            visit(rest[0])

    for _, fields in parsed.values():
        for _, desc in fields:
            visit(desc)
    return list(dict.fromkeys(found))


def _service_event_types(event: str, text: str) -> dict[str, Any]:
    """Types of a ``pkg/srv/Name_Event`` from the ``.srv`` text that rosbag2 stores for it.

    rosidl generates ``Name_Event`` as ``ServiceEventInfo info``, ``Name_Request[<=1] request``
    and ``Name_Response[<=1] response``.
    """
    if "---" not in text:
        return dict(get_types_from_msg(text, event))
    base = event.removesuffix("_Event")
    package, _, name = base.split("/")
    request_text, response_text = text.split("---", 1)
    types: dict[str, Any] = {}
    # The msg parser only names types pkg/msg/Name: parse as such, then rename.
    for part, part_text in (("Request", request_text), ("Response", response_text)):
        parsed = dict(get_types_from_msg(part_text, f"{package}/msg/{name}_{part}"))
        types[f"{base}_{part}"] = parsed.pop(f"{package}/msg/{name}_{part}")
        types.update(parsed)
    types[event] = (
        [],
        [
            ("info", (Nodetype.NAME, _SERVICE_EVENT_INFO)),
            ("request", (Nodetype.SEQUENCE, ((Nodetype.NAME, f"{base}_Request"), 1))),
            ("response", (Nodetype.SEQUENCE, ((Nodetype.NAME, f"{base}_Response"), 1))),
        ],
    )
    return types
