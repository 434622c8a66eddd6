"""Messages as flat ``{dotted path: value}`` dicts, and the same paths read from the schema alone.

Path rules (shared by stats and compare): nested fields ``linear_acceleration.x``; fixed-size
arrays one leaf per index ``orientation_covariance[0]``; variable-length sequences pooled over
their elements ``ranges[]`` and ``status[].level``. Booleans become 0/1, ``byte``/``char``
integers; strings stay strings so they can be compared exactly but are not numeric.
"""

from __future__ import annotations

import functools
from dataclasses import dataclass
from typing import Any

import numpy as np
from rosbags.interfaces import Nodetype
from rosbags.typesys.store import Typestore

STRING_TYPES = frozenset({"string", "wstring"})

# Value of one leaf: a scalar, or for a pooled leaf the list (or array) of every element's value.
FlatValue = int | float | str | list[Any] | np.ndarray


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


def leaf_fields(typestore: Typestore, typename: str) -> list[LeafField]:
    """Every leaf of ``typename`` in definition order, from the schema (no message needed).

    Raises:
        KeyError: ``typename`` (or a type it uses) is not in ``typestore``.
    """
    return list(_leaf_fields(typestore, typename))


# Typestores hash by identity and a type's fields never change once registered.
@functools.lru_cache(maxsize=1024)
def _leaf_fields(typestore: Typestore, typename: str) -> tuple[LeafField, ...]:
    leaves: list[LeafField] = []
    for name, desc in typestore.fielddefs[typename][1]:
        _walk_desc(typestore, name, desc, pooled=False, out=leaves)
    return tuple(leaves)


def _walk_desc(
    typestore: Typestore, path: str, desc: Any, *, pooled: bool, out: list[LeafField]
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
    msg: object, typestore: Typestore, *, numeric_only: bool = False
) -> dict[str, FlatValue]:
    """Flatten a rosbags message object into ``{path: value}``.

    Pooled leaves are always present (an empty list when the sequence is empty); their value is
    a numpy array for sequences of numbers, a list otherwise.

    Args:
        msg: a message decoded by ``typestore`` (``MessageTypes.deserialize``).
        typestore: the typestore that knows ``msg``'s type.
        numeric_only: drop string leaves (the view statistics use).
    """
    typename: str = msg.__msgtype__  # type: ignore[attr-defined]
    # Pre-filled in definition order; pooled leaves start as empty lists and are extended.
    out: dict[str, FlatValue] = {
        leaf.path: [] if leaf.pooled else 0 for leaf in _leaf_fields(typestore, typename)
    }
    _flatten_struct(out, "", msg, typename, typestore, pooled=False)
    if numeric_only:
        strings = {leaf.path for leaf in _leaf_fields(typestore, typename) if not leaf.numeric}
        return {k: v for k, v in out.items() if k not in strings}
    return out


def _scalar(value: Any) -> int | float | str:
    if isinstance(value, (bool, np.bool_)):
        return int(value)
    if isinstance(value, np.generic):
        return value.item()
    return value


def _flatten_struct(
    out: dict[str, FlatValue],
    prefix: str,
    msg: object,
    typename: str,
    ts: Typestore,
    *,
    pooled: bool,
) -> None:
    for name, desc in ts.fielddefs[typename][1]:
        _flatten_value(out, f"{prefix}{name}", getattr(msg, name), desc, ts, pooled=pooled)


def _flatten_value(
    out: dict[str, FlatValue], path: str, value: Any, desc: Any, ts: Typestore, *, pooled: bool
) -> None:
    kind, rest = desc
    if kind == Nodetype.BASE:
        if pooled:
            out[path].append(_scalar(value))  # type: ignore[union-attr]
        else:
            out[path] = _scalar(value)
    elif kind == Nodetype.NAME:
        _flatten_struct(out, f"{path}.", value, rest, ts, pooled=pooled)
    elif kind == Nodetype.ARRAY:
        sub = rest[0]
        for i, item in enumerate(value):
            _flatten_value(out, f"{path}[{i}]", item, sub, ts, pooled=pooled)
    else:
        sub = rest[0]
        key = f"{path}[]"
        if sub[0] == Nodetype.BASE and isinstance(value, np.ndarray) and not pooled:
            out[key] = value.astype(np.uint8) if value.dtype == np.bool_ else value
            return
        if sub[0] == Nodetype.BASE:
            if isinstance(out[key], np.ndarray):
                out[key] = list(out[key])  # type: ignore[arg-type]
            out[key].extend(_scalar(v) for v in value)  # type: ignore[union-attr]
            return
        for item in value:
            _flatten_value(out, key, item, sub, ts, pooled=True)
