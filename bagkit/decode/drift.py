"""Drift: how a topic's stored definition differs from the one installed today, per field.

A bag keeps the definition its messages were written with; the system that replays or checks
it uses the definition installed now. Both are parsed into typestores (so ``.msg``, ``.srv``
event and action texts are compared alike) and walked together from the topic's type: every
field added, removed, retyped (type, array length or bound) or moved, and every constant
added, removed or changed, is named by its path (``header.stamp.sec``, ``points[*].x``).
"""

from __future__ import annotations

from collections.abc import Iterable, Mapping
from dataclasses import dataclass, field
from enum import Enum
from pathlib import Path
from typing import Any

from bagkit.bag.definitions import canonical_type_name, message_definition, type_description_hash
from bagkit.bag.errors import UnknownMessageTypeError
from bagkit.bag.messages import TopicInfo
from bagkit.bag.reader import BagReader
from bagkit.decode.message_types import MessageTypes
from bagkit.decode.msgdef import Nodetype

# Nesting deeper than this is reported as one change rather than walked (hostile definitions).
MAX_DEPTH = 32


class DriftStatus(str, Enum):
    """How a topic's stored definition compares with the installed one."""

    SAME = "same"
    DRIFTED = "drifted"
    NOT_INSTALLED = "not installed"
    UNREADABLE = "unreadable"


@dataclass(frozen=True, slots=True)
class TopicDrift:
    """One topic's comparison.

    Attributes:
        topic, type: the topic and its bag type.
        status: see :class:`DriftStatus`.
        changes: one line per difference (``added: variance (float32)``), in field order;
            for ``NOT_INSTALLED`` and ``UNREADABLE`` the reason.
    """

    topic: str
    type: str
    status: DriftStatus
    changes: list[str] = field(default_factory=list)

    def to_dict(self) -> dict[str, Any]:
        """A JSON-ready form."""
        return {
            "topic": self.topic,
            "type": self.type,
            "status": self.status.value,
            "changes": self.changes,
        }


def describe(desc: Any) -> str:
    """A field description as the ``.msg`` type it stands for (``float64[<=3]``)."""
    kind, rest = desc
    if kind == Nodetype.BASE:
        base, bound = rest
        return f"{base}<={bound}" if bound else str(base)
    if kind == Nodetype.NAME:
        return str(rest)
    inner, size = rest
    if kind == Nodetype.ARRAY:
        return f"{describe(inner)}[{size}]"
    return f"{describe(inner)}[<={size}]" if size else f"{describe(inner)}[]"


def _nested(desc: Any) -> tuple[str | None, str]:
    """The message type a field holds (None for primitives) and the path suffix to reach it."""
    kind, rest = desc
    if kind == Nodetype.NAME:
        return str(rest), ""
    if kind in (Nodetype.ARRAY, Nodetype.SEQUENCE):
        inner, _ = rest
        nested, _ = _nested(inner)
        return nested, "[*]"
    return None, ""


def definition_changes(
    typename: str, old: Mapping[str, Any], new: Mapping[str, Any], prefix: str = "", depth: int = 0
) -> list[str]:
    """The differences between ``typename`` in typestore field definitions ``old`` and ``new``.

    Both map type names to rosbags' ``(constants, fields)``; a type missing on one side is
    one change. Fields are compared by name, then their order (which changes the layout).
    """
    where = prefix.rstrip(".") or typename
    if typename not in old or typename not in new:
        side = "stored" if typename not in old else "installed"
        return [f"{where}: no {side} definition of {typename}"]
    if depth > MAX_DEPTH:
        return [f"{where}: nested deeper than {MAX_DEPTH} levels, not compared"]
    old_constants, old_fields = old[typename]
    new_constants, new_fields = new[typename]
    before, after = dict(old_fields), dict(new_fields)
    changes = _constant_changes(prefix, old_constants, new_constants)
    for name, desc in old_fields:
        if name not in after:
            changes.append(f"removed: {prefix}{name} ({describe(desc)})")
        elif describe(desc) != describe(after[name]):
            changes.append(
                f"type changed: {prefix}{name} ({describe(desc)} -> {describe(after[name])})"
            )
        else:
            nested, suffix = _nested(desc)
            if nested is not None:
                changes += definition_changes(
                    nested, old, new, f"{prefix}{name}{suffix}.", depth + 1
                )
    changes += [
        f"added: {prefix}{name} ({describe(desc)})"
        for name, desc in new_fields
        if name not in before
    ]
    kept_old = [name for name, _ in old_fields if name in after]
    kept_new = [name for name, _ in new_fields if name in before]
    if kept_old != kept_new:
        changes.append(f"order changed: {where} ({', '.join(kept_old)} -> {', '.join(kept_new)})")
    return changes


def _constant_changes(
    prefix: str, old: Iterable[tuple[str, str, Any]], new: Iterable[tuple[str, str, Any]]
) -> list[str]:
    before = {name: (kind, value) for name, kind, value in old}
    after = {name: (kind, value) for name, kind, value in new}
    changes = [f"constant removed: {prefix}{name}" for name in before if name not in after]
    changes += [
        f"constant changed: {prefix}{name} ({before[name][0]} {before[name][1]!r} -> "
        f"{after[name][0]} {after[name][1]!r})"
        for name in before
        if name in after and before[name] != after[name]
    ]
    changes += [
        f"constant added: {prefix}{name} ({kind} {value!r})"
        for name, (kind, value) in after.items()
        if name not in before
    ]
    return changes


def topic_drift(info: TopicInfo, stored_text: str | None) -> TopicDrift:
    """Compare ``info``'s stored definition (``stored_text``; None: the bag has none) with the
    installed one.

    Where the bag keeps a type hash (RIHS01) and the installed type has the same, the types
    are the same without parsing.
    """
    name = canonical_type_name(info.type)
    try:
        installed_text = message_definition(name)
    except UnknownMessageTypeError as exc:
        return TopicDrift(info.name, info.type, DriftStatus.NOT_INSTALLED, [str(exc)])
    if info.type_description_hash and info.type_description_hash == _installed_hash(name):
        return TopicDrift(info.name, info.type, DriftStatus.SAME)
    if stored_text is None:
        return TopicDrift(
            info.name, info.type, DriftStatus.UNREADABLE, ["the bag stores no definition"]
        )
    stored, installed = MessageTypes(), MessageTypes()
    stored.add(name, stored_text)
    installed.add(name, installed_text)
    for types, side in ((stored, "stored"), (installed, "installed")):
        if name in types.problems:
            return TopicDrift(
                info.name, info.type, DriftStatus.UNREADABLE, [f"{side}: {types.problems[name]}"]
            )
    changes = definition_changes(name, stored.typestore.fielddefs, installed.typestore.fielddefs)
    status = DriftStatus.DRIFTED if changes else DriftStatus.SAME
    return TopicDrift(info.name, info.type, status, changes)


def _installed_hash(name: str) -> str:
    try:
        return type_description_hash(name)
    except UnknownMessageTypeError:
        return ""


def bag_drift(bag: str | Path) -> list[TopicDrift]:
    """:func:`topic_drift` of each topic of ``bag`` (sorted by name).

    Raises:
        BagError: the bag cannot be opened.
    """
    with BagReader(bag, allow_empty=True) as reader:  # definitions need no messages
        return [
            topic_drift(info, reader.topic_definitions.get(name, reader.definitions.get(info.type)))
            for name, info in sorted(reader.topics.items())
        ]
