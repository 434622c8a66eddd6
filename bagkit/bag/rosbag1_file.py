"""The ROS 1 back-end: a ``.bag`` (format 2.0) read through rosbags' rosbag1 reader.

The records are parsed by :mod:`rosbags.rosbag1.reader` (its ``Header`` and its connection,
chunk-info and index-data readers); this module decides what is read when. :meth:`open`
reads the bag's index only (the connection and chunk-info records at ``index_pos``, and each
chunk's record header for its compression and size): counts per topic, times and sizes come
from it, no message is read. A chunk's index-data records (where each message is) are read
when a command needs them, and the chunk's data when its messages are read.

Above this layer a ROS 1 bag is a ROS 2 bag (:mod:`bagkit.bag.ros1_types`): topics carry ROS 2
type names, definitions and hashes, payloads are CDR, a message's log and publish time are its
ROS 1 record time (header stamps stay in the payload). :meth:`chunks` hands out each ROS 1
chunk as MCAP Message records, so the bulk readers take it as they take an MCAP chunk.

Every byte is untrusted: a chunk declaring more than ``max_chunk_size`` decompressed bytes,
or decompressing to other than it declares, loses its messages (one problem line), as does a
message whose payload does not match its definition.
"""

from __future__ import annotations

import heapq
import io
import itertools
import os
from collections.abc import Iterator
from pathlib import Path
from typing import TYPE_CHECKING, BinaryIO

from rosbags.interfaces import Connection
from rosbags.rosbag1.reader import (
    ChunkInfo,
    Header,
    IndexData,
    Reader,
    RecordType,
    read_uint32,
)

from bagkit.bag.errors import CorruptBagError, NotABagError, UnsupportedStorageError
from bagkit.bag.mcapio.message_index import Span, widen
from bagkit.bag.messages import BagMessage, TopicInfo, make_message
from bagkit.bag.ros1_types import LATCHED_QOS, Ros2Type, ros2_types
from bagkit.bag.rosbag1_check import disagreements
from bagkit.bag.rosbag1_records import (
    RECORD_ERRORS,
    ChunkDataError,
    ChunkRecord,
    chunk_data,
    mcap_records,
    message_at,
)
from bagkit.bag.storage import ROSBAG1_MAGIC, BagChunk

if TYPE_CHECKING:
    import numpy as np


class Rosbag1File:
    """A ROS 1 bag file (format 2.0), a :class:`~bagkit.bag.storage.StorageFile`.

    Args:
        path: the ``.bag`` file.
        max_chunk_size: the largest decompressed chunk read (larger ones: messages lost).
    """

    storage_identifier = "rosbag1"
    has_summary = True

    def __init__(self, path: Path, *, max_chunk_size: int) -> None:
        self.path = path
        self.max_chunk_size = max_chunk_size
        self.topics: dict[str, TopicInfo] = {}
        self.definitions: dict[str, str] = {}
        self.topic_definitions: dict[str, str] = {}  # one text per ROS 2 type
        self.topic_counts: dict[str, int] = {}
        self.start_ns = self.end_ns = 0
        self.problems: list[str] = []
        self.compression = ""
        self.compressed_size = self.uncompressed_size = 0
        self._reader = Reader(path)
        self._types: dict[int, Ros2Type] = {}
        self._topic_of: dict[int, str] = {}  # connection id -> topic
        self._chunks: list[ChunkRecord] = []
        self._indexes: dict[int, dict[int, list[IndexData]]] = {}  # chunk pos -> conn -> entries
        self._lost: dict[str, int] = {}  # topic -> payloads that did not convert
        self._connection_ids: set[int] = set()  # of the index's connection records

    @property
    def _bio(self) -> BinaryIO:
        assert self._reader.bio is not None
        return self._reader.bio

    def open(self) -> None:
        """Read the bag's index: connections, chunk infos and chunk record headers.

        Raises:
            NotABagError: no ROS 1 bag 2.0 magic. UnsupportedStorageError: encrypted.
            CorruptBagError: the header or index cannot be read (truncated, not indexed).
        """
        self._reader.bio = open(self.path, "rb")  # noqa: SIM115 (closed by close())
        if self._bio.readline(64) != ROSBAG1_MAGIC:
            raise NotABagError(f"{self.path}: not a ROS 1 bag (format 2.0)")
        try:
            index_pos, conn_count, chunk_count = self._bag_header()
            if index_pos == 0:
                raise CorruptBagError(
                    f"{self.path}: the ROS 1 bag has no index (not closed cleanly: "
                    "`rosbag reindex` it)"
                )
            size = os.fstat(self._bio.fileno()).st_size
            # The index is written last (at the very end of a bag without connections).
            if index_pos > size or (index_pos == size and conn_count + chunk_count):
                raise CorruptBagError(
                    f"{self.path}: the ROS 1 bag is cut short at {size} bytes (its index "
                    f"starts at byte {index_pos}: `rosbag reindex` it)"
                )
            self._bio.seek(index_pos)
            connections = [self._reader.read_connection() for _ in range(conn_count)]
            infos = [self._reader.read_chunk_info() for _ in range(chunk_count)]
            self._chunks = [self._chunk_record(info) for info in infos]
        except RECORD_ERRORS as exc:
            raise CorruptBagError(f"{self.path}: the ROS 1 bag's index is damaged ({exc})") from exc
        self._connection_ids = {c.id for c in connections}
        self._types, problems = ros2_types(connections)
        for problem in problems:
            self._problem(f"{problem}: its messages are left out")
        self._describe(connections)

    def _bag_header(self) -> tuple[int, int, int]:
        header = Header.read(self._bio, RecordType.BAGHEADER)
        if "encryptor" in header and header.get_string("encryptor"):
            raise UnsupportedStorageError(
                f"{self.path}: encrypted ROS 1 bags ({header.get_string('encryptor')}) "
                "are not supported"
            )
        return (
            header.get_uint64("index_pos"),
            header.get_uint32("conn_count"),
            header.get_uint32("chunk_count"),
        )

    def _chunk_record(self, info: ChunkInfo) -> ChunkRecord:
        self._bio.seek(info.pos)
        header = Header.read(self._bio, RecordType.CHUNK)
        data_size = read_uint32(self._bio)
        data_pos = self._bio.tell()
        return ChunkRecord(
            info,
            header.get_string("compression"),
            header.get_uint32("size"),
            data_pos,
            data_size,
            data_pos + data_size,
        )

    def _describe(self, connections: list[Connection]) -> None:
        for conn in connections:
            mapped = self._types.get(conn.id)
            if mapped is None:
                continue
            known = self.topics.get(conn.topic)
            if known is not None and known.type != mapped.name:
                self._problem(
                    f"{conn.topic} has type {known.type} and {mapped.name}: "
                    f"the {mapped.name} messages are left out"
                )
                del self._types[conn.id]
                continue
            qos = LATCHED_QOS if mapped.latched else ""
            if known is None or (qos and not known.offered_qos_profiles):
                self.topics[conn.topic] = TopicInfo(
                    conn.topic, mapped.name, "cdr", qos, mapped.type_hash
                )
            self.definitions.setdefault(mapped.name, mapped.definition)
            self._topic_of[conn.id] = conn.topic
        self.topic_counts = dict.fromkeys(self.topics, 0)
        with_messages = []
        for chunk in self._chunks:
            for conn_id, count in chunk.info.connection_counts.items():
                topic = self._topic_of.get(conn_id)
                if topic is not None and count:
                    self.topic_counts[topic] += count
                    with_messages.append(chunk)
        if with_messages:
            self.start_ns = min(c.info.start_time for c in with_messages)
            self.end_ns = max(c.info.end_time for c in with_messages) - 1  # rosbags adds 1
        kinds = sorted({c.compression for c in self._chunks})
        self.compression = ",".join(kinds)
        self.compressed_size = sum(c.data_size for c in self._chunks)
        self.uncompressed_size = sum(c.size for c in self._chunks)

    def _problem(self, text: str) -> None:
        line = f"{self.path.name}: {text}"
        if line not in self.problems:
            self.problems.append(line)

    def close(self) -> None:
        """Close the file."""
        if self._reader.bio is not None:
            self._reader.bio.close()
            self._reader.bio = None

    # -- indexes ----------------------------------------------------------------------------

    def check_index(self) -> list[str]:
        """``doctor``'s walk: each chunk's records against its chunk info and index data
        (messages, times, connections), one line per disagreement (the problems of reading
        it, in ``problems``)."""
        found: list[str] = []
        for chunk in self._chunks:
            where = f"chunk at byte {chunk.info.pos}"
            data = self._data(chunk)
            if data is None:
                continue  # a problem already
            index = self._chunk_index(chunk)
            found += disagreements(
                where,
                chunk.info,
                data,
                index=index,
                topic_of=self._topic_of,
                known=self._connection_ids,
            )
        return found

    def _chunk_index(self, chunk: ChunkRecord) -> dict[int, list[IndexData]]:
        """Where each message of ``chunk`` is, by connection (read once, then kept)."""
        found = self._indexes.get(chunk.info.pos)
        if found is None:
            entries: dict[int, list[IndexData]] = {c: [] for c in chunk.info.connection_counts}
            try:
                self._bio.seek(chunk.index_pos)
                for _ in chunk.info.connection_counts:
                    self._reader.read_index_data(chunk.info.pos, entries)
            except RECORD_ERRORS as exc:
                self._problem(
                    f"the index of the chunk at byte {chunk.info.pos} is damaged ({exc}): "
                    "its messages are lost"
                )
                entries = {}
            found = self._indexes[chunk.info.pos] = entries
        return found

    def _holding(self, conn_ids: set[int]) -> list[ChunkRecord]:
        return [c for c in self._chunks if not conn_ids.isdisjoint(c.info.connection_counts)]

    def _conn_ids(self, topics: set[str] | None) -> set[int]:
        return {c for c, t in self._topic_of.items() if topics is None or t in topics}

    def index_log_times(self, topic: str) -> np.ndarray | None:
        """None: the chunks' index data is read with the messages (no cheaper source)."""
        return None

    def topic_spans(self, *, message_indexes: bool = True) -> dict[str, Span]:
        """(first, last) log time of each topic, from the index data of the chunks at its ends
        (whatever ``message_indexes`` says: a ROS 1 bag is a local file or copy)."""
        spans: dict[str, Span] = {}
        for topic in self.topics:
            ids = self._conn_ids({topic})
            chunks = self._holding(ids)
            if not chunks:
                continue
            first_end = min(c.info.end_time for c in chunks)
            last_start = max(c.info.start_time for c in chunks)
            for chunk in chunks:
                if chunk.info.start_time < first_end or chunk.info.end_time > last_start:
                    times = [e.time for c in ids for e in self._chunk_index(chunk).get(c, ())]
                    if times:
                        widen(spans, topic, min(times), max(times))
        return spans

    # -- messages ---------------------------------------------------------------------------

    def _entries(
        self, topics: set[str] | None, start_ns: int | None, end_ns: int | None
    ) -> Iterator[tuple[ChunkRecord, list[tuple[int, int, int]]]]:
        """Each chunk holding ``topics`` in the window, with its selected ``(time, offset,
        connection)`` entries in storage order, chunks by start time."""
        ids = self._conn_ids(topics)
        low = start_ns if start_ns is not None else -1
        high = end_ns if end_ns is not None else 1 << 64
        for chunk in sorted(self._holding(ids), key=lambda c: (c.info.start_time, c.info.pos)):
            if chunk.info.end_time < low or chunk.info.start_time >= high:
                continue
            index = self._chunk_index(chunk)
            entries = sorted(
                (e.time, e.offset, c) for c in ids for e in index.get(c, ()) if low <= e.time < high
            )
            if entries:
                yield chunk, entries

    def _data(self, chunk: ChunkRecord) -> bytes | None:
        """The decompressed data of ``chunk``, or None (a problem) when it cannot be had."""
        try:
            return chunk_data(self._bio, chunk, self.max_chunk_size)
        except ChunkDataError as exc:
            self._problem(f"the chunk at byte {chunk.info.pos} {exc}: its messages are lost")
            return None

    def _payloads(
        self, chunk: ChunkRecord, entries: list[tuple[int, int, int]]
    ) -> Iterator[tuple[int, int, bytes]]:
        """``(time, connection, CDR payload)`` of each entry; damage is counted as lost."""
        data = self._data(chunk)
        if data is None:
            return
        stream = io.BytesIO(data)
        for time, offset, conn_id in entries:
            try:
                raw = message_at(stream, offset)
            except RECORD_ERRORS as exc:
                self._problem(
                    f"the chunk at byte {chunk.info.pos} holds no message at its offset "
                    f"{offset} ({exc}): the message is lost"
                )
                continue
            try:
                payload = bytes(self._types[conn_id].to_cdr(raw))
            except Exception:
                self._lose(self._topic_of[conn_id])
                continue
            yield time, conn_id, payload

    def _lose(self, topic: str) -> None:
        """Count a payload of ``topic`` that did not convert (one problem line per topic)."""
        count = self._lost[topic] = self._lost.get(topic, 0) + 1
        prefix = f"{self.path.name}: messages of {topic} that do not match their definition"
        self.problems[:] = [p for p in self.problems if not p.startswith(prefix)]
        self.problems.append(f"{prefix}: {count} lost")

    def messages(
        self, topics: set[str] | None, start_ns: int | None, end_ns: int | None
    ) -> Iterator[BagMessage]:
        """Yield the messages in log-time order (ties in storage order), as CDR.

        A chunk is decompressed when the merge reaches its start time, and let go once its
        messages are out: memory is the chunks that overlap in time, not the bag.
        """
        chunks = self._entries(topics, start_ns, end_ns)
        following = next(chunks, None)
        heap: list[tuple[int, int, int, int, bytes, Iterator[tuple[int, int, bytes]]]] = []
        rank = order = 0
        topic_of = self._topic_of
        while heap or following is not None:
            while following is not None and (
                not heap or following[0].info.start_time <= heap[0][0]
            ):
                stream = self._payloads(*following)
                for time, conn_id, payload in itertools.islice(stream, 1):
                    heapq.heappush(heap, (time, rank, order, conn_id, payload, stream))
                    order += 1
                rank += 1
                following = next(chunks, None)
            if not heap:
                continue
            time, stream_rank, _, conn_id, payload, stream = heapq.heappop(heap)
            yield make_message(topic_of[conn_id], payload, time, time, 0)
            for time, conn_id, payload in itertools.islice(stream, 1):
                heapq.heappush(heap, (time, stream_rank, order, conn_id, payload, stream))
                order += 1

    def last_messages(self, topics: set[str], before_ns: int) -> dict[str, BagMessage]:
        """The last message before ``before_ns`` of each topic, from the chunks' index data
        (the chunks ending last first, until none can hold a later one)."""
        found: dict[str, BagMessage] = {}
        for topic in sorted(topics & self.topics.keys()):
            ids = self._conn_ids({topic})
            best: tuple[int, int, int, int] | None = None  # time, chunk pos, offset, conn
            chunks = [c for c in self._holding(ids) if c.info.start_time < before_ns]
            by_pos = {c.info.pos: c for c in chunks}
            for chunk in sorted(chunks, key=lambda c: -c.info.end_time):
                if best is not None and chunk.info.end_time <= best[0]:
                    break
                index = self._chunk_index(chunk)
                for conn_id in ids:
                    for entry in index.get(conn_id, ()):
                        key = (entry.time, chunk.info.pos, entry.offset, conn_id)
                        if entry.time < before_ns and (best is None or key > best):
                            best = key
            if best is not None:
                time, pos, offset, conn_id = best
                for _, _, payload in self._payloads(by_pos[pos], [(time, offset, conn_id)]):
                    found[topic] = make_message(topic, payload, time, time, 0)
        return found

    def chunks(
        self, topics: set[str] | None, start_ns: int | None = None, end_ns: int | None = None
    ) -> Iterator[BagChunk]:
        """Each ROS 1 chunk holding ``topics`` in the time range as MCAP Message records of CDR
        payloads."""
        for chunk, entries in self._entries(topics, start_ns, end_ns):
            built = mcap_records(self._payloads(chunk, entries), self._topic_of)
            if built is not None:
                yield BagChunk(self.path, *built)
