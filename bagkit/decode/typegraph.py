"""Limits on the shape of message types, checked before anything walks a type recursively.

A bag's definitions are untrusted input: a type that holds itself (``A`` holds ``A``, ``A[]``,
or ``B`` that holds ``A``) or a chain of thousands of nested types would exhaust the Python
stack in every recursive walk (rosbags' code generation, leaf listing, layouts, flattening,
direct readers), and fixed arrays of structs multiply leaves (``A[1000]`` of ``B[1000]``). The
check here is iterative: a type is accepted when it is acyclic, at most ``MAX_TYPE_DEPTH`` types
deep, has at most ``MAX_LEAF_FIELDS`` leaves (each fixed-array element counted) and declares at
most ``MAX_DECLARED_FIELDS`` fields with the types it uses, which bounds the recursion and the
size of everything generated from it (rosbags generates a dataclass and a decoder per type: 10,000
declared fields took seconds to compile). ROS types are far inside these limits
(``nav_msgs/msg/Odometry``: 5 deep, 100 leaves, 29 declared fields).
"""

from __future__ import annotations

import weakref
from collections.abc import Iterable, Iterator, Mapping
from typing import Any

from bagkit.decode.errors import SchemaError
from bagkit.decode.msgdef import Nodetype, TypeDefinitions

MAX_TYPE_DEPTH = 100
MAX_LEAF_FIELDS = 100_000
MAX_DECLARED_FIELDS = 2_000

# Types already checked in a typestore (registered types never change).
_CHECKED: weakref.WeakKeyDictionary[TypeDefinitions, set[str]] = weakref.WeakKeyDictionary()


def check_type_graph(definitions: Mapping[str, Any], roots: Iterable[str]) -> None:
    """Check the types ``roots`` and all they use, as ``definitions`` (name -> rosbags field
    definitions ``(consts, fields)``) define them; names it does not define are not followed.

    Raises:
        SchemaError: a type holds itself, is nested too deep, has too many leaves or declares
            too many fields.
    """
    leaves: dict[str, int] = {}
    for root in roots:
        if root in leaves or root not in definitions:
            continue
        stack: list[tuple[str, Iterator[str]]] = [(root, _used_types(definitions[root]))]
        while stack:
            name, used = stack[-1]
            child = next(used, None)
            if child is None:
                stack.pop()
                leaves[name] = _leaf_count(definitions[name], leaves)
                if leaves[name] > MAX_LEAF_FIELDS:
                    raise SchemaError(f"{name} has more than {MAX_LEAF_FIELDS:,} leaf fields")
                continue
            if child in leaves or child not in definitions:
                continue
            path = [entry[0] for entry in stack]
            if child in path:
                cycle = " -> ".join([*path[path.index(child) :], child])
                raise SchemaError(f"{root} is recursive ({cycle})")
            if len(stack) >= MAX_TYPE_DEPTH:
                raise SchemaError(f"{root} nests types more than {MAX_TYPE_DEPTH} deep")
            stack.append((child, _used_types(definitions[child])))
        if _declared_fields(definitions, root) > MAX_DECLARED_FIELDS:
            raise SchemaError(
                f"{root} declares more than {MAX_DECLARED_FIELDS:,} fields with the types it uses"
            )


def check_registered(typestore: TypeDefinitions, typename: str) -> None:
    """:func:`check_type_graph` for a type of ``typestore``, once per typestore and type.

    Raises:
        SchemaError: see :func:`check_type_graph`.
    """
    checked = _CHECKED.get(typestore)
    if checked is None:
        checked = _CHECKED[typestore] = set()
    if typename not in checked:
        check_type_graph(typestore.fielddefs, (typename,))
        checked.add(typename)


def _element(desc: Any) -> tuple[Any, int]:
    """The element description of a field and how many leaves-worth of it the field holds."""
    kind, rest = desc
    if kind == Nodetype.ARRAY:
        return rest[0], rest[1]
    if kind == Nodetype.SEQUENCE:
        return rest[0], 1
    return desc, 1


def _used_types(definition: Any) -> Iterator[str]:
    for _, desc in definition[1]:
        element, _count = _element(desc)
        if element[0] == Nodetype.NAME:
            yield element[1]


def _declared_fields(definitions: Mapping[str, Any], root: str) -> int:
    """The fields declared by ``root`` and every type it uses (each type counted once)."""
    seen = {root}
    todo = [root]
    total = 0
    while todo:
        definition = definitions[todo.pop()]
        total += len(definition[1])
        for child in _used_types(definition):
            if child in definitions and child not in seen:
                seen.add(child)
                todo.append(child)
    return total


def _leaf_count(definition: Any, known: Mapping[str, int]) -> int:
    total = 0
    for _, desc in definition[1]:
        element, count = _element(desc)
        each = known.get(element[1], 1) if element[0] == Nodetype.NAME else 1
        total += count * each
    return total
