"""A bag read topic by topic into Arrow record batches, one decompressed chunk at a time."""

from __future__ import annotations

from collections.abc import Callable, Iterator
from contextlib import closing
from dataclasses import dataclass, field
from functools import partial
from typing import TYPE_CHECKING

from bagkit.bag import BagReader
from bagkit.data.columns import Rows, TopicColumns
from bagkit.data.errors import UnknownFieldError
from bagkit.data.table import ColumnTable
from bagkit.decode import DecodeError, MessageTypes, leaf_fields
from bagkit.decode.matcher import PayloadMatcher
from bagkit.prefetch import prefetch
from bagkit.selection.fields import select_fields
from bagkit.selection.query import Query
from bagkit.selection.windows import Window
from bagkit.words import counted

if TYPE_CHECKING:
    import pyarrow as pa  # only the batches' type: find and check read numpy columns


@dataclass(slots=True)
class Scan:
    """The decodable selected topics of one open bag, and why the others are skipped.

    Build with :func:`plan_scan`; :meth:`batches` reads the bag.
    """

    reader: BagReader
    window: Window
    topics: dict[str, TopicColumns]
    skipped: dict[str, str] = field(default_factory=dict)
    outside: str | None = None
    """The one warning when the time window holds none of the bag's messages."""

    def batches(self) -> Iterator[tuple[str, pa.RecordBatch]]:
        """(topic, batch) per topic and chunk, in file order."""
        for topic, rows in self._decode(lambda t, n: Rows.empty(self.topics[t].leaves, n)):
            yield topic, rows.batch(self.topics[topic].schema)

    def table(self, topic: str) -> ColumnTable:
        """Every selected message of ``topic`` (the only topic of the scan) in one table."""
        capacity = self.reader.topic_counts.get(topic, 0)
        table = ColumnTable(self.topics[topic].leaves, capacity)
        for _ in self._decode(lambda _topic, n: table.reserve(n)):
            pass
        return table

    def _decode(self, reserve: Callable[[str, int], Rows]) -> Iterator[tuple[str, Rows]]:
        """(topic, rows) per topic and chunk, rows from ``reserve(topic, count)``."""
        if not self.topics:
            return
        # closing(): the reading thread stops before the reader is closed, also on error.
        read = self.reader.chunks(self.topics, self.window.start_ns, self.window.end_ns)
        with closing(prefetch(read)) as chunks:
            for chunk in chunks:
                for topic, index in chunk.message_index.items():
                    columns = self.topics.get(topic)
                    if columns is not None:
                        rows = columns.decode_chunk(
                            chunk.records, index, self.window, partial(reserve, topic)
                        )
                        if len(rows.ok):
                            yield topic, rows

    @property
    def problems(self) -> list[str]:
        """What was lost: unreadable parts of the bag, messages that do not decode."""
        found = list(self.reader.problems)
        for topic, columns in self.topics.items():
            if columns.undecodable:
                found.append(
                    f"{topic}: {counted(columns.undecodable, 'message')} could not be decoded "
                    f"({columns.first_undecodable})"
                )
            if columns.unindexed:
                found.append(
                    f"{topic}: {columns.unindexed} index entries point outside their chunk"
                )
        return found


def plan_scan(reader: BagReader, query: Query, *, label: str, bulk: bool = True) -> Scan:
    """Which topics of ``reader`` can be decoded, with which fields, in which time window.

    ``query`` is resolved against this bag (``label``: the bag as the user named it, for the
    window's warning). Its topics (all when it names none) must be in the bag. Its fields are
    path globs (see :func:`~bagkit.selection.fields.select_fields`): with several topics a topic
    none of whose fields match is left out, with one topic that is an error. Its condition keeps
    the messages satisfying it; as with fields, with several topics those without its fields
    are left out, with one topic that is an error.

    Raises:
        UnknownTopicError, UnknownFieldError; SelectionError for a condition comparing text
        with a number.
    """
    resolved = query.resolve(reader, label=label)
    topics = resolved.topics or None
    fields, where = query.fields, query.where
    types = MessageTypes.for_bag(reader)
    window, outside = resolved.window, resolved.outside
    scan = Scan(reader, window, {}, outside=outside)
    for name in topics if topics is not None else sorted(reader.topics):
        info = reader.topics[name]
        if info.serialization_format != "cdr":
            scan.skipped[name] = f"serialization format {info.serialization_format!r} is not CDR"
            continue
        try:
            own = types.for_topic(name)
            leaves = leaf_fields(own.typestore, own.resolve(info.type))
        except DecodeError as exc:
            scan.skipped[name] = str(exc)
            continue
        if fields and (topics is None or len(topics) > 1):
            # Several topics: those with none of the fields are not what was asked for.
            leaves = select_fields(leaves, fields, topic=name, must_match=False)
            if not leaves:
                continue
        else:
            leaves = select_fields(leaves, fields, topic=name)
        matcher = None
        if where is not None:
            try:
                matcher = PayloadMatcher(types, name, info.type, where, bulk=bulk)
            except UnknownFieldError:
                if topics is not None and len(topics) == 1:
                    raise
                continue  # several topics: those without the condition's fields are left out
        scan.topics[name] = TopicColumns(types, name, info.type, leaves, bulk=bulk, matcher=matcher)
    if fields and not scan.topics and not scan.skipped:
        raise UnknownFieldError(f"no topic of {label} has a field {', '.join(fields)}")
    if where is not None and not scan.topics and not scan.skipped:
        raise UnknownFieldError(f"no topic of {label} has the fields of {where.text!r}")
    return scan
