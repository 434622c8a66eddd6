"""Message objects read from CDR: bagkit's decoder of every type into objects.

Generating one type's reader here costs a fraction of rosbags' code generation (15 functions
a type, of which a decoder uses one) and reads faster too (benchmarks/README.md, "Start-up,
sixth pass"); rosbags' (de)serializers also have no ``wstring``. ROS 2 (rmw_fastrtps) writes
one as a ``uint32`` count of UTF-16 code units, then each unit widened to 4 bytes
(``wchar_t``), with no terminator; its size estimate, which
``rclpy.serialization.serialize_message`` returns as the payload, counts 4 bytes more per wide
string (a terminator it never writes), so a payload may end up to 4 bytes per wide string
after the message.

:func:`object_reader` generates a reader per type and byte order that builds the same objects
as rosbags' would: the typestore's classes, numpy arrays for arrays and sequences of numbers,
lists for the rest; or, for a caller that prints (``echo``), lists of Python numbers, so that
reading a message imports no numpy. The generated source holds no name from the definition:
fields are passed to the class by position and nested types' readers are looked up in a table.
"""

from __future__ import annotations

import struct
from collections.abc import Callable
from typing import Any

from bagkit.decode.msgdef import Nodetype, TypeDefinitions

# (object, position after it, wide strings read) from (payload after the header, position).
ObjectReader = Callable[[Any, int], tuple[object, int, int]]
# (object, its end) from a payload after its header.
PayloadReader = Callable[[Any], tuple[object, int]]

# struct code of each primitive, one place for both decoders (direct reads ``byte`` as uint8).
STRUCT_CODES: dict[str, str] = {
    "bool": "?",
    "byte": "B",
    "char": "B",
    "int8": "b",
    "uint8": "B",
    "int16": "h",
    "uint16": "H",
    "int32": "i",
    "uint32": "I",
    "int64": "q",
    "uint64": "Q",
    "float32": "f",
    "float64": "d",
}
# As rosbags reads them: ``byte`` signed, so the objects built here equal rosbags' own.
_CODES = {**STRUCT_CODES, "byte": "b"}
# numpy types as rosbags makes them (numpy.byte is int8).
_NUMPY = {"bool": "?", "byte": "i1", "char": "u1", "int8": "i1", "uint8": "u1"} | {
    f"{kind}{bits}": f"{code}{bits // 8}"
    for kind, code in (("int", "i"), ("uint", "u"), ("float", "f"))
    for bits in (16, 32, 64)
    if kind != "float" or bits > 16
}
WIDE_UNIT = 4


def wide_string(data: Any, offset: int, count: int, order: str) -> str:
    """The text of ``count`` 4-byte UTF-16 code units at ``offset``.

    Raises:
        ValueError: the units are not UTF-16 (too large, a lone surrogate, past the end).
    """
    try:
        units = struct.unpack_from(f"{order}{count}I", data, offset)
        return struct.pack(f"<{count}H", *units).decode("utf-16-le")
    except struct.error as exc:  # a unit over 0xFFFF, or past the end
        raise ValueError(f"a wide string that is not UTF-16: {exc}") from None


def has_wide_strings(typestore: TypeDefinitions, typename: str) -> bool:
    """Whether ``typename`` or a type it uses has a ``wstring``."""
    todo, seen = [typename], {typename}
    while todo:
        for _, desc in typestore.fielddefs[todo.pop()][1]:
            element = desc if desc[0] in (Nodetype.BASE, Nodetype.NAME) else desc[1][0]
            if element[0] == Nodetype.BASE and element[1][0] == "wstring":
                return True
            if element[0] == Nodetype.NAME and element[1] not in seen:
                seen.add(element[1])
                todo.append(element[1])
    return False


def object_reader(
    typestore: TypeDefinitions, typename: str, *, little: bool, lists: bool = False
) -> ObjectReader:
    """The reader of ``typename`` payloads (after the 4-byte header) in one byte order;
    ``lists``: arrays of numbers as lists of Python numbers, not numpy arrays.

    A reader raises ValueError, IndexError or struct.error on bytes that do not match.
    The type graph must have been checked (:func:`bagkit.decode.typegraph.check_type_graph`).
    """
    readers: dict[str, ObjectReader] = {}
    order = "<" if little else ">"

    def build(name: str) -> ObjectReader:
        if name not in readers:
            readers[name] = _Codegen(typestore, order, build, lists=lists).generate(name)
        return readers[name]

    return build(typename)


def payload_reader(
    typestore: TypeDefinitions, typename: str, *, little: bool, lists: bool = False
) -> PayloadReader:
    """:func:`object_reader` of a whole payload (after its 4-byte header), the end it returns
    moved past rclpy's 4 bytes per wide string when present: a caller checks trailing bytes as
    for any CDR payload."""
    read = object_reader(typestore, typename, little=little, lists=lists)

    def deserialize(data: Any) -> tuple[object, int]:
        message, end, wide = read(data, 0)
        return message, end + min(WIDE_UNIT * wide, max(len(data) - end, 0))

    return deserialize


class _Codegen:
    """The statements of one type's reader: ``b`` the payload, ``p`` the position, ``w`` the
    wide strings read, ``v`` the field values."""

    def __init__(
        self,
        typestore: TypeDefinitions,
        order: str,
        build: Callable[[str], ObjectReader],
        *,
        lists: bool,
    ) -> None:
        self.typestore = typestore
        self.order = order
        self.build = build
        self.lists = lists
        self.lines: list[str] = []
        self.namespace: dict[str, Any] = {
            "_u32": struct.Struct(f"{order}I").unpack_from,
            "_unpack": struct.unpack_from,
            "_wide": wide_string,
            "_order": order,
        }

    def emit(self, line: str, depth: int = 1) -> None:
        self.lines.append("    " * depth + line)

    def constant(self, value: Any) -> str:
        name = f"k{len(self.namespace)}"
        self.namespace[name] = value
        return name

    def generate(self, typename: str) -> ObjectReader:
        self.namespace["_cls"] = self.typestore.types[typename]
        self.emit("v = []")
        self.emit("w = 0")
        for _, desc in self.typestore.fielddefs[typename][1]:
            self.emit(f"v.append({self.value(desc, 1)})")
        self.emit("return _cls(*v), p, w")
        source = "\n".join(["def read(b, p):", *self.lines])
        exec(compile(source, f"<bagkit cdr {typename}>", "exec"), self.namespace)
        reader: ObjectReader = self.namespace["read"]
        return reader

    def value(self, desc: Any, depth: int) -> str:
        """Emit the statements reading one value; return the expression that holds it."""
        kind, rest = desc
        if kind == Nodetype.BASE:
            return self.scalar(rest[0], depth)
        if kind == Nodetype.NAME:
            reader = self.constant(self.build(rest))
            item = f"o{len(self.lines)}"
            self.emit(f"{item}, p, n = {reader}(b, p)", depth)
            self.emit("w += n", depth)
            return item
        sub, size = rest
        base = sub[1][0] if sub[0] == Nodetype.BASE else None
        count = str(size)
        if kind == Nodetype.SEQUENCE:
            count = self.length(WIDE_UNIT if base == "wstring" else 1, depth)
        if base in _CODES:
            return self.numbers(base, count, depth)
        items = f"l{len(self.lines)}"
        self.emit(f"{items} = []", depth)
        self.emit(f"for _ in range({count}):", depth)
        self.emit(f"{items}.append({self.value(sub, depth + 1)})", depth + 1)
        return items

    def scalar(self, base: str, depth: int) -> str:
        if base in _CODES:
            unpack = self.constant(struct.Struct(self.order + _CODES[base]).unpack_from)
            size = struct.calcsize(_CODES[base])
            item = f"s{len(self.lines)}"
            self.emit(f"p = (p + {size - 1}) & -{size}", depth)
            self.emit(f"{item} = {unpack}(b, p)[0]", depth)
            self.emit(f"p += {size}", depth)
            return item
        item = f"t{len(self.lines)}"
        if base == "wstring":
            count = self.length(WIDE_UNIT, depth)
            self.emit(f"{item} = _wide(b, p, {count}, _order)", depth)
            self.emit(f"p += {WIDE_UNIT} * {count}", depth)
            self.emit("w += 1", depth)
            return item
        count = self.length(1, depth)
        # A CDR string counts its NUL terminator, which must be there (as rosbags checks).
        self.emit(f"if {count} < 1 or b[p + {count} - 1] != 0:", depth)
        self.emit("raise ValueError('a string without its terminator')", depth + 1)
        self.emit(f"{item} = bytes(b[p : p + {count} - 1]).decode()", depth)
        self.emit(f"p += {count}", depth)
        return item

    def length(self, element_size: int, depth: int) -> str:
        """Emit: align to 4, read a length prefix, refuse one the bytes left cannot hold."""
        count = f"c{len(self.lines)}"
        self.emit("p = (p + 3) & -4", depth)
        self.emit(f"{count} = _u32(b, p)[0]", depth)
        self.emit("p += 4", depth)
        self.emit(f"if {count} * {element_size} > len(b) - p:", depth)
        self.emit("raise ValueError('a length prefix says more than the payload holds')", depth + 1)
        return count

    def numbers(self, base: str, count: str, depth: int) -> str:
        if self.lists:
            return self.number_list(base, count, depth)
        import numpy as np  # here: a reader of lists (echo's) needs no numpy

        self.namespace["_np"] = np
        code = _NUMPY[base]
        dtype = np.dtype(code if code[-1] in "?1" else self.order + code)
        native = self.constant(dtype.newbyteorder("="))
        typed = self.constant(dtype)
        item = f"a{len(self.lines)}"
        if dtype.itemsize > 1:  # writers align the first element only when there is one
            self.emit(f"if {count}:", depth)
            self.emit(f"p = (p + {dtype.itemsize - 1}) & -{dtype.itemsize}", depth + 1)
        self.emit(f"{item} = _np.frombuffer(b, {typed}, {count}, p)", depth)
        if not dtype.isnative:
            self.emit(f"{item} = {item}.astype({native})", depth)
        self.emit(f"p += {count} * {dtype.itemsize}", depth)
        return item

    def number_list(self, base: str, count: str, depth: int) -> str:
        code = _CODES[base]
        size = struct.calcsize(code)
        item = f"a{len(self.lines)}"
        if size > 1:  # writers align the first element only when there is one
            self.emit(f"if {count}:", depth)
            self.emit(f"p = (p + {size - 1}) & -{size}", depth + 1)
        self.emit(f"{item} = list(_unpack(f'{self.order}{{{count}}}{code}', b, p))", depth)
        self.emit(f"p += {count} * {size}", depth)
        return item
