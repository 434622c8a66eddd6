"""Leaf values read straight from CDR bytes, without building message objects.

The general decoding path (types that bulk decoding cannot place, and the messages it leaves
over) needs a few leaf values per message, not the message. rosbags' generated deserializer
builds an object per nested message and a numpy array per fixed-size array; here a function is
generated per type and set of paths that reads the values with ``struct``: consecutive
primitives and fixed-size primitive arrays in one ``unpack_from`` per run (a precompiled
``Struct`` for each of the 8 possible alignments of the run's start), strings and sequences
with their length prefixes. The values are those of :func:`bagkit.decode.field_getter` on the
decoded message (same paths, same types), which the tests hold it to.

Only little-endian plain CDR is read here; :func:`value_reader` hands anything else to the
object path.
"""

from __future__ import annotations

import struct
from collections.abc import Callable, Sequence
from typing import Any

import numpy as np

from bagkit.decode.cdr import STRUCT_CODES, WIDE_UNIT, wide_string
from bagkit.decode.errors import DecodeError, undecodable
from bagkit.decode.flatten import FlatValue
from bagkit.decode.layout import PRIMITIVE_FORMATS, U32
from bagkit.decode.msgdef import Nodetype, TypeDefinitions
from bagkit.decode.typegraph import check_registered

_DTYPES = {name: np.dtype(fmt) for name, fmt in PRIMITIVE_FORMATS.items()}


class UnsupportedTypeError(Exception):
    """The type has parts this reader does not handle (sequences of structs nested deeper
    than Python nests loops); use the object path."""


ValueReader = Callable[[bytes | memoryview], list[FlatValue]]


def value_reader(
    typestore: TypeDefinitions,
    typename: str,
    paths: Sequence[str],
    fallback: Callable[[bytes | memoryview], list[FlatValue]],
) -> ValueReader:
    """A function returning the values of ``paths`` of one ``typename`` payload, in order.

    Args:
        typestore: the typestore that defines ``typename``.
        typename: the canonical type name.
        paths: leaf paths (as :func:`bagkit.decode.leaf_fields` names them).
        fallback: the object path (``field_getter(...)(decoder(data))``), used for payloads
            that are not little-endian plain CDR and for types this reader does not handle.

    The returned function raises DecodeError when the bytes do not match the type; a length
    prefix is checked against the bytes left before anything is read or allocated for it.

    Raises:
        SchemaError: the type is recursive or too large (:mod:`bagkit.decode.typegraph`).
        KeyError: a path that the type does not have.
    """
    check_registered(typestore, typename)
    try:
        direct = _generate(typestore, typename, tuple(paths))
    except UnsupportedTypeError:
        return fallback

    def read(data: bytes | memoryview) -> list[FlatValue]:
        if len(data) < 4 or data[0] != 0 or data[1] != 1:
            return fallback(data)
        try:
            values, end = direct(data)
        except (struct.error, ValueError, IndexError, OverflowError) as exc:
            raise undecodable(typename, exc) from exc
        # CDR writers pad to 4 bytes at most (a reader of wide strings allows for rclpy's 4
        # more bytes per wide string in the end it returns).
        size = len(data) - 4
        if not size - 3 <= end <= size:
            problem = "it ends past the payload" if end > size else f"{size - end} bytes after it"
            raise DecodeError(f"{typename} message does not decode: {problem}")
        return values

    return read


class _Codegen:
    """Emits the statements of one reader: ``p`` is the position after the 4-byte header, ``n``
    the size of what follows it."""

    def __init__(self, typestore: TypeDefinitions, wanted: frozenset[str]) -> None:
        self.typestore = typestore
        self.wanted = wanted
        self.lines: list[str] = []
        self.namespace: dict[str, Any] = {"_u32": U32.unpack_from, "np": np, "_wide": wide_string}
        self.variables: dict[str, str] = {}  # leaf path -> local holding its value
        self.pooled_init: list[str] = []
        self._names = 0
        self._run: list[tuple[str, str, int | None]] = []  # (path, base, count or None)
        self.wide = False  # the type has wide strings: ``w`` counts them

    def name(self, stem: str) -> str:
        self._names += 1
        return f"{stem}{self._names}"

    def emit(self, line: str, depth: int) -> None:
        self.lines.append("    " * depth + line)

    # -- walking the type ---------------------------------------------------------------------

    def struct(self, typename: str, prefix: str, depth: int, pooled: bool) -> None:
        for field_name, desc in self.typestore.fielddefs[typename][1]:
            self.field(desc, f"{prefix}{field_name}", depth, pooled)

    def field(self, desc: Any, path: str, depth: int, pooled: bool) -> None:
        kind, rest = desc
        if kind == Nodetype.BASE:
            base = rest[0]
            if base in STRUCT_CODES:
                self._run.append((path, base, None))
                return
            self.flush(depth, pooled)
            self.string(path, base, depth, pooled)
            return
        if kind == Nodetype.NAME:
            self.struct(rest, f"{path}.", depth, pooled)
            return
        sub, length = rest
        element = sub[1][0] if sub[0] == Nodetype.BASE else None
        if kind == Nodetype.ARRAY:
            if element in STRUCT_CODES:
                self._run.append((path, element, length))
                return
            for i in range(length):
                self.field(sub, f"{path}[{i}]", depth, pooled)
            return
        self.flush(depth, pooled)
        self.sequence(sub, element, f"{path}[]", depth, pooled)

    # -- primitives ---------------------------------------------------------------------------

    def flush(self, depth: int, pooled: bool) -> None:
        """Emit the pending run of primitives as one unpack."""
        run, self._run = self._run, []
        if not run:
            return
        variants = []
        for start in range(8):
            fmt, pos = "<", start
            for _path, base, count in run:
                code, size = STRUCT_CODES[base], _DTYPES[base].itemsize
                if count == 0:
                    continue
                pad = -pos % size
                fmt += "x" * pad + (code if count is None else f"{count}{code}")
                pos += pad + size * (1 if count is None else count)
            compiled = struct.Struct(fmt)
            variants.append((compiled.unpack_from, pos - start))
        table = self.name("run")
        self.namespace[table] = tuple(variants)
        values, unpack, run_size = self.name("t"), self.name("u"), self.name("n")
        self.emit(f"{unpack}, {run_size} = {table}[p & 7]", depth)
        self.emit(f"{values} = {unpack}(b, 4 + p)", depth)
        self.emit(f"p += {run_size}", depth)
        index = 0
        for path, base, count in run:
            if count is None:
                self.leaf(path, base, f"{values}[{index}]", depth, pooled)
                index += 1
                continue
            for i in range(count):
                self.leaf(f"{path}[{i}]", base, f"{values}[{index + i}]", depth, pooled)
            index += count

    def leaf(self, path: str, base: str, expr: str, depth: int, pooled: bool) -> None:
        if path not in self.wanted:
            return
        self.store(path, f"int({expr})" if base == "bool" else expr, depth, pooled)

    def store(self, path: str, expr: str, depth: int, pooled: bool, *, many: bool = False) -> None:
        """Emit the code that keeps ``expr`` as the value of ``path`` (``many``: a sequence).

        Inside a sequence of structs (``pooled``) values are collected in the path's pool.
        """
        if not pooled:
            self.emit(f"{self.variable(path)} = {expr}", depth)
        elif many:
            self.emit(f"{self.pooled(path)}.extend({expr}.tolist())", depth)
        else:
            self.emit(f"{self.pooled(path)}.append({expr})", depth)

    def variable(self, path: str) -> str:
        return self.variables.setdefault(path, self.name("v"))

    def pooled(self, path: str) -> str:
        if path not in self.variables:
            self.variables[path] = self.name("l")
            self.pooled_init.append(f"{self.variables[path]} = []")
        return self.variables[path]

    # -- strings and sequences ----------------------------------------------------------------

    def length(self, depth: int, element_size: int = 1) -> str:
        """Emit: align to 4, read a uint32 length prefix; return its local's name.

        Every element of a string or sequence takes at least a byte (a wide string's units 4):
        a prefix larger than the bytes left is refused before a loop runs or anything is
        allocated for it.
        """
        count = self.name("c")
        self.emit("p = (p + 3) & -4", depth)
        self.emit(f"{count} = _u32(b, 4 + p)[0]", depth)
        self.emit("p += 4", depth)
        units = count if element_size == 1 else f"{count} * {element_size}"
        self.emit(f"if {units} > n - p:", depth)
        self.emit("raise ValueError('a length prefix says more than the payload holds')", depth + 1)
        return count

    def string(self, path: str, base: str, depth: int, pooled: bool) -> None:
        if base == "wstring":
            count = self.length(depth, WIDE_UNIT)
            if path in self.wanted:
                self.store(path, f"_wide(b, 4 + p, {count}, '<')", depth, pooled)
            self.emit(f"p += {WIDE_UNIT} * {count}", depth)
            self.emit("w += 1", depth)
            self.wide = True
            return
        count = self.length(depth)
        if path in self.wanted:
            # The count includes the terminating NUL (0 only from writers that omit it).
            text = f"bytes(b[4 + p : 4 + p + max({count} - 1, 0)]).decode()"
            self.store(path, text, depth, pooled)
        self.emit(f"p += {count}", depth)

    def sequence(self, sub: Any, element: str | None, path: str, depth: int, pooled: bool) -> None:
        count = self.length(depth)
        if element in STRUCT_CODES:
            self.primitive_sequence(path, element, count, depth, pooled)
            return
        item = self.name("i")
        self.emit(f"for {item} in range({count}):", depth)
        self.emit("pass", depth + 1)
        if element is not None:
            self.string(path, element, depth + 1, True)
        else:
            self.struct(sub[1], f"{path}.", depth + 1, True)
            self.flush(depth + 1, True)

    def primitive_sequence(
        self, path: str, base: str, count: str, depth: int, pooled: bool
    ) -> None:
        size = _DTYPES[base].itemsize
        if size > 1:
            # Writers align the first element only when there is one.
            self.emit(f"if {count}:", depth)
            self.emit(f"p = (p + {size - 1}) & -{size}", depth + 1)
        if path in self.wanted:
            dtype = self.name("d")
            self.namespace[dtype] = _DTYPES[base]
            array = f"np.frombuffer(b, {dtype}, {count}, 4 + p)"
            if base == "bool":
                array = f"({array} != 0).astype({dtype})"
            self.store(path, array, depth, pooled, many=True)
        self.emit(f"p += {count} * {size}", depth)


def _generate(
    typestore: TypeDefinitions, typename: str, paths: tuple[str, ...]
) -> Callable[[bytes | memoryview], tuple[list[FlatValue], int]]:
    gen = _Codegen(typestore, frozenset(paths))
    gen.struct(typename, "", 1, False)
    gen.flush(1, False)
    missing = [path for path in paths if path not in gen.variables]
    if missing:
        raise KeyError(f"{typename} has no leaf {', '.join(missing)}")
    body = [
        "def read(b):",
        "    p = 0",
        "    n = len(b) - 4",
        *(["    w = 0"] if gen.wide else []),
        *(f"    {line}" for line in gen.pooled_init),
        *gen.lines,
        # rclpy's payloads hold up to 4 bytes per wide string after the message: counted in.
        *([f"    p += min({WIDE_UNIT} * w, max(n - p, 0))"] if gen.wide else []),
        f"    return [{', '.join(gen.variables[path] for path in paths)}], p",
    ]
    try:
        code = compile("\n".join(body), f"<bagkit read {typename}>", "exec")
    except (SyntaxError, RecursionError) as exc:  # Python's limits on nested blocks
        raise UnsupportedTypeError(f"{typename}: {exc}") from exc
    exec(code, gen.namespace)
    reader: Callable[[bytes | memoryview], tuple[list[FlatValue], int]] = gen.namespace["read"]
    return reader
