"""Which payloads of one topic satisfy a field condition (``--where``, ``find``'s ``--when``).

Fixed-layout types are matched a chunk at a time: the columns the condition reads are decoded
in bulk (:mod:`bagkit.decode.bulk`) and compared as numpy arrays (:meth:`Condition.mask`).
Conditions on sequences, and payloads the bulk decoder hands back, are decoded one by one and
matched on the message object (:meth:`Condition.matches`). A payload that does not decode is
counted in :attr:`PayloadMatcher.undecodable` and never matches.
"""

from __future__ import annotations

import numpy as np

from bagkit.decode.bulk import BulkGroup, decode_bulk
from bagkit.decode.errors import DecodeError
from bagkit.decode.flatten import STRING_TYPES, leaf_fields
from bagkit.decode.layout import CdrLayout
from bagkit.decode.message_types import MessageTypes
from bagkit.selection.conditions import Condition
from bagkit.words import counted


class PayloadMatcher:
    """Matches the payloads of ``topic`` (type ``type_name``) against ``condition``; a
    :class:`bagkit.surgery.select.PayloadFilter` (``filter --where``).

    The condition's fields and value types are checked against the type on construction.

    Args:
        bulk: match fixed-layout payloads in bulk (False: every payload decoded, to
            cross-check).

    Raises:
        UnknownFieldError: the condition names a field the type lacks.
        SelectionError: it compares a text field with a number, or a number with text.
        SchemaError, DecodeError: the type cannot be decoded.
    """

    def __init__(
        self,
        types: MessageTypes,
        topic: str,
        type_name: str,
        condition: Condition,
        *,
        bulk: bool = True,
    ) -> None:
        condition.require_per_message()
        types = types.for_topic(topic)
        canonical = types.resolve(type_name)
        leaves = leaf_fields(types.typestore, canonical)
        paths = [leaf.path for leaf in leaves]
        texts = {leaf.path for leaf in leaves if leaf.base in STRING_TYPES}
        condition.check_fields(topic, paths, texts)
        octet_paths = {leaf.path for leaf in leaves if leaf.base in ("byte", "char")}
        self.octets = frozenset(
            comparison
            for comparison, names in condition.reads(paths).items()
            if octet_paths.intersection(names)
        )
        self.condition = condition
        self.topic = topic
        self.reads = condition.bulk_columns(paths)
        self.layout = (
            CdrLayout.of(types.typestore, canonical) if bulk and self.reads is not None else None
        )
        self.texts = texts
        self._types = types
        self._type_name = type_name
        # The bulk path decodes only the payloads it hands back: rosbags' code for the general
        # decoder is generated on first need (per bag: a large share of `find`'s time, see
        # benchmarks/README.md).
        self._decode = None if self.layout is not None else types.decoder(type_name)
        self.undecodable = 0
        self.first_failure = ""

    @property
    def problem(self) -> str | None:
        """The line for messages that did not decode (never matched), or None."""
        if not self.undecodable:
            return None
        return (
            f"{self.topic}: {counted(self.undecodable, 'message')} could not be decoded, not "
            f"matched ({self.first_failure})"
        )

    def matches(self, data: bytes | memoryview) -> bool:
        """Whether one payload satisfies the condition (False, and counted, if it does not
        decode)."""
        if self._decode is None:
            self._decode = self._types.decoder(self._type_name)
        try:
            return self.condition.matches(self._decode(data), self.octets)
        except DecodeError as exc:
            self.undecodable += 1
            self.first_failure = self.first_failure or str(exc)
            return False

    def mask_records(
        self,
        records: bytes,
        starts: np.ndarray,
        lengths: np.ndarray,
        log_times: np.ndarray | None = None,
    ) -> np.ndarray:
        """Which of the payloads ``records[starts[i] : starts[i] + lengths[i]]`` match (their
        log times do not matter: a per-message condition)."""
        keep = np.zeros(len(starts), dtype=bool)
        leftover = np.arange(len(starts))
        if self.layout is not None and len(starts):
            buf = np.frombuffer(records, dtype=np.uint8)
            groups, leftover = decode_bulk(buf, starts, lengths, self.layout)
            for group in groups:
                hits = self._group_mask(group)
                if hits is None:  # a string that is not UTF-8: the decoder says why
                    leftover = np.union1d(leftover, group.indexes)
                else:
                    keep[group.indexes] = hits
        view = memoryview(records)
        for i, start, length in zip(
            leftover.tolist(), starts[leftover].tolist(), lengths[leftover].tolist(), strict=True
        ):
            keep[i] = self.matches(view[start : start + length])
        return keep

    def _group_mask(self, group: BulkGroup) -> np.ndarray | None:
        assert self.reads is not None  # a layout is only made for bulk-readable conditions
        names = sorted({name for names in self.reads.values() for name in names})
        found = group.columns(names)
        columns: dict[str, np.ndarray] = {}
        for name in names:
            if name in self.texts:
                text = _texts(found.get(name), len(group.indexes))
                if text is None:
                    return None
                columns[name] = text
            else:
                columns[name] = found[name]
        with np.errstate(over="ignore", invalid="ignore"):  # a value beyond a float32's range
            return self.condition.mask(columns, self.reads)


def _texts(raw: np.ndarray | None, count: int) -> np.ndarray | None:
    """Bulk string bytes as text (a layout holds none for empty strings); None if not UTF-8."""
    if raw is None:
        return np.full(count, "", dtype=object)
    try:
        return np.char.decode(raw, "utf-8")
    except UnicodeDecodeError:
        return None
