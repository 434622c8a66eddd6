"""A rosbags typestore built from the message definitions stored in a bag, no ROS install needed.

rosbag2 stores each type's ``.msg`` text followed by its dependencies, each after a line of 80
``=`` and ``MSG: pkg/Type``. The text is the bag's, untrusted: :mod:`bagkit.decode.msgdef`
parses it into names that are identifiers and values that are Python values, and the message
classes are made here with :func:`dataclasses.make_dataclass` rather than by rosbags'
``Typestore.register``, which generates and runs Python source with the constants in it. Each
type is registered on its own so that one unparseable definition only costs its own topics.

Two gaps are filled: service-event topics (``pkg/srv/Name_Event``) store the raw ``.srv`` text,
from which the event type is rebuilt as rosidl generates it; and older ``.db3`` bags store no
definitions (or incomplete ones), for which rosbags' own Jazzy types are used where it has them.
Messages are decoded into objects by :mod:`bagkit.decode.cdr`'s readers (wide strings too).
"""

from __future__ import annotations

import dataclasses
from collections import ChainMap
from collections.abc import Callable, Mapping, Sequence
from dataclasses import dataclass, field
from typing import TYPE_CHECKING, Any

from bagkit.bag.definitions import canonical_type_name
from bagkit.decode.cdr import PayloadReader, payload_reader
from bagkit.decode.errors import DefinitionError, SchemaError, undecodable
from bagkit.decode.flatten import FlatValue, field_getter
from bagkit.decode.msgdef import EMPTY_STRUCT_MEMBER, Nodetype, TypeDef, member_name
from bagkit.decode.stored import COMMON_SERVICES, parse_stored
from bagkit.decode.typegraph import check_type_graph

if TYPE_CHECKING:
    from rosbags.typesys.store import Typestore

    from bagkit.bag.reader import BagReader
    from bagkit.decode.direct import ValueReader


class _MessageClasses(dict[str, type]):
    """Type name -> message class, each made on first lookup from the typestore's definitions.

    Only decoding into objects needs the classes (bagkit's readers and rosbags' converters look
    them up here); the bulk and direct readers never do, and making one costs about 1 ms, more
    than a small bag's reading for a bag of twenty types.
    """

    def __init__(self, fielddefs: Mapping[str, Any]) -> None:
        super().__init__()
        self._fielddefs = fielddefs

    def __missing__(self, typename: str) -> type:
        definition = self._fielddefs.get(typename)
        if definition is None:
            raise KeyError(typename)
        made = self[typename] = _message_class(typename, definition)
        return made

    def __contains__(self, typename: object) -> bool:
        return typename in self._fielddefs

    def get(self, typename: str, default: Any = None) -> Any:
        return self[typename] if typename in self._fielddefs else default


class DefinitionStore:
    """What bagkit needs of a rosbags typestore: definitions by type name and their message
    classes, made on first use. rosbags' own (:meth:`MessageTypes.rosbags_typestore`) is made
    only to encode: importing it costs every command that decodes (benchmarks/README.md,
    "Start-up, sixth pass")."""

    def __init__(self) -> None:
        self.fielddefs: dict[str, TypeDef] = {}
        self.types = _MessageClasses(self.fielddefs)


@dataclass(slots=True)
class MessageTypes:
    """The message types of one or more bags, decodable from their stored definitions.

    Attributes:
        typestore: every type that parsed (see :meth:`rosbags_typestore` to encode).
        problems: bag type name -> why it cannot be decoded.

    Type names are looked up in one typestore; a topic whose schema holds another text for its
    type has its own :class:`MessageTypes` (:meth:`for_topic`): decode a topic's messages with
    ``types.for_topic(topic)``.
    """

    typestore: DefinitionStore = field(default_factory=DefinitionStore)
    problems: dict[str, str] = field(default_factory=dict)
    # Topics whose schema holds another text for their type: (type, text), parsed on first use.
    _topic_texts: dict[str, tuple[str, str]] = field(default_factory=dict)
    _topic_types: dict[str, MessageTypes] = field(default_factory=dict)
    # (type, little endian) -> its reader, generated on first use.
    _readers: dict[tuple[str, bool, bool], PayloadReader] = field(default_factory=dict)
    _rosbags: Typestore | None = None

    @classmethod
    def from_definitions(cls, definitions: Mapping[str, str]) -> MessageTypes:
        """Parse ``definitions`` (bag type name -> stored text) into a typestore."""
        types = cls()
        for name, text in definitions.items():
            types.add(name, text)
        return types

    @classmethod
    def for_bag(cls, bag: BagReader) -> MessageTypes:
        """The types of an open bag: its ``definitions``, and for each topic of its
        ``topic_definitions`` that topic's own text (see :meth:`for_topic`)."""
        types = cls.from_definitions(bag.definitions)
        for topic, text in bag.topic_definitions.items():
            types._topic_texts[topic] = (bag.topics[topic].type, text)
        return types

    def for_topic(self, topic: str) -> MessageTypes:
        """The types to decode ``topic`` with: its own schema's where its text differs from
        the one stored first for its type (two schemas of one type name in a bag), else self."""
        found = self._topic_types.get(topic)
        if found is None:
            if topic not in self._topic_texts:
                return self
            type_name, text = self._topic_texts[topic]
            found = self._topic_types[topic] = MessageTypes.from_definitions({type_name: text})
        return found

    def add(self, name: str, text: str) -> None:
        """Register one stored definition; a failure is recorded in ``problems``, not raised.

        A type already registered is kept: use one ``MessageTypes`` per bag.
        """
        canonical = canonical_type_name(name)
        if canonical in self.typestore.fielddefs:
            return
        try:
            self._register(parse_stored(text, canonical))
        except DefinitionError as exc:
            self.problems[name] = f"definition of {name} cannot be parsed ({exc})"
        except KeyError as exc:
            missing = exc.args[0] if exc.args else exc
            self.problems[name] = f"definition of {name} is incomplete (no definition of {missing})"
        except SchemaError as exc:
            self.problems[name] = f"definition of {name} cannot be used ({exc})"

    def _register(self, parsed: dict[str, TypeDef]) -> None:
        """Register ``parsed`` plus the dependencies it names but does not define."""
        missing = [
            dep
            for dep in _references(parsed)
            if dep not in self.typestore.fielddefs and dep not in parsed
        ]
        if missing:  # rosbags' own Jazzy types load only then
            builtin: Mapping[str, Any] = _jazzy_definitions()
            for dep in missing:
                if dep not in parsed:
                    if dep not in builtin:
                        raise KeyError(dep)
                    parsed[dep] = builtin[dep]
                    missing.extend(d for d in _references({dep: builtin[dep]}) if d not in parsed)
        # Before rosbags sees them: its code generation recurses through the types.
        check_type_graph(ChainMap(parsed, self.typestore.fielddefs), parsed)
        for typename, definition in parsed.items():
            known = self.typestore.fielddefs.get(typename)
            if known is not None and list(known[1]) != list(definition[1]):
                raise SchemaError(f"{typename} is defined twice, differently")
        fielddefs: dict[str, Any] = self.typestore.fielddefs
        for typename, definition in parsed.items():
            if typename not in fielddefs:
                fielddefs[typename] = definition  # its class is made on first use

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
            builtin: Mapping[str, Any] = _jazzy_definitions()
            if canonical in builtin:
                self._register({canonical: builtin[canonical]})
                return canonical
            service = canonical.removesuffix("_Event")
            if service in COMMON_SERVICES:  # an action's cancel events, stored without text
                self.add(canonical, COMMON_SERVICES[service])
                if canonical in self.typestore.fielddefs:
                    return canonical
        raise SchemaError(self.problems.get(name, f"no message definition stored for {name}"))

    def deserialize(self, data: bytes | memoryview, name: str) -> object:
        """Decode one CDR message of bag type ``name`` into a rosbags message object.

        Raises:
            SchemaError: the type cannot be decoded.
            DecodeError: the data does not match the definition.
        """
        return self.decoder(name)(data)

    def rosbags_typestore(self) -> Typestore:
        """rosbags' typestore of these types and classes, for its serializers (made once)."""
        if self._rosbags is None:
            from rosbags.typesys.store import Typestore  # its code generation: to encode only

            store = Typestore()
            store.fielddefs = self.typestore.fielddefs  # type: ignore[assignment]
            store.types = self.typestore.types
            self._rosbags = store
        return self._rosbags

    def decoder(self, name: str, *, lists: bool = False) -> Callable[[bytes | memoryview], object]:
        """``deserialize`` for one type, resolved once (for many messages of a topic); ``lists``:
        arrays of numbers as lists of Python numbers, not numpy arrays (for printing).

        Reads with bagkit's generated readers (:mod:`bagkit.decode.cdr`), not rosbags': they
        build the same objects, and generating one type's costs a fraction of rosbags' 15
        functions a type (benchmarks/README.md, start-up, sixth pass). Given a memoryview (of
        a chunk), the payload is not copied; arrays in the message may then be views of it.

        Raises:
            SchemaError: the type cannot be decoded.
        """
        canonical = self.resolve(name)

        def decode(data: bytes | memoryview) -> object:
            try:
                if len(data) < 4 or data[0] != 0 or data[1] > 1:
                    raise ValueError("not a plain CDR encapsulation")
                message, end = self._reader(canonical, bool(data[1]), lists)(data[4:])
                # CDR writers pad to 4 bytes at most (rosbags' own check).
                if end + 4 + 3 < len(data):
                    raise ValueError(f"{len(data) - 4 - end} bytes after the message")
            except Exception as exc:  # readers raise struct/index/unicode errors on bad bytes
                raise undecodable(name, exc) from exc
            return message

        return decode

    def _reader(self, canonical: str, little: bool, lists: bool) -> PayloadReader:
        """The reader of ``canonical`` in one byte order, generated on first use."""
        reader = self._readers.get((canonical, little, lists))
        if reader is None:
            reader = payload_reader(self.typestore, canonical, little=little, lists=lists)
            self._readers[(canonical, little, lists)] = reader
        return reader

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
        # The object path is made on first use: generating rosbags' deserializer costs more
        # than a small bag's reading, and the direct reader rarely falls back to it.
        decoders: list[Callable[[bytes | memoryview], object]] = []

        def through_objects(data: bytes | memoryview) -> list[FlatValue]:
            if not decoders:
                decoders.append(self.decoder(name))  # SchemaError: a DecodeError per message
            return getter(decoders[0](data))

        # The direct reader (and its layouts) when a command reads leaves: echo starts without.
        from bagkit.decode.direct import value_reader

        return value_reader(self.typestore, canonical, paths, through_objects)


def _message_class(typename: str, definition: TypeDef) -> type:
    """The message class of a type, as rosbags would generate it: fields in order, the
    constants and ``__msgtype__`` as class attributes."""
    constants: dict[str, Any] = {member_name(name): value for name, _, value in definition[0]}
    # An explicit field() each: dataclasses would take a class attribute of the same name
    # (``mro``) as the member's default.
    members: list[Any] = [
        (member_name(name), Any, dataclasses.field()) for name, _ in definition[1]
    ]
    if definition[1] == [EMPTY_STRUCT_MEMBER]:
        members = [(EMPTY_STRUCT_MEMBER[0], Any, dataclasses.field(default=0))]
    namespace = {**constants, "__msgtype__": typename}
    try:
        return dataclasses.make_dataclass(typename.replace("/", "__"), members, namespace=namespace)
    except (TypeError, ValueError) as exc:
        raise SchemaError(f"{typename} cannot be a Python class ({exc})") from None


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


def _jazzy_definitions() -> Mapping[str, Any]:
    """rosbags' own Jazzy types, for definitions a bag lacks."""
    from rosbags.typesys import Stores, get_typestore  # a slow import: only when one is missing

    return get_typestore(Stores.ROS2_JAZZY).fielddefs
