"""One ``IDL:`` section of a ``ros2idl`` definition, parsed by rosbags, checked as untrusted.

rosbag2 stores a type it finds no ``.msg`` for (and newer rosbag2 versions some others) as
OMG IDL: one section per type, each after a line of 80 ``=`` and ``IDL: pkg/msg/Name``, with the
``#include`` lines rosidl generates. rosbags' parser (``get_types_from_idl``) reads the IDL but
not preprocessor lines, so they are blanked first (every included type has its own section).
Its result is then checked like :mod:`bagkit.decode.msgdef`'s: names that are identifiers,
types that are ROS 2 types, values that are Python values.
"""

from __future__ import annotations

import functools
import re
from typing import Any

from rosbags.typesys import get_types_from_idl

from bagkit.bag.definitions import PRIMITIVES
from bagkit.decode.errors import DefinitionError
from bagkit.decode.msgdef import Nodetype, TypeDef, check_identifier, type_name
from bagkit.words import counted

# rosbags' parser takes time and stack in proportion to the text: a generated IDL file of a
# large message is a few KiB, 256 KiB is far beyond any.
MAX_IDL_SECTION = 256 << 10
_PREPROCESSOR = re.compile(r"^[ \t]*#.*$", re.MULTILINE)
_VALUE_TYPES = (bool, int, float, str)


def parse_idl_section(text: str, header: str) -> dict[str, TypeDef]:
    """The types that one IDL section defines, checked.

    Args:
        text: the section's IDL (after its ``IDL:`` line).
        header: the section's ``pkg/msg/Name``, for messages.

    Raises:
        DefinitionError: the IDL does not parse, or defines what a ROS 2 type cannot hold.
    """
    return dict(_parse(text, header))  # a copy: the caller adds to it


@functools.lru_cache(maxsize=512)  # the same dependency sections recur across a bag's schemas
def _parse(text: str, header: str) -> dict[str, TypeDef]:
    if len(text) > MAX_IDL_SECTION:
        raise DefinitionError(
            f"IDL {header}: {counted(len(text), 'character')}, over {MAX_IDL_SECTION}"
        )
    source = _PREPROCESSOR.sub("", text)
    try:
        parsed = get_types_from_idl(source)
    except Exception as exc:  # the parser raises TypesysError, and others on odd input
        raise DefinitionError(f"IDL {header} does not parse{_where(source, exc)}") from None
    if not parsed:
        raise DefinitionError(f"IDL {header} defines no struct")
    return {
        _checked_name(name, header): _checked(definition, header)
        for name, definition in parsed.items()
    }


def _where(source: str, exc: Exception) -> str:
    """`` at line N`` from rosbags' message (``Could not parse:\\n<text>\\n<pos>\\n...``)."""
    parts = str(exc).split("\n")
    if len(parts) > 2 and parts[2].strip().isdigit():
        line = source.count("\n", 0, int(parts[2])) + 1
        return f" at line {line}"
    return f" ({type(exc).__name__})"


def _checked_name(name: str, header: str) -> str:
    try:
        return type_name(name)
    except DefinitionError as exc:
        raise DefinitionError(f"IDL {header}: {exc}") from None


def _checked(definition: Any, header: str) -> TypeDef:
    """rosbags' ``(constants, fields)`` of one type, each part checked."""
    try:
        constants, fields = definition
        for name, kind, value in constants:
            check_identifier(name, "constant")
            if kind not in PRIMITIVES or not isinstance(value, _VALUE_TYPES):
                raise DefinitionError(f"constant {name} of type {kind!r}")
        for name, desc in fields:
            check_identifier(name, "field")
            _check_desc(desc)
    except (TypeError, ValueError):
        raise DefinitionError(f"IDL {header}: an unexpected definition") from None
    except DefinitionError as exc:
        raise DefinitionError(f"IDL {header}: {exc}") from None
    return list(constants), list(fields)


def _check_desc(desc: Any) -> None:
    kind, rest = desc
    if kind == Nodetype.BASE:
        base, bound = rest
        if base not in PRIMITIVES or not isinstance(bound, int):
            raise DefinitionError(f"field type {base!r}")
    elif kind == Nodetype.NAME:
        type_name(rest)
    elif kind in (Nodetype.ARRAY, Nodetype.SEQUENCE):
        inner, count = rest
        nested = inner[0] not in (Nodetype.BASE, Nodetype.NAME)
        if not isinstance(count, int) or count < 0 or nested:
            raise DefinitionError("an array of arrays")
        _check_desc(inner)
    else:
        raise DefinitionError(f"field kind {kind!r}")
