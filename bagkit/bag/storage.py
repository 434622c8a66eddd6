"""The storage files of a bag: what every back-end provides, and the chunks it hands out.

The back-ends, side by side: :mod:`bagkit.bag.mcap_file` (MCAP),
:mod:`bagkit.bag.sqlite3_file` (SQLite3, imported only when a ``.db3`` file is opened:
``sqlite3`` is not free at start-up) and :mod:`bagkit.bag.rosbag1_file` (ROS 1 ``.bag``
through rosbags, imported only when one is opened). The reader and ``bagkit info`` use them through
:class:`StorageFile` only.
"""

from __future__ import annotations

from collections.abc import Callable, Iterator, Mapping, Sequence
from dataclasses import dataclass
from pathlib import Path
from typing import TYPE_CHECKING, Protocol, runtime_checkable

from bagkit.bag.mcapio.chunks import payload_spans
from bagkit.bag.mcapio.message_index import Span
from bagkit.bag.mcapio.records import (
    MESSAGE_PREFIX,
    MESSAGE_RECORD_HEADER,
    Opcode,
    message_record_dtype,
)
from bagkit.bag.messages import BagMessage, TopicInfo
from bagkit.words import counted

if TYPE_CHECKING:
    import numpy as np

SQLITE_MAGIC = b"SQLite format 3\x00"
ROSBAG1_MAGIC = b"#ROSBAG V2.0\n"


class BagChunk:
    """One chunk, decompressed, with where each of its topics' messages are.

    ``message_index[topic]`` is a ``message_index_dtype`` array (``log_time``, ``offset`` of
    the Message record in ``records``, as stored); :meth:`payloads` gives the checked payload
    spans. A chunk laid out here (:func:`chunk_of_payloads`: db3 rows, ROS 1 messages) lays
    out its records when they are first asked for: :meth:`payload_view` reads the payloads
    where they are, and its spans are known from the layout, not read back.
    """

    __slots__ = ("_layout", "_records", "file", "message_index", "problems")

    def __init__(
        self,
        file: Path,
        records: bytes | None,
        message_index: dict[str, np.ndarray],
        problems: list[str] | None = None,
        *,
        layout: _Layout | None = None,
    ) -> None:
        self.file = file
        self.message_index = message_index
        self.problems: list[str] = [] if problems is None else problems
        self._records = records
        self._layout = layout

    @property
    def records(self) -> bytes:
        """The Message records, back to back."""
        if self._records is None:
            assert self._layout is not None
            self._records = self._layout.records()
        return self._records

    def payloads(self, topic: str) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """``(log_times, starts, lengths)`` (int64) of each payload of ``topic`` in ``records``.

        A message whose index entry points outside the chunk, or at no whole Message record,
        is left out and counted in ``problems``.
        """
        if self._layout is not None and topic in self._layout.spans:
            log_times, in_records, _, lengths = self._layout.spans[topic]
            return log_times, in_records, lengths
        entries = self.message_index.get(topic)
        if entries is None:
            import numpy as np

            return np.zeros(0, np.int64), np.zeros(0, np.int64), np.zeros(0, np.int64)
        log_times, starts, lengths, dropped = payload_spans(self.records, entries)
        if dropped:
            self.problems.append(
                f"{self.file.name}: {counted(dropped, 'message')} of {topic} indexed outside "
                "their chunk (damaged message index): lost"
            )
        return log_times, starts, lengths

    def payload_view(self, topic: str) -> tuple[bytes, np.ndarray, np.ndarray, np.ndarray]:
        """``(buffer, log_times, starts, lengths)``: :meth:`payloads` in ``records``, or for a
        chunk laid out here, in its payloads back to back (its records not laid out)."""
        if self._layout is not None and topic in self._layout.spans:
            log_times, _, starts, lengths = self._layout.spans[topic]
            return self._layout.payloads, log_times, starts, lengths
        return (self.records, *self.payloads(topic))


@dataclass(frozen=True, slots=True)
class _Layout:
    """Messages to lay out as Message records (:func:`chunk_of_payloads`), and by topic
    their ``(log_times, starts in the records, starts in payloads, lengths)``."""

    log_times: np.ndarray
    payloads: bytes
    lengths: np.ndarray
    spans: dict[str, tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray]]

    def records(self) -> bytes:
        import numpy as np

        headers = np.zeros(len(self.lengths), message_record_dtype())
        headers["opcode"] = Opcode.MESSAGE
        headers["length"] = self.lengths + MESSAGE_PREFIX.size
        # Bit for bit: a hostile db3's negative timestamp stays the int64 its index entry holds.
        headers["log_time"] = headers["publish_time"] = self.log_times.view(np.uint64)
        return _laid_out(headers, self.payloads, self.lengths)


class StorageFile(Protocol):
    """One storage file of a bag, whatever its format.

    Constructing one does no I/O; :meth:`open` reads what the file holds (topics, counts,
    times) and fills the attributes, and raises ``NotABagError``/``CorruptBagError`` (the
    file is unusable) or ``UnsupportedStorageError``. Damage found later (an unreadable chunk,
    a bad page) is appended to ``problems``, never raised.

    Attributes:
        path: the file.
        storage_identifier: rosbag2's name of the format (``mcap``, ``sqlite3``; ``rosbag1``).
        topics: by name.
        definitions: the stored definition text (``ros2msg`` or ``ros2idl``, any form of
            :mod:`bagkit.decode.stored`) by type name: the first schema's of each type.
        topic_definitions: by topic, the text of a topic whose schema holds another text for
            its type than ``definitions`` (two actions' ``action_msgs/msg/GoalStatusArray``,
            a type changed between recordings); empty in the common case and for back-ends
            that store one text per type (SQLite3). Decoders are looked up per topic, so each
            schema's messages decode with its own text (``MessageTypes.for_bag``).
        topic_counts: messages per topic (every topic of ``topics``, 0 included).
        start_ns, end_ns: log times of the first and last message (0 without messages).
        problems: what could not be read, one line each, starting with the file's name.
        has_summary: False when the file had to be salvaged (an MCAP file without summary).
        compression: the chunk compressions used (``zstd``, ``lz4``, ``none``, comma-separated;
            ``""`` without chunks); ``compressed_size``, ``uncompressed_size``: chunk bytes as
            stored and decompressed (0 without chunks).
    """

    path: Path
    storage_identifier: str
    topics: dict[str, TopicInfo]
    definitions: dict[str, str]
    topic_definitions: dict[str, str]
    topic_counts: dict[str, int]
    start_ns: int
    end_ns: int
    problems: list[str]
    has_summary: bool
    compression: str
    compressed_size: int
    uncompressed_size: int

    def open(self) -> None:
        """Read what the file holds (the only I/O before messages are asked for)."""

    def close(self) -> None:
        """Release the file (also when :meth:`open` was not called or failed)."""

    def messages(
        self, topics: set[str] | None, start_ns: int | None, end_ns: int | None
    ) -> Iterator[BagMessage]:
        """Yield the messages of ``topics`` (all when None) with ``start_ns <= log_time <
        end_ns`` in log-time order (ties in storage order)."""

    def last_messages(self, topics: set[str], before_ns: int) -> dict[str, BagMessage]:
        """The last message with ``log_time < before_ns`` of each of ``topics`` that has one
        (ties: the one stored last), found from indexes, not by reading from the start."""

    def chunks(
        self, topics: set[str] | None, start_ns: int | None = None, end_ns: int | None = None
    ) -> Iterator[BagChunk]:
        """Yield the chunks holding messages of ``topics`` in file order (none: no chunks).

        A chunk whose messages all lie outside ``start_ns <= log_time < end_ns`` (by its index)
        is not read, so neither fetched nor reported lost; one that is read may hold messages
        outside: the caller keeps its window.
        """

    def topic_spans(self, *, message_indexes: bool = True) -> dict[str, Span]:
        """(first, last) log time of each topic with messages, from indexes (no message read).

        Where no index tells (salvaged chunks without Message Index records), the bounds of
        the chunks that may hold the topic. ``message_indexes=False``: those bounds for every
        topic, from the summary alone (from the start of the first chunk holding the topic to
        the end of the last: a span that holds the true one); back-ends without a summary to
        take them from (a local file or copy) give the exact spans.
        """

    def index_log_times(self, topic: str) -> np.ndarray | None:
        """The log times (int64 ns, in no order) of ``topic``'s messages from indexes, no
        message read; None when an index is missing or damaged (read the messages)."""


class PayloadFilter(Protocol):
    """What a back-end passes its payloads through (the compression layer's decompression)."""

    def many(self, payloads: list[bytes], topic_of: Callable[[int], str]) -> list[bytes | None]:
        """Each payload to use, or None to leave its message out (``topic_of(i)``: the topic
        of payload ``i``, for the problems)."""

    def joined(
        self, stored: bytes, lengths: np.ndarray, topic_of: Callable[[int], str]
    ) -> Iterator[tuple[np.ndarray, bytes, np.ndarray]]:
        """The payloads stored back to back (``lengths`` each) as pieces of the ones to use:
        (their indices, their bytes back to back, their lengths)."""


@runtime_checkable
class FiltersPayloads(Protocol):
    """A back-end that passes its payloads through ``payload_filter`` as it reads them (before
    they are laid out in chunks: no chunk is laid out twice)."""

    payload_filter: PayloadFilter | None


def chunk_of_rows(
    file: Path,
    topics: Sequence[str] | str,
    log_times: Sequence[int],
    payloads: Sequence[bytes | None],
) -> BagChunk:
    """Messages laid out as MCAP Message records in one chunk (log time as publish time,
    channel ids and sequences 0), for the bulk decoders of a storage without chunks; a
    message whose payload is None is left out. ``topics``: each message's, or one for all."""
    import numpy as np

    if None in payloads:
        keep = [i for i, payload in enumerate(payloads) if payload is not None]
        if not isinstance(topics, str):
            topics = [topics[i] for i in keep]
        log_times = [log_times[i] for i in keep]
        payloads = [payloads[i] for i in keep]
    lengths = np.fromiter(map(len, payloads), np.int64, len(payloads))  # type: ignore[arg-type]
    times = np.asarray(log_times, np.int64)
    joined = b"".join(payloads)  # type: ignore[arg-type]
    if isinstance(topics, str):
        return chunk_of_payloads(file, topics, times, joined, lengths)
    numbers: dict[str, int] = {}
    ids = np.fromiter((numbers.setdefault(t, len(numbers)) for t in topics), np.int64, len(topics))
    names = {number: topic for topic, number in numbers.items()}
    return chunk_of_payloads(file, names, times, joined, lengths, topic_ids=ids)


def chunk_of_payloads(
    file: Path,
    topics: Mapping[int, str] | str,
    log_times: np.ndarray,
    payloads: bytes,
    lengths: np.ndarray,
    *,
    topic_ids: np.ndarray | None = None,
) -> BagChunk:
    """Messages laid out as MCAP Message records in one chunk, as :func:`chunk_of_rows` does,
    from their payloads back to back (``lengths``, int64, summing to ``len(payloads)``).

    ``topics``: one for all, or by the id in ``topic_ids`` (int64, one per message; several
    ids may name one topic).
    """
    import numpy as np

    from bagkit.bag.mcapio.records import message_index_dtype

    count = len(lengths)
    size = MESSAGE_RECORD_HEADER.size
    offsets = np.zeros(count, np.uint64)
    np.cumsum(lengths[:-1] + size, out=offsets[1:])
    in_records = offsets.astype(np.int64) + size
    in_payloads = np.zeros(count, np.int64)
    np.cumsum(lengths[:-1], out=in_payloads[1:])
    log_times = np.asarray(log_times, np.int64)
    index = {}
    spans = {}
    if isinstance(topics, str):
        index[topics] = np.empty(count, message_index_dtype())
        index[topics]["log_time"], index[topics]["offset"] = log_times, offsets
        spans[topics] = (log_times, in_records, in_payloads, lengths)
    else:
        assert topic_ids is not None
        ids, numbers = np.unique(topic_ids, return_inverse=True)
        named: dict[str, list[int]] = {}
        for number, topic_id in enumerate(ids.tolist()):
            named.setdefault(topics[topic_id], []).append(number)
        for topic, mine in named.items():
            rows = np.isin(numbers, mine)
            entries = np.empty(int(rows.sum()), message_index_dtype())
            entries["log_time"] = log_times[rows]
            entries["offset"] = offsets[rows]
            index[topic] = entries
            spans[topic] = (log_times[rows], in_records[rows], in_payloads[rows], lengths[rows])
    return BagChunk(file, None, index, layout=_Layout(log_times, payloads, lengths, spans))


def _laid_out(headers: np.ndarray, payloads: bytes, lengths: np.ndarray) -> bytes:
    """Each header followed by its payload: row by row in numpy when the payloads are all of
    one length (a topic of fixed-size messages), else joined from slices."""
    import numpy as np

    count, size = len(headers), MESSAGE_RECORD_HEADER.size
    if count and (lengths == lengths[0]).all():
        width = int(lengths[0])
        records = np.empty((count, size + width), np.uint8)
        records[:, :size] = headers.view(np.uint8).reshape(count, size)
        records[:, size:] = np.frombuffer(payloads, np.uint8).reshape(count, width)
        return records.tobytes()
    view = memoryview(payloads)
    ends = np.cumsum(lengths).tolist()
    parts: list[object] = [None] * (2 * count)
    parts[0::2] = headers.view(f"V{size}").tolist()  # one bytes object each, made in C
    parts[1::2] = [view[end - n : end] for end, n in zip(ends, lengths.tolist(), strict=True)]
    return b"".join(parts)  # type: ignore[arg-type]
