"""Messages as flat ``{dotted path: value}`` dicts, and the same paths read from the schema alone.

Path rules (shared by stats and compare): nested fields ``linear_acceleration.x``; fixed-size
arrays one leaf per index ``orientation_covariance[0]``; variable-length sequences pooled over
their elements ``ranges[]`` and ``status[].level``. Booleans become 0/1, ``byte``/``char``
integers; strings stay strings so they can be compared exactly but are not numeric.
"""

from __future__ import annotations

import re
import weakref
from collections.abc import Callable
from dataclasses import dataclass
from typing import TYPE_CHECKING, Any, Union

from bagkit.decode.msgdef import Nodetype, TypeDefinitions, member_name
from bagkit.decode.typegraph import check_registered

if TYPE_CHECKING:
    import numpy as np

STRING_TYPES = frozenset({"string", "wstring"})

# Value of one leaf: a scalar, or for a pooled leaf the list (or array) of every element's value.
# numpy is named, not imported: reading a message to print it (echo) needs no numpy.
FlatValue = Union[int, float, str, list[Any], "np.ndarray"]


@dataclass(frozen=True, slots=True)
class LeafField:
    """One leaf of a message type.

    Attributes:
        path: dotted path, see the module docstring.
        base: the ROS primitive type (``float64``, ``bool``, ``string`` ...).
        pooled: inside a variable-length sequence: one value per element, not per message.
    """

    path: str
    base: str
    pooled: bool

    @property
    def numeric(self) -> bool:
        """Whether statistics apply (everything but strings)."""
        return self.base not in STRING_TYPES


def leaf_fields(typestore: TypeDefinitions, typename: str) -> list[LeafField]:
    """Every leaf of ``typename`` in definition order, from the schema (no message needed).

    Raises:
        KeyError: ``typename`` (or a type it uses) is not in ``typestore``.
        SchemaError: the type is recursive or too large (:mod:`bagkit.decode.typegraph`).
    """
    check_registered(typestore, typename)
    return list(_leaf_fields(typestore, typename))


# What is derived from a type is cached per typestore (a type's fields never change once
# registered) and goes away with it: each summary or comparison builds its own typestore.
_CACHE: weakref.WeakKeyDictionary[TypeDefinitions, dict[tuple[Any, ...], Any]] = (
    weakref.WeakKeyDictionary()
)


def _cached(typestore: TypeDefinitions, key: tuple[Any, ...], make: Callable[[], Any]) -> Any:
    per_store = _CACHE.get(typestore)
    if per_store is None:
        per_store = _CACHE[typestore] = {}
    value = per_store.get(key)
    if value is None:
        value = per_store[key] = make()
    return value


def _leaf_fields(typestore: TypeDefinitions, typename: str) -> tuple[LeafField, ...]:
    def make() -> tuple[LeafField, ...]:
        leaves: list[LeafField] = []
        for name, desc in typestore.fielddefs[typename][1]:
            _walk_desc(typestore, name, desc, pooled=False, out=leaves)
        return tuple(leaves)

    result: tuple[LeafField, ...] = _cached(typestore, ("leaves", typename), make)
    return result


def _walk_desc(
    typestore: TypeDefinitions, path: str, desc: Any, *, pooled: bool, out: list[LeafField]
) -> None:
    kind, rest = desc
    if kind == Nodetype.BASE:
        out.append(LeafField(path, rest[0], pooled))
    elif kind == Nodetype.NAME:
        for name, sub in typestore.fielddefs[rest][1]:
            _walk_desc(typestore, f"{path}.{name}", sub, pooled=pooled, out=out)
    elif kind == Nodetype.ARRAY:
        sub, length = rest
        for i in range(length):
            _walk_desc(typestore, f"{path}[{i}]", sub, pooled=pooled, out=out)
    else:  # SEQUENCE, bounded or not
        _walk_desc(typestore, f"{path}[]", rest[0], pooled=True, out=out)


def flatten_message(
    msg: object, typestore: TypeDefinitions, *, numeric_only: bool = False
) -> dict[str, FlatValue]:
    """Flatten a rosbags message object into ``{path: value}``, in definition order.

    Pooled leaves are always present (an empty list when the sequence is empty); their value is
    a numpy array for a top-level sequence of numbers, a list otherwise.

    Args:
        msg: a message decoded by ``typestore`` (``MessageTypes.deserialize``).
        typestore: the typestore that knows ``msg``'s type.
        numeric_only: drop string leaves (the view statistics use).
    """
    typename: str = msg.__msgtype__  # type: ignore[attr-defined]
    flatten = _cached(
        typestore,
        ("flatten", typename, numeric_only),
        lambda: _generate(typestore, typename, None, numeric_only=numeric_only),
    )
    return flatten(msg)


def _as_list(value: Any) -> list[Any]:
    return value.tolist() if hasattr(value, "tolist") else list(value)  # numpy's, or a list


def field_getter(
    typestore: TypeDefinitions, typename: str, paths: tuple[str, ...]
) -> Callable[[object], list[FlatValue]]:
    """A function returning the values of ``paths`` of a ``typename`` message, in that order.

    Values are those of :func:`flatten_message`; this skips building the dict (statistics read
    a few fields of millions of messages).

    Raises:
        KeyError: a path that ``typename`` does not have.
    """
    getter: Callable[[object], list[FlatValue]] = _cached(
        typestore,
        ("get", typename, paths),
        lambda: _generate(typestore, typename, paths, numeric_only=False),
    )
    return getter


# Flattening walks the type once, here, and generates a function of attribute reads and list
# comprehensions: a recursive walk per message costs several times rosbags' deserialization.
def _generate(
    typestore: TypeDefinitions, typename: str, paths: tuple[str, ...] | None, *, numeric_only: bool
) -> Any:
    """``flatten(m) -> dict`` (all leaves when ``paths`` is None) or ``get(m) -> list``."""
    check_registered(typestore, typename)
    gen = _Codegen(typestore, numeric_only)
    gen.struct("m", typename, "", [])
    if paths is None:
        result = ["    return {", *(f"        {p!r}: {e}," for p, e in gen.entries), "    }"]
    else:
        expressions = dict(gen.entries)
        result = [
            "    return [",
            *(
                f"        {e},"
                for e in _splat([expressions[p] for p in paths], list(expressions.values()))
            ),
            "    ]",
        ]
    body = "\n".join(["def generated(m):", *(f"    {line}" for line in gen.prelude), *result])
    import numpy as np

    namespace: dict[str, Any] = {"_as_list": _as_list, "_ndarray": np.ndarray, "np": np}
    exec(compile(body, f"<bagkit flatten {typename}>", "exec"), namespace)
    return namespace["generated"]


_ITEM = re.compile(r"(a\d+)\[(\d+)\]")


def _splat(expressions: list[str], every: list[str]) -> list[str]:
    """``a1[0], a1[1] ... a1[8]`` (a whole array's list, in order) -> ``*a1``.

    ``every`` holds the expressions of all leaves: it tells each array's length.
    """
    lengths: dict[str, int] = {}
    for expr in every:
        if match := _ITEM.fullmatch(expr):
            lengths[match[1]] = lengths.get(match[1], 0) + 1
    out: list[str] = []
    i = 0
    while i < len(expressions):
        match = _ITEM.fullmatch(expressions[i])
        if match and match[2] == "0":
            run = [f"{match[1]}[{k}]" for k in range(lengths[match[1]])]
            if expressions[i : i + len(run)] == run:
                out.append(f"*{match[1]}")
                i += len(run)
                continue
        out.append(expressions[i])
        i += 1
    return out


class _Codegen:
    """Builds the body of a flattening function: prelude statements and (path, expression)."""

    def __init__(self, typestore: TypeDefinitions, numeric_only: bool) -> None:
        self.typestore = typestore
        self.numeric_only = numeric_only
        self.prelude: list[str] = []
        self.entries: list[tuple[str, str]] = []
        self._names = 0

    def _var(self, stem: str) -> str:
        self._names += 1
        return f"{stem}{self._names}"

    def struct(self, expr: str, typename: str, prefix: str, loops: list[str]) -> None:
        for name, desc in self.typestore.fielddefs[typename][1]:
            attr = f"{expr}.{member_name(name)}"
            self.value(attr, desc, f"{prefix}{name}", loops)

    def _emit(self, path: str, expr: str, loops: list[str]) -> None:
        self.entries.append((path, f"[{expr} {' '.join(loops)}]" if loops else expr))

    def value(self, expr: str, desc: Any, path: str, loops: list[str]) -> None:
        kind, rest = desc
        if kind == Nodetype.NAME:
            self.struct(expr, rest, f"{path}.", loops)
            return
        if kind == Nodetype.BASE:
            base = rest[0]
            if base in STRING_TYPES and self.numeric_only:
                return
            self._emit(path, f"int({expr})" if base == "bool" else expr, loops)
            return
        sub = rest[0]
        base = sub[1][0] if sub[0] == Nodetype.BASE else None
        if base in STRING_TYPES and self.numeric_only:
            return
        if kind == Nodetype.ARRAY:
            if base is None or base in STRING_TYPES:
                for i in range(rest[1]):
                    self.value(f"{expr}[{i}]", sub, f"{path}[{i}]", loops)
                return
            # Numbers: one tolist() (Python scalars), then index it.
            if loops:
                items = self._var("a")
                loops = [*loops, f"for {items} in ({_as_list_call(expr)},)"]
            else:
                items = self._var("a")
                # Inline: decoded messages always hold ndarrays, a call per array adds up.
                self.prelude.append(f"{items} = {expr}")
                self.prelude.append(
                    f"{items} = {items}.tolist() "
                    f"if {items}.__class__ is _ndarray else list({items})"
                )
            for i in range(rest[1]):
                item = f"{items}[{i}]"
                self._emit(f"{path}[{i}]", f"int({item})" if base == "bool" else item, loops)
            return
        key = f"{path}[]"
        if base is None:
            item = self._var("x")
            self.struct(item, sub[1], f"{key}.", [*loops, f"for {item} in {expr}"])
            return
        if not loops:
            if base in STRING_TYPES:
                self._emit(key, f"list({expr})", loops)
            elif base == "bool":
                self._emit(key, f"np.asarray({expr}, dtype=np.uint8)", loops)
            else:
                self._emit(
                    key, f"{expr} if isinstance({expr}, np.ndarray) else list({expr})", loops
                )
            return
        item = self._var("v")
        source = expr if base in STRING_TYPES else _as_list_call(expr)
        self._emit(
            key, f"int({item})" if base == "bool" else item, [*loops, f"for {item} in {source}"]
        )


def _as_list_call(expr: str) -> str:
    return f"_as_list({expr})"
