"""A topic's messages rewritten to the target definition: decode, convert, encode, decode again.

:func:`migrate_topic` compares the topic's stored definition with the target's
(:func:`bagkit.decode.drift.definition_changes`) and, when they differ, plans the conversion
(:class:`~bagkit.migrate.plan.Planner`); :meth:`TopicMigration.payload` then rewrites one
payload. Every payload written is decoded with the new definition first, so a migrated bag
never holds a message its own definition cannot read.

A chunk's payloads migrated in bulk (:mod:`bagkit.migrate.bulk`) come in groups of one old
and one new layout, every row built by the same byte operations: the first and last row of
each group must be the very bytes this path gives for their old payloads (decoded, converted,
encoded and decoded with the new definition), else the whole batch goes this path. That checks
every row: the rows of a group share every byte that is not a copied value (header, length
prefixes, padding), and a copied value is a number or the bytes of a string, which decode
whatever they hold, as they did in the old payload (decoded in bulk with the old layout).
The operations a group's rows are built by depend on nothing but the old payloads' length
prefixes (they fix both layouts, the spans copied and the constants): once a group of given
prefixes agreed, a group of the same prefixes in a later batch is built exactly as it was and
is not checked again (the values each batch copies are checked as before: strings ASCII,
bools 0 or 1, :meth:`~bagkit.migrate.bulk.BulkMigration.payloads`).
"""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass, field, replace
from typing import Any

import numpy as np

from bagkit.bag.definitions import canonical_type_name
from bagkit.bag.messages import TopicInfo
from bagkit.decode.cdr import has_wide_strings
from bagkit.decode.drift import definition_changes
from bagkit.decode.errors import DecodeError, SchemaError
from bagkit.decode.message_types import MessageTypes
from bagkit.migrate.bulk import BulkGroup, BulkMigration
from bagkit.migrate.errors import MigrateError
from bagkit.migrate.plan import Planner
from bagkit.migrate.rules import Rules
from bagkit.migrate.targets import Target

# Layouts (old length prefixes) remembered as agreed, at most: memory stays flat whatever the
# strings' lengths; one forgotten is checked again.
_AGREED_LAYOUTS = 1024


@dataclass
class TopicMigration:
    """How one topic is migrated.

    Attributes:
        topic: the topic as the output lists it (the new type hash, QoS kept).
        definition: the new definition's full text.
        changes: what differs from the stored definition (drift lines).
        rules_run: the rules its conversion applies.
        dropped: old fields whose values are not carried over (``--allow-drop``).
        bulk: the column-by-column path of a chunk's payloads, when the layouts allow it.
        migrated: payloads rewritten so far.
    """

    topic: TopicInfo
    definition: str
    changes: list[str]
    rules_run: list[str]
    dropped: list[str]
    decode: Callable[[bytes | memoryview], object] = field(repr=False)
    convert: Callable[[Any], Any] = field(repr=False)
    encode: Callable[[Any], bytes] = field(repr=False)
    check: Callable[[bytes | memoryview], object] = field(repr=False)
    bulk: BulkMigration | None = field(default=None, repr=False)
    migrated: int = 0
    # Length prefixes of old payloads whose bulk group agreed (see the module's docstring).
    _agreed: set[tuple[int, ...]] = field(default_factory=set, repr=False)

    def payloads(
        self, buf: np.ndarray, starts: np.ndarray, lengths: np.ndarray, room: int = 0
    ) -> list[tuple[np.ndarray, np.ndarray]]:
        """The payloads at ``starts``/``lengths`` of ``buf`` (uint8) migrated, as groups
        ``(indexes, rows)`` of payloads of one size (``rows[i]``: ``room`` zero bytes left for
        the caller, then the payload at ``indexes[i]`` of the batch): in bulk when :attr:`bulk`
        can take them all, else one by one (:meth:`payload`).

        Raises:
            MigrateError: as :meth:`payload`.
        """
        if self.bulk is not None:
            found = self.bulk.payloads(buf, starts, lengths, room)
            if found is not None and self._agrees(found, buf, starts, lengths, room):
                self.migrated += len(starts)
                return [(group.indexes, group.rows) for group in found]
        view = memoryview(buf.data)
        made = [
            self.payload(view[start : start + length])
            for start, length in zip(starts.tolist(), lengths.tolist(), strict=True)
        ]
        return _rows(made, room)

    def payload(self, data: bytes | memoryview) -> bytes:
        """One payload of the stored definition as a payload of the new one.

        Raises:
            MigrateError: it does not decode with its stored definition, or the result does
                not encode or decode with the new one. RuleError: a rule failed on it.
        """
        encoded = self._migrated(data)
        self.migrated += 1
        return encoded

    def _agrees(
        self,
        groups: list[BulkGroup],
        buf: np.ndarray,
        starts: np.ndarray,
        lengths: np.ndarray,
        room: int,
    ) -> bool:
        """Whether the first and last row of each bulk group hold what :meth:`payload` gives
        for their old payloads, or a group of the same old length prefixes did (see the
        module's docstring)."""
        view = memoryview(buf.data)
        for indexes, rows, prefixes in groups:
            if prefixes in self._agreed:
                continue
            for row in {0, len(indexes) - 1}:
                start, length = int(starts[indexes[row]]), int(lengths[indexes[row]])
                try:
                    expected = self._migrated(view[start : start + length])
                except MigrateError:
                    return False  # this path raises it, naming the message
                if rows[row, room:].data != expected:
                    return False
            if len(self._agreed) >= _AGREED_LAYOUTS:
                self._agreed.clear()
            self._agreed.add(prefixes)
        return True

    def _migrated(self, data: bytes | memoryview) -> bytes:
        """:meth:`payload` without counting it."""
        where = f"{self.topic.name} message {self.migrated + 1}"
        try:
            old = self.decode(data)
        except DecodeError as exc:
            raise MigrateError(f"{where}: {exc}") from None
        try:
            new = self.convert(old)
        except MigrateError as exc:
            raise type(exc)(f"{exc.problem} ({where})", exc.field) from None
        try:
            encoded = self.encode(new)
            self.check(encoded)
        except DecodeError as exc:
            raise MigrateError(f"{where}: the migrated message does not decode: {exc}") from None
        except Exception as exc:  # rosbags' serializer raises struct, type and index errors
            raise MigrateError(
                f"{where}: cannot be encoded ({type(exc).__name__}: {exc})"
            ) from None
        return encoded


def migrate_topic(
    info: TopicInfo,
    stored: str | None,
    target: Target,
    rules: Rules | None = None,
    *,
    allow_drop: bool = False,
) -> TopicMigration | None:
    """The migration of topic ``info`` (stored definition ``stored``) to ``target``; None when
    there is nothing to do (the target lacks the type, or defines it the same way).

    Raises:
        MigrateError: a definition cannot be parsed, a field cannot be converted, data would
            be lost (DataLossError), a rule is bad (RuleError).
    """
    name = canonical_type_name(info.type)
    text = target.definition(name)
    if text is None:
        return None
    old_types = MessageTypes.from_definitions({name: stored} if stored else {})
    new_types = MessageTypes.from_definitions({name: text})
    try:
        old_name, new_name = old_types.resolve(name), new_types.resolve(name)
        decode, check = old_types.decoder(name), new_types.decoder(name)
    except SchemaError as exc:
        raise MigrateError(f"{info.name}: {exc}") from None
    old_store, new_store = old_types.typestore, new_types.typestore
    changes = definition_changes(name, old_store.fielddefs, new_store.fielddefs)
    if not changes and (rules is None or not _has_rules(rules, old_store.fielddefs)):
        return None
    if has_wide_strings(new_store, new_name):
        raise MigrateError(f"{info.name}: {name} has wide strings, which bagkit cannot encode")
    planner = Planner(old_store, new_store, rules or Rules(), allow_drop)
    try:
        convert = planner.converter(old_name, new_name)
    except MigrateError as exc:
        raise type(exc)(f"{info.name} ({name}): {exc.problem}", exc.field) from None

    encoder = new_types.rosbags_typestore()

    def encode(message: Any) -> bytes:
        return bytes(encoder.serialize_cdr(message, new_name))

    topic = replace(info, type_description_hash=target.type_hash(name, text))
    bulk = BulkMigration.of(old_store, new_store, name) if not planner.rules_run else None
    return TopicMigration(
        topic,
        text,
        changes,
        planner.rules_run,
        planner.dropped,
        decode,
        convert,
        encode,
        check,
        bulk,
    )


def _rows(payloads: list[bytes], room: int) -> list[tuple[np.ndarray, np.ndarray]]:
    """``payloads`` as groups of one size, each after ``room`` zero bytes (see
    :meth:`TopicMigration.payloads`)."""
    sizes = np.fromiter(map(len, payloads), np.int64, len(payloads))
    groups = []
    for size in np.unique(sizes).tolist():
        indexes = np.flatnonzero(sizes == size)
        rows = np.zeros((len(indexes), room + size), np.uint8)
        joined = b"".join(payloads[i] for i in indexes.tolist())
        rows[:, room:] = np.frombuffer(joined, np.uint8).reshape(len(indexes), size)
        groups.append((indexes, rows))
    return groups


def _has_rules(rules: Rules, types: dict[str, Any]) -> bool:
    return any(rules.of(name) is not None for name in types)
