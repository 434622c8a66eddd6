"""Reading the messages of a rosbag2 ``.db3`` file (the rows of its ``messages`` table), for
:class:`~bagkit.bag.sqlite3_file.Sqlite3File`: by rows (``messages``, the latched state, and
where the bulk read cannot apply) and in windows of rows laid out as chunks
(:mod:`bagkit.bag.sqlite3_windows`).
"""

from __future__ import annotations

import contextlib
import sqlite3
from collections.abc import Iterator, Sequence
from pathlib import Path
from typing import TYPE_CHECKING

from bagkit.bag.messages import BagMessage, make_message
from bagkit.bag.storage import BagChunk, PayloadFilter, chunk_of_payloads, chunk_of_rows
from bagkit.prefetch import prefetch
from bagkit.words import counted

if TYPE_CHECKING:
    from bagkit.bag.sqlite3_windows import StoredRows

# A message row is readable when its timestamp is an integer and its data a blob.
VALID_ROW = "typeof(timestamp) = 'integer' AND typeof(data) = 'blob'"
# Rows read one by one are laid out in chunks of this many (a few MB of small messages),
# read from SQLite in batches; payload bytes held in one chunk at most (a batch more at worst).
ROWS_PER_CHUNK = 16_384
ROWS_PER_BATCH = 1_024
BATCH_BYTES = 8 << 20
MAX_CHUNK_BYTES = 64 << 20
INT64_MIN = -(1 << 63)
INT64_MAX = (1 << 63) - 1


class Sqlite3Reading:
    """The reading half of :class:`~bagkit.bag.sqlite3_file.Sqlite3File`, which opens the file
    and fills these attributes."""

    path: Path
    problems: list[str]
    topic_counts: dict[str, int]
    payload_filter: PayloadFilter | None
    _db: sqlite3.Connection | None
    _topic_ids: dict[int, str]
    _clean: bool  # every row valid and of a known topic

    def _problem(self, text: str) -> None:
        self.problems.append(f"{self.path.name}: {text}")

    def chunks(
        self, topics: set[str] | None, start_ns: int | None = None, end_ns: int | None = None
    ) -> Iterator[BagChunk]:
        """The rows of ``topics`` with ``start_ns <= timestamp < end_ns`` in timestamp order
        (ties by row id), laid out as chunks of MCAP Message records: a window of rows each
        (:mod:`bagkit.bag.sqlite3_windows`), or :data:`ROWS_PER_CHUNK` rows read one by one,
        fewer where their payloads pass :data:`MAX_CHUNK_BYTES` (large messages: memory stays
        bounded)."""
        from bagkit.bag.sqlite3_windows import RowWindows, timestamp_index

        wanted = self._wanted_ids(topics)
        if self._db is None or not any(self.topic_counts.get(self._topic_ids[i]) for i in wanted):
            return
        one = self._one_topic(topics)
        try:
            order_index = timestamp_index(self._db)
        except sqlite3.Error:
            order_index = None
        if order_index is None:
            # Without a timestamp index, rows read by row id could not be checked to be in
            # timestamp order without reading them twice (SQLite sorts them instead); a
            # UTF-16 database's payloads would not survive group_concat. rosbag2 writes
            # neither.
            yield from self._row_chunks(topics, one, None, 0, (start_ns, end_ns))
            return
        conditions, values = self._conditions(wanted)
        # ``+timestamp``: a window is a range of row ids, which the timestamp index must not
        # replace (each window would walk the whole time range of the index).
        in_time, bounds = _time_conditions(start_ns, end_ns, "+timestamp")
        windows = RowWindows(
            self._db,
            conditions + in_time,
            values + bounds,
            several_topics=one is None,
            order_index=order_index,
            row_bytes=self.path.stat().st_size // max(sum(self.topic_counts.values()), 1),
        )
        # The next window is read (SQLite steps its rows without the GIL) while one is
        # decompressed and laid out; closing(): that thread stops first, also on error.
        with contextlib.closing(prefetch(iter(windows))) as ahead:
            for rows in ahead:
                yield from self._window_chunks(rows, one)
        if windows.resume_from is not None:  # out of order, or damage: by rows from there
            yield from self._row_chunks(
                topics, one, windows.resume_from, windows.read, (start_ns, end_ns)
            )

    def _window_chunks(self, rows: StoredRows, one: str | None) -> Iterator[BagChunk]:
        """The chunks of one window's rows, their payloads passed through ``payload_filter``."""
        topics: str | dict[int, str] = self._topic_ids if one is None else one
        ids = rows.topic_ids
        if self.payload_filter is None:
            yield chunk_of_payloads(
                self.path, topics, rows.log_times, rows.payloads, rows.lengths, topic_ids=ids
            )
            return
        names = self._topic_ids

        def topic_of(row: int) -> str:
            return one if ids is None else names[int(ids[row])]  # type: ignore[return-value]

        pieces = self.payload_filter.joined(rows.payloads, rows.lengths, topic_of)
        for kept, payloads, lengths in pieces:
            yield chunk_of_payloads(
                self.path,
                topics,
                rows.log_times[kept],
                payloads,
                lengths,
                topic_ids=ids[kept] if ids is not None else None,
            )

    def _row_chunks(
        self,
        topics: set[str] | None,
        one: str | None,
        from_row_id: int | None,
        read: int,
        span: tuple[int | None, int | None],
    ) -> Iterator[BagChunk]:
        """:meth:`chunks` by rows (from row id ``from_row_id``, ``read`` rows read before; of
        the time ``span``)."""
        held: tuple[list[int], list[int], list[bytes | None]] = ([], [], [])
        size = 0
        for ids, log_times, stored in self._batches(
            topics, *span, from_row_id=from_row_id, read=read
        ):
            payloads = self._filtered(ids, one, stored)
            if one is None:
                held[0].extend(ids)
            held[1].extend(log_times)
            held[2].extend(payloads)
            size += sum(map(len, filter(None, payloads)))
            if len(held[1]) >= ROWS_PER_CHUNK or size >= MAX_CHUNK_BYTES:
                yield self._chunk(held, one)
                held, size = ([], [], []), 0
        if held[1]:
            yield self._chunk(held, one)

    def _chunk(
        self, held: tuple[list[int], list[int], list[bytes | None]], one: str | None
    ) -> BagChunk:
        ids, log_times, payloads = held
        topics = one if one is not None else list(map(self._topic_ids.__getitem__, ids))
        return chunk_of_rows(self.path, topics, log_times, payloads)

    def last_messages(self, topics: set[str], before_ns: int) -> dict[str, BagMessage]:
        """The last valid row with ``timestamp < before_ns`` of each of ``topics`` that has one
        (ties: the last row id), one indexed query per topic."""
        found: dict[str, BagMessage] = {}
        if self._db is None or before_ns <= INT64_MIN:
            return found
        upper = min(before_ns, INT64_MAX)
        for topic in sorted(topics):
            ids = [i for i, t in self._topic_ids.items() if t == topic]
            if not ids:
                continue
            marks = ",".join("?" * len(ids))
            query = (
                f"SELECT timestamp, data FROM messages WHERE topic_id IN ({marks}) "
                f"AND timestamp < ? AND {VALID_ROW} ORDER BY timestamp DESC, rowid DESC LIMIT 1"
            )
            try:
                row = self._db.execute(query, (*ids, upper)).fetchone()
            except sqlite3.Error as exc:
                self._problem(f"last message of {topic} unreadable ({exc})")
                continue
            if row is None:
                continue
            data = row[1]
            if self.payload_filter is not None:
                (data,) = self.payload_filter.many([data], [topic].__getitem__)
            if data is not None:
                found[topic] = make_message(topic, data, row[0], row[0], 0)
        return found

    def messages(
        self, topics: set[str] | None, start_ns: int | None, end_ns: int | None
    ) -> Iterator[BagMessage]:
        """Yield the valid rows in timestamp order (ties by row id).

        By rows, not windows: a time window is found through the timestamp index (windows of
        row ids would scan the whole table for it), and each row becomes a message anyway.
        """
        one = self._one_topic(topics)
        names = self._topic_ids
        for ids, log_times, stored in self._batches(topics, start_ns, end_ns):
            payloads = self._filtered(ids, one, stored)
            topics_of = [one] * len(log_times) if one is not None else map(names.__getitem__, ids)
            for topic, timestamp, data in zip(topics_of, log_times, payloads, strict=True):
                if data is not None:
                    yield make_message(topic, data, timestamp, timestamp, 0)

    def _one_topic(self, topics: set[str] | None) -> str | None:
        """The topic of every row read, when the rows read are of one topic id."""
        wanted = self._wanted_ids(topics)
        return self._topic_ids[wanted[0]] if len(wanted) == 1 else None

    def _wanted_ids(self, topics: set[str] | None) -> list[int]:
        return [i for i, t in self._topic_ids.items() if topics is None or t in topics]

    def _filtered(
        self, ids: Sequence[int], one: str | None, stored: Sequence[bytes]
    ) -> list[bytes | None]:
        """The payloads passed through ``payload_filter`` (decompressed), None where lost."""
        if self.payload_filter is None:
            return list(stored)
        if one is not None:
            return self.payload_filter.many(list(stored), lambda _: one)
        return self.payload_filter.many(list(stored), lambda i: self._topic_ids[ids[i]])

    def _conditions(self, wanted: list[int]) -> tuple[list[str], list[int]]:
        """SQL conditions (and their values) that leave out the rows not read: each only
        where it can leave a row out (the file is immutable), so that SQLite walks the
        timestamp index or the table alone."""
        conditions: list[str] = []
        values: list[int] = []
        if not self._clean or len(wanted) < len(self._topic_ids):
            conditions.append(f"topic_id IN ({','.join('?' * len(wanted))})")
            values += wanted
        if not self._clean:
            conditions.append(VALID_ROW)
        return conditions, values

    def _batches(
        self,
        topics: set[str] | None,
        start_ns: int | None,
        end_ns: int | None,
        *,
        from_row_id: int | None = None,
        read: int = 0,
    ) -> Iterator[tuple[Sequence[int], Sequence[int], Sequence[bytes]]]:
        """The valid rows in timestamp order as (topic ids, timestamps, stored payloads), a
        batch at a time: as many rows as fit :data:`BATCH_BYTES` at the mean size so far (one
        first), at most :data:`ROWS_PER_BATCH`; damage ends them with a problem (``read``:
        rows read before, for it). Rows of one topic id are read without it (the ids are then
        empty). ``from_row_id``: only the rows from that row id on."""
        wanted = self._wanted_ids(topics)
        if not wanted or self._db is None:
            return
        conditions, values = self._conditions(wanted)
        in_time, bounds = _time_conditions(start_ns, end_ns, "timestamp")
        conditions += in_time
        values += bounds
        if from_row_id is not None:
            conditions.append("rowid >= ?")
            values.append(from_row_id)
        where = f"WHERE {' AND '.join(conditions)} " if conditions else ""
        columns = "timestamp, data" if len(wanted) == 1 else "topic_id, timestamp, data"
        query = f"SELECT {columns} FROM messages {where}ORDER BY timestamp, rowid"
        read_before = read
        try:
            cursor = self._db.execute(query, values)
            batch, stored_bytes = 1, 0
            while rows := cursor.fetchmany(batch):
                read += len(rows)
                if len(wanted) == 1:
                    ids: Sequence[int] = ()
                    log_times, stored = zip(*rows, strict=True)
                else:
                    ids, log_times, stored = zip(*rows, strict=True)
                stored_bytes += sum(map(len, stored))
                batch = max(
                    1,
                    min(ROWS_PER_BATCH, BATCH_BYTES * (read - read_before) // max(stored_bytes, 1)),
                )
                yield ids, log_times, stored
        except sqlite3.Error as exc:
            problem = f"{self.path.name}: unreadable after {counted(read, 'message')} ({exc})"
            if problem not in self.problems:  # each read of a damaged file meets it again
                self.problems.append(problem)


def _time_conditions(
    start_ns: int | None, end_ns: int | None, column: str
) -> tuple[list[str], list[int]]:
    """The SQL condition ``start_ns <= column < end_ns`` (half-open, as every storage's
    window) and its values; none without bounds."""
    if start_ns is None and end_ns is None:
        return [], []
    low = INT64_MIN if start_ns is None else start_ns
    high = INT64_MAX if end_ns is None else end_ns
    return [f"{column} >= ? AND {column} < ?"], [
        min(max(low, INT64_MIN), INT64_MAX),
        min(max(high, INT64_MIN), INT64_MAX),
    ]
