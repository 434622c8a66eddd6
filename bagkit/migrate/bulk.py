"""Many payloads of one topic migrated at once, column by column, when the layouts allow it.

When the stored and the new type both have a CDR layout (:mod:`bagkit.decode.layout`: strings
and sequences of primitives only), the new one bounds no string or sequence, and the migration
runs no rule, every new slot is either a slot of the old layout with the same path and type
(copied) or a new one (zero, the empty string, the empty sequence), and an old slot the new
layout lacks is dropped (the planner has refused that without ``--allow-drop``): the
payloads of a chunk are decoded with :func:`~bagkit.decode.bulk.decode_bulk`, and each group
of one layout is built with numpy by the same byte operations on every row (constants
broadcast, the same spans copied), so that its rows differ only in the values copied; the
caller checks them (:meth:`~bagkit.migrate.topics.TopicMigration.payloads`). Anything else
(a type change, a bound, a rule, a string that is not ASCII, a bool that is not 0 or 1, a
payload bulk decoding leaves over) goes message by message.
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import Any, NamedTuple

import numpy as np

from bagkit.decode.bulk import decode_bulk
from bagkit.decode.errors import SchemaError
from bagkit.decode.layout import CDR_LE, U32, CdrLayout, NeedLength
from bagkit.decode.msgdef import Nodetype, TypeDefinitions

_EMPTY_STRING = 1  # a CDR string's length counts its NUL


class BulkGroup(NamedTuple):
    """Payloads of one old layout migrated at once.

    Attributes:
        indexes: the payloads' indexes in the batch.
        rows: a 2-D uint8 array, one size per group: ``rows[i]`` holds the payload at
            ``indexes[i]``, after the room the caller asked for.
        prefixes: the old payloads' length prefixes (:meth:`BulkMigration.prefixes`), which
            fix both layouts.
    """

    indexes: np.ndarray
    rows: np.ndarray
    prefixes: tuple[int, ...]


# None: not taken in bulk.
PayloadRows = list[BulkGroup] | None


@dataclass(frozen=True)
class BulkMigration:
    """The slot mapping between two layouts of one type.

    Attributes:
        old, new: the layouts.
        sources: per new slot, the index of the old slot it copies (None: a new slot).
    """

    old: CdrLayout
    new: CdrLayout
    sources: tuple[int | None, ...]

    @classmethod
    def of(cls, old: TypeDefinitions, new: TypeDefinitions, name: str) -> BulkMigration | None:
        """The bulk migration of ``name`` between the two typestores, or None when the
        layouts do not allow one (see the module's docstring)."""
        try:
            old_layout, new_layout = CdrLayout.of(old, name), CdrLayout.of(new, name)
        except SchemaError:
            return None
        if old_layout is None or new_layout is None or _bounded(new, name):
            return None
        by_path = {slot.path: i for i, slot in enumerate(old_layout.slots)}
        sources: list[int | None] = []
        for slot in new_layout.slots:
            index = by_path.get(slot.path)
            if index is not None and old_layout.slots[index] != slot:
                return None  # retyped: converted message by message
            sources.append(index)
        return cls(old_layout, new_layout, tuple(sources))

    def payloads(
        self, buf: np.ndarray, starts: np.ndarray, lengths: np.ndarray, room: int = 0
    ) -> PayloadRows:
        """The migrated payloads at ``starts``/``lengths`` of ``buf`` (uint8) as groups of
        rows of equal size (:class:`BulkGroup`), each payload after ``room`` zero bytes left for the
        caller; None when one of them does not decode in bulk (the caller goes message by
        message)."""
        groups, leftover = decode_bulk(buf, starts, lengths, self.old)
        if len(leftover):
            return None
        found = []
        for group in groups:
            if not self._decodable(group.values):
                return None
            old_lengths = self.prefixes(buf, int(starts[group.indexes[0]]))
            made = self._records(group.values, old_lengths, room)
            if made is None:
                return None
            found.append(BulkGroup(group.indexes, made, old_lengths))
        return found

    def prefixes(self, buf: np.ndarray, start: int) -> tuple[int, ...]:
        """The length prefixes of the old payload at ``start`` of ``buf``, already decoded in
        bulk (they fit): what fixes both layouts of its group, and the bytes copied."""
        lengths: tuple[int, ...] = ()
        while True:
            step = self.old.resolve(lengths)
            if not isinstance(step, NeedLength):
                return lengths
            at = start + step.offset
            lengths += (int(buf[at : at + 4].view("<u4")[0]),)

    def _decodable(self, values: np.ndarray) -> bool:
        """Whether every string of ``values`` is ASCII and every bool 0 or 1: values that the
        message-by-message decoder takes (it refuses a string that is not UTF-8), as it takes
        every number. Others go message by message, which keeps or refuses them."""
        fields = values.dtype.fields
        assert fields is not None  # structured: one field per slot with values
        for index, slot in enumerate(self.old.slots):
            if slot.base not in {"string", "bool"} or str(index) not in fields:
                continue
            column = values[str(index)]
            if slot.base == "string":
                if (column[:, None].view(np.uint8) >= 0x80).any():
                    return False
            elif (column > 1).any():
                return False
        return True

    def _records(
        self, values: np.ndarray, old_lengths: tuple[int, ...], room: int
    ) -> np.ndarray | None:
        """The new payloads of one group (rows of bytes after ``room``); None when the new
        layout needs a length it cannot place."""
        prefixed = [i for i, slot in enumerate(self.old.slots) if slot.count is None]
        by_old = dict(zip(prefixed, old_lengths, strict=True))
        new_lengths = tuple(
            by_old[source]
            if source is not None
            else (_EMPTY_STRING if slot.base == "string" else 0)
            for slot, source in zip(self.new.slots, self.sources, strict=True)
            if slot.count is None
        )
        resolved = self.new.resolve(new_lengths)
        if isinstance(resolved, NeedLength):
            return None
        size = resolved.dtype.itemsize
        # What every row holds before the copied values: the room and padding zero, the CDR
        # header, the length prefixes; repeated into all rows at once.
        template = np.zeros(room + size, np.uint8)
        template[room : room + len(CDR_LE)] = np.frombuffer(CDR_LE, np.uint8)
        for offset, length in zip(_prefix_offsets(self.new, new_lengths), new_lengths, strict=True):
            at = room + offset
            template[at : at + 4] = np.frombuffer(U32.pack(length), np.uint8)
        rows = np.empty((len(values), room + size), np.uint8)
        old_bytes = values[:, None].view(np.uint8)  # one row of bytes per payload (a view)
        filled = 0  # the template is broadcast only where no span is copied: each byte once
        for at, source_at, length in sorted(self._spans(values.dtype, resolved.dtype)):
            _fill(rows, template, filled, room + at)
            # Each row's span as one item of ``length`` bytes: a copy per row, not per byte.
            span = np.dtype((np.void, length))
            target = rows[:, room + at : room + at + length].view(span)
            target[:, 0] = old_bytes[:, source_at : source_at + length].view(span)[:, 0]
            filled = room + at + length
        _fill(rows, template, filled, room + size)
        return rows

    def _spans(self, old: np.dtype, new: np.dtype) -> list[tuple[int, int, int]]:
        """``(offset in new, offset in old, length)`` of the bytes copied from old payloads:
        each slot with values on both sides, slots adjacent on both sides joined (the padding
        between slots is never copied: it stays zero, as a serializer writes it)."""
        old_fields, new_fields = old.fields, new.fields
        assert old_fields is not None and new_fields is not None  # structured: one per slot
        spans: list[list[int]] = []
        for index, source in enumerate(self.sources):
            if source is None or str(source) not in old_fields:
                continue
            field_type, at = new_fields[str(index)][:2]
            source_at = old_fields[str(source)][1]
            last = spans[-1] if spans else None
            if last and last[0] + last[2] == at and last[1] + last[2] == source_at:
                last[2] += field_type.itemsize
            else:
                spans.append([at, source_at, field_type.itemsize])
        return [(at, source_at, length) for at, source_at, length in spans]


def _bounded(typestore: TypeDefinitions, name: str) -> bool:
    """Whether ``name`` or a type it holds has a bounded string or sequence (the message-by-
    message path checks each value against its bound)."""
    seen, todo = set(), [name]
    while todo:
        current = todo.pop()
        if current in seen:
            continue
        seen.add(current)
        for _, (kind, rest) in typestore.fielddefs[current][1]:
            element: Any = (kind, rest)  # rosbags' field descriptions: (kind, details)
            if kind in {Nodetype.ARRAY, Nodetype.SEQUENCE}:
                if kind == Nodetype.SEQUENCE and rest[1]:
                    return True
                element = rest[0]
            if element[0] == Nodetype.BASE and element[1][1]:
                return True
            if element[0] == Nodetype.NAME:
                todo.append(element[1])
    return False


def _fill(rows: np.ndarray, template: np.ndarray, start: int, stop: int) -> None:
    """``template[start:stop]`` into every row of ``rows`` at the same place."""
    if stop > start:
        span = np.dtype((np.void, stop - start))
        rows[:, start:stop].view(span)[:, 0] = template[start:stop].view(span)[0]


def _prefix_offsets(layout: CdrLayout, lengths: tuple[int, ...]) -> list[int]:
    offsets = []
    for known in range(len(lengths)):
        step = layout.resolve(lengths[:known])
        assert isinstance(step, NeedLength)
        offsets.append(step.offset)
    return offsets
