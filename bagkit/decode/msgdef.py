"""ROS 2 ``.msg`` text parsed, as untrusted input, into rosbags' field definitions.

The text rosbag2 stores for a type (its ``.msg`` followed by each dependency's after a line of
``=`` and ``MSG: pkg/Type``, split by :mod:`bagkit.decode.stored`) comes from the bag. Each
``.msg`` text is parsed here by rosidl's rules into the
``(constants, fields)`` pairs a rosbags typestore holds: every name is checked against an
identifier pattern and every value converted to a Python number or string, so that whatever is
later generated from a type (rosbags' serializers, bagkit's readers) is made of identifiers
only, and constants such as ``inf`` or ``1e999`` are values, never source text.

Beyond rosidl, the spellings of ROS 1 definitions in converted bags are accepted: ``Header``,
``time``, ``duration``, ``pkg/Type`` and mixed-case names.
"""

from __future__ import annotations

import keyword
import re
from collections.abc import Mapping
from enum import IntEnum
from typing import Any, Protocol

from bagkit.bag.definitions import PRIMITIVES
from bagkit.decode.errors import DefinitionError


class Nodetype(IntEnum):
    """The kind of a field description, numbered as rosbags numbers it: definitions of rosbags'
    (its Jazzy types, its IDL parser's) and bagkit's mix, and compare by number. bagkit's own, so
    that decoding starts without importing rosbags (benchmarks/README.md, "Start-up, sixth
    pass")."""

    BASE = 1
    NAME = 2
    ARRAY = 3
    SEQUENCE = 4


STRINGS = frozenset({"string", "wstring"})
# rosidl gives a message without fields this one member (CDR has no empty struct).
EMPTY_STRUCT_MEMBER = ("structure_needs_at_least_one_member", (Nodetype.BASE, ("uint8", 0)))

_PACKAGE = re.compile(r"[a-z][a-z0-9_]*\Z")
_IDENTIFIER = re.compile(r"[A-Za-z][A-Za-z0-9_]*\Z")  # messages, fields, constants
_KINDS = frozenset({"msg", "srv", "action"})
_ALIASES = {
    "Header": "std_msgs/msg/Header",
    "time": "builtin_interfaces/msg/Time",
    "duration": "builtin_interfaces/msg/Duration",
}
_CONSTANT = re.compile(r"([^\s=]+)\s*=(.*)\Z")
_INTEGER_RANGES = {
    f"{sign}int{bits}": (0, 2**bits - 1) if sign else (-(2 ** (bits - 1)), 2 ** (bits - 1) - 1)
    for sign in ("", "u")
    for bits in (8, 16, 32, 64)
} | {"byte": (0, 255), "char": (0, 255)}

TypeDef = tuple[list[tuple[str, str, Any]], list[tuple[str, Any]]]
"""rosbags' definition of one type: ``([(name, type, value)], [(name, field description)])``."""


class TypeDefinitions(Protocol):
    """Types by name as a typestore holds them: bagkit's (``MessageTypes.typestore``, no code
    generation) or rosbags' own."""

    @property
    def fielddefs(self) -> Mapping[str, Any]:
        """Type name -> its :data:`TypeDef`."""

    @property
    def types(self) -> Mapping[str, Any]:
        """Type name -> its message class."""


def member_name(name: str) -> str:
    """The attribute of field or constant ``name`` in a message object: a Python keyword gets
    an underscore (``class_``), as rosbags names it."""
    return f"{name}_" if keyword.iskeyword(name) else name


def parse_message(lines: list[str], typename: str) -> TypeDef:
    """One type's ``.msg`` lines as its definition (``typename`` as :func:`type_name` gives it).

    Raises:
        DefinitionError: a name, type or value that a ``.msg`` cannot hold.
    """
    package = typename.split("/", maxsplit=1)[0]
    constants: list[tuple[str, str, Any]] = []
    fields: list[tuple[str, Any]] = []
    names: set[str] = set()
    for number, raw in enumerate(lines, 1):
        line = raw.replace("\t", " ").split("#", 1)[0].strip()
        if not line or line.startswith("@"):  # rosbags' annotations carry nothing decoded
            continue
        try:
            kind, _, rest = line.partition(" ")
            rest = rest.strip()
            if not rest:
                raise DefinitionError(f"{line!r} is not 'type name'")
            if constant := _CONSTANT.match(rest):
                name, value = check_identifier(constant[1], "constant"), constant[2].strip()
                base, bound = _string_bound(kind)
                if base not in PRIMITIVES:
                    raise DefinitionError(f"a constant of type {kind!r}")
                constants.append((name, base, parse_value(base, value, bound)))
            else:
                name, _, default = rest.partition(" ")
                desc = field_description(kind, package)
                if default.strip():
                    _check_default(desc, default.strip())
                fields.append((check_identifier(name, "field"), desc))
        except DefinitionError as exc:
            raise DefinitionError(f"{typename} line {number}: {exc}") from None
        # rosbags names a field ``class`` ``class_``: that must not be another member too.
        if member_name(name) in names:
            raise DefinitionError(f"{typename} declares {name} twice")
        names.add(member_name(name))
    return constants, fields or [EMPTY_STRUCT_MEMBER]


def type_name(name: str, package: str | None = None) -> str:
    """``pkg/msg/Name`` for a type reference (``pkg/Name``, ``Name`` in ``package``, ROS 1
    aliases), checked to be made of identifiers.

    Raises:
        DefinitionError: not a type name.
    """
    if name in _ALIASES:
        return _ALIASES[name]
    parts = name.split("/")
    if len(parts) == 1 and package is not None:
        parts = [package, "msg", name]
    elif len(parts) == 2:
        parts = [parts[0], "msg", parts[1]]
    if len(parts) != 3 or parts[1] not in _KINDS or not _PACKAGE.match(parts[0]):
        raise DefinitionError(f"{name[:80]!r} is not a message type name")
    check_identifier(parts[2], "type")
    return "/".join(parts)


def field_description(kind: str, package: str) -> Any:
    """rosbags' description of a field type: ``float64``, ``string<=8``, ``pkg/T[3]``,
    ``int32[<=4]``, ``wstring[]``.

    Raises:
        DefinitionError: see :func:`parse_message`.
    """
    element, count, bounded = kind, None, False
    if kind.endswith("]"):
        element, bracket, size = kind[:-1].rpartition("[")
        if not bracket:
            raise DefinitionError(f"type {kind!r} has ']' without '['")
        bounded = size.startswith("<=")
        count = _positive(size.removeprefix("<="), kind) if size else 0
    base, bound = _string_bound(element)
    if base in PRIMITIVES:
        inner: Any = (Nodetype.BASE, (base, bound))
    else:
        inner = (Nodetype.NAME, type_name(element, package))
    if count is None:
        return inner
    if count and not bounded:
        return (Nodetype.ARRAY, (inner, count))
    return (Nodetype.SEQUENCE, (inner, count))


def parse_value(base: str, text: str, bound: int = 0) -> bool | int | float | str:
    """A constant's or default's value as rosidl reads it.

    Raises:
        DefinitionError: not a value of that type.
    """
    if base == "bool":
        if text.lower() not in ("true", "1", "false", "0"):
            raise DefinitionError(f"bool value {text[:40]!r} is not true, false, 1 or 0")
        return text.lower() in ("true", "1")
    if base in ("float32", "float64"):
        try:
            return float(text)  # rosidl's own reading: inf, nan, 1e-3 included
        except ValueError:
            raise DefinitionError(f"{base} value {text[:40]!r} is not a number") from None
    if base in _INTEGER_RANGES:
        low, high = _INTEGER_RANGES[base]
        value = _integer(text)
        if value is None or not low <= value <= high:
            raise DefinitionError(f"{base} value {text[:40]!r} is not an integer in range")
        return value
    return _string_value(text, bound)


def check_identifier(name: str, what: str) -> str:
    """``name`` when it is an identifier (a message, field or constant name).

    Raises:
        DefinitionError: it is not.
    """
    if not _IDENTIFIER.match(name):
        raise DefinitionError(f"{name[:80]!r} is not a {what} name")
    return name


def _positive(text: str, kind: str) -> int:
    if not text.isdigit() or int(text) <= 0:
        raise DefinitionError(f"type {kind!r}: a size must be a positive integer")
    return int(text)


def _string_bound(kind: str) -> tuple[str, int]:
    """``string<=8`` -> (``string``, 8); other types with bound 0."""
    base, token, bound = kind.partition("<=")
    if token and base in STRINGS:
        return base, _positive(bound, kind)
    return kind, 0


def _integer(text: str) -> int | None:
    for base in (10, 0):  # decimal first: rosidl reads 010 as ten
        try:
            return int(text, base)
        except ValueError:
            continue
    return None


def _string_value(text: str, bound: int) -> str:
    for quote in ('"', "'"):
        if len(text) >= 2 and text[0] == quote and text[-1] == quote:
            inner = text[1:-1]
            if re.search(rf"(?<!\\){quote}", inner):
                raise DefinitionError(f"string value {text[:40]!r} has an unescaped quote")
            text = inner.replace("\\" + quote, quote)
            break
    if bound and len(text) > bound:
        raise DefinitionError(f"string value {text[:40]!r} is longer than {bound}")
    return text


def _check_default(desc: Any, text: str) -> None:
    """Parse a field's default value (rosbags keeps none; a broken one breaks the type)."""
    kind, rest = desc
    if kind == Nodetype.BASE:
        parse_value(rest[0], text, rest[1])
        return
    inner = rest[0] if kind != Nodetype.NAME else desc
    if inner[0] != Nodetype.BASE or not (text.startswith("[") and text.endswith("]")):
        raise DefinitionError(f"default {text[:40]!r} of a field that takes none or a list")
    base, bound = inner[1]
    items = _string_items(text[1:-1]) if base in STRINGS else _number_items(text[1:-1])
    if rest[1] and (len(items) > rest[1] or (kind == Nodetype.ARRAY and len(items) != rest[1])):
        raise DefinitionError(f"default {text[:40]!r} has {len(items)} elements")
    for item in items:
        parse_value(base, item, bound)


def _number_items(text: str) -> list[str]:
    return [item.strip() for item in text.split(",")] if text.strip() else []


def _string_items(text: str) -> list[str]:
    """The elements of a list of strings, quoted ones kept with their quotes."""
    items: list[str] = []
    rest = text.strip()
    while rest:
        quote = rest[0] if rest[0] in "\"'" else None
        if quote:
            end = re.search(rf"(?<!\\){quote}", rest[1:])
            if end is None:
                raise DefinitionError(f"string list {text[:40]!r} has an open quote")
            items.append(rest[: end.end() + 1])
            rest = rest[end.end() + 1 :].strip()
        else:
            item, _, rest = rest.partition(",")
            items.append(item.strip())
            rest = "," + rest if rest else ""
        if rest and not rest.startswith(","):
            raise DefinitionError(f"string list {text[:40]!r}: ',' expected")
        rest = rest[1:].strip()
    return items
