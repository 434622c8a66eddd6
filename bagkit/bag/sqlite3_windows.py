"""The SQLite3 back-end's bulk read: the messages table in windows of row ids, one query each.

Python's ``sqlite3`` hands out a tuple per row, and that (not SQLite) is most of the cost of
reading a large ``.db3``. Here a window of rows comes out of one aggregate query as three
values: the payloads back to back (``group_concat`` of the blobs), their lengths and their
timestamps as text lists that numpy parses (the topic ids too when several topics are read).
SQLite steps the rows in C, without the GIL. The values are the file's, untrusted: the counts
and the lengths' sum are checked against the payloads before use.

Order: chunks hand out rows in timestamp order, ties by row id; a window reads them in row id
order (a range of the table, not a walk of the timestamp index). A window whose times are not
in order is sorted (stable: ties stay in row id order). Across windows, before one is handed
out, the timestamp index tells whether any later row (a larger row id) is older than the
newest row handed out so far: whether a row beyond the window has a timestamp between the
newest before this window and the newest now (each stretch of the index walked once). Then
the bulk read stops (:attr:`RowWindows.resume_from`) and the caller reads the rest in
timestamp order, row by row: those rows are all at least as new as every row handed out.

Memory: a window holds as many rows as :data:`WINDOW_BYTES` holds at the mean size read so
far (the first window: at the file's size per row; each next one at most twice as many),
at most :data:`ROWS_PER_WINDOW`; where available (Python
3.11+), SQLite refuses a window's payloads over :data:`MAX_WINDOW_BYTES` and the window is
halved (a single larger row is read alone, without that limit).
"""

from __future__ import annotations

import sqlite3
from collections.abc import Callable, Iterator, Sequence
from dataclasses import dataclass

import numpy as np

ROWS_PER_WINDOW = 8_192
WINDOW_BYTES = 16 << 20
MAX_WINDOW_BYTES = 64 << 20
# Row ids spanned by one window at most (a topic that is a small share of the rows).
MAX_WINDOW_ROW_IDS = 1 << 20
INT64_MIN = -(1 << 63)
INT64_MAX = (1 << 63) - 1
# Connection.setlimit: Python 3.11+ (without it, SQLite's own limit of 1e9 bytes holds).
_SET_LIMIT: Callable[[sqlite3.Connection, int, int], int] | None = getattr(
    sqlite3.Connection, "setlimit", None
)
_LIMIT_LENGTH: int = getattr(sqlite3, "SQLITE_LIMIT_LENGTH", 0)


@dataclass(frozen=True, slots=True)
class StoredRows:
    """The rows of one window, in timestamp order (ties by row id).

    ``topic_ids`` is None when the rows are of one topic id.
    """

    log_times: np.ndarray
    topic_ids: np.ndarray | None
    payloads: bytes
    lengths: np.ndarray


def timestamp_index(db: sqlite3.Connection) -> str | None:
    """The name of an index of ``messages`` that starts with ``timestamp`` (rosbag2's
    ``timestamp_idx``), quoted for SQL, for the order check; None when the bulk read cannot
    apply: no such index (or only partial ones), or a database whose text is not UTF-8
    (``group_concat`` would convert the payloads as text)."""
    (encoding,) = db.execute("PRAGMA encoding").fetchone()
    if encoding != "UTF-8":
        return None
    indexes = db.execute("SELECT name, partial FROM pragma_index_list('messages')").fetchall()
    for name, partial in indexes:
        if partial or not isinstance(name, str):
            continue
        first = db.execute(
            "SELECT name FROM pragma_index_info(?) ORDER BY seqno LIMIT 1", (name,)
        ).fetchone()
        if first is not None and first[0] == "timestamp":
            return '"' + name.replace('"', '""') + '"'
    return None


class RowWindows:
    """The rows of ``messages`` that satisfy ``conditions``, window by window.

    Args:
        db: the open database.
        conditions: SQL conditions on a row (AND-ed; none: every row), with ``values`` for
            their parameters.
        several_topics: read each row's topic id too.
        order_index: from :func:`timestamp_index`.
        row_bytes: the file's size over its rows: the first window's guess of a row's size.
    """

    def __init__(
        self,
        db: sqlite3.Connection,
        conditions: Sequence[str],
        values: Sequence[int],
        *,
        several_topics: bool,
        order_index: str,
        row_bytes: int,
    ) -> None:
        self._db = db
        self._first_span = min(max(WINDOW_BYTES // max(row_bytes, 1), 1), ROWS_PER_WINDOW)
        self._values = list(values)
        where = "".join(f" AND {c}" for c in conditions)
        ids = ", group_concat(topic_id)" if several_topics else ""
        self._query = (
            "SELECT CAST(group_concat(data, '') AS BLOB), group_concat(length(data)), "
            f"group_concat(timestamp){ids} FROM messages WHERE rowid BETWEEN ? AND ?{where}"
        )
        self._next_query = f"SELECT min(rowid) FROM messages WHERE rowid >= ?{where}"
        # Stops at the first row beyond the window; SQLite reads the row ids from the index.
        self._order_query = (
            f"SELECT 1 FROM messages INDEXED BY {order_index} "
            "WHERE timestamp >= ? AND timestamp < ? AND rowid > ? LIMIT 1"
        )
        self.read = 0
        self.resume_from: int | None = None

    def __iter__(self) -> Iterator[StoredRows]:
        """The windows in turn; when the bulk read stops early, :attr:`resume_from` is the
        first row id not handed out (the rest is to be read by rows)."""
        unread = INT64_MIN  # the first row id not handed out
        try:
            first = self._next_row_id(unread)
            span = self._first_span
            spanned = stored = 0
            newest = INT64_MIN  # the newest timestamp handed out
            while first is not None:
                last = min(first + span - 1, INT64_MAX)
                try:
                    rows = self._window(first, last)
                except _WindowTooLargeError:
                    span //= 2
                    continue
                if rows is None or not self._in_order(rows, newest, last):
                    self.resume_from = unread
                    return
                if len(rows.lengths):
                    newest = max(newest, int(rows.log_times[-1]))
                    yield rows
                self.read += len(rows.lengths)
                spanned += last - first + 1
                stored += len(rows.payloads)
                span = self._next_span(span, spanned, stored)
                if last == INT64_MAX:
                    return
                unread = last + 1
                first = unread if len(rows.lengths) else self._next_row_id(unread)
        except sqlite3.Error:  # damage: the rows meet it again, and report it
            self.resume_from = unread

    def _next_span(self, span: int, spanned: int, stored: int) -> int:
        """Row ids in the next window: the rows that fit :data:`WINDOW_BYTES` at the mean
        size so far, over the share of the rows read; at most twice this one's (a window
        halved to fit :data:`MAX_WINDOW_BYTES` grows back slowly)."""
        if not self.read:
            return min(2 * span, MAX_WINDOW_ROW_IDS)
        rows = min(max(WINDOW_BYTES * self.read // max(stored, 1), 1), ROWS_PER_WINDOW)
        return min(max(rows * spanned // self.read, 1), 2 * span, MAX_WINDOW_ROW_IDS)

    def _next_row_id(self, first: int) -> int | None:
        """The first row id from ``first`` of a row read (skips gaps and other topics)."""
        (found,) = self._db.execute(self._next_query, (first, *self._values)).fetchone()
        return found if isinstance(found, int) else None

    def _window(self, first: int, last: int) -> StoredRows | None:
        """The rows with row ids in ``[first, last]``; None when the values do not add up
        (the payloads are not as long as their lengths say)."""
        set_limit = _SET_LIMIT if last > first else None  # one row: read whatever its size
        if set_limit is not None:
            before = set_limit(self._db, _LIMIT_LENGTH, MAX_WINDOW_BYTES)
        try:
            found = self._db.execute(self._query, (first, last, *self._values)).fetchone()
        except sqlite3.DataError as exc:
            if set_limit is not None and "too big" in str(exc):
                raise _WindowTooLargeError from None
            raise
        finally:
            if set_limit is not None:
                set_limit(self._db, _LIMIT_LENGTH, before)
        payloads, *lists = found
        if not all(text is None or isinstance(text, str) for text in lists):
            return None
        lengths, log_times, *topic_ids = (
            np.fromstring(text or "", dtype=np.int64, sep=",") for text in lists
        )
        payloads = payloads or b""
        count = len(log_times)
        if (
            not isinstance(payloads, bytes)
            or any(len(numbers) != count for numbers in (lengths, *topic_ids))
            or count > last - first + 1
            or (count and lengths.min() < 0)
            or int(lengths.sum()) != len(payloads)
        ):
            return None
        rows = StoredRows(log_times, topic_ids[0] if topic_ids else None, payloads, lengths)
        return _sorted(rows)

    def _in_order(self, rows: StoredRows, newest: int, last: int) -> bool:
        """True when no row after ``last`` is older than the newest of ``rows`` or before:
        no row of the index's stretch from ``newest`` to there lies beyond ``last``."""
        if not len(rows.lengths) or rows.log_times[-1] <= newest:
            return True
        beyond = self._db.execute(
            self._order_query, (newest, int(rows.log_times[-1]), last)
        ).fetchone()
        return beyond is None


class _WindowTooLargeError(Exception):
    """A window's payloads are over :data:`MAX_WINDOW_BYTES`."""


def _sorted(rows: StoredRows) -> StoredRows:
    """``rows`` in timestamp order, ties in row id order (as read)."""
    times = rows.log_times
    if not len(times) or (times[1:] >= times[:-1]).all():
        return rows
    order = np.argsort(times, kind="stable")
    ends = np.cumsum(rows.lengths)
    view = memoryview(rows.payloads)
    payloads = b"".join(
        view[end - length : end]
        for end, length in zip(ends[order].tolist(), rows.lengths[order].tolist(), strict=True)
    )
    ids = rows.topic_ids[order] if rows.topic_ids is not None else None
    return StoredRows(times[order], ids, payloads, rows.lengths[order])
