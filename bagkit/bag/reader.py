"""BagReader: one logical bag from a bag directory, a split bag, or a single storage file."""

from __future__ import annotations

import heapq
import itertools
from collections.abc import Iterable, Iterator
from pathlib import Path
from types import TracebackType
from typing import TYPE_CHECKING

from bagkit.bag.bag_contents import BagContents
from bagkit.bag.compression import Decompression
from bagkit.bag.distro_definitions import distro_definitions
from bagkit.bag.errors import BagError, CorruptBagError, EmptyBagError, NotABagError
from bagkit.bag.mcap_file import McapFile
from bagkit.bag.mcapio import DEFAULT_MAX_CHUNK_SIZE
from bagkit.bag.mcapio.message_index import Span, widen
from bagkit.bag.messages import BagMessage, TopicInfo
from bagkit.bag.metadata import METADATA_FILENAME, BagMetadata
from bagkit.bag.storage import BagChunk, StorageFile, chunk_of_rows
from bagkit.bag.storage_files import (
    COMPRESSED_STORAGE_SUFFIXES,
    bag_path,
    find_storage_files,
    listed_file,
    open_storage_file,
)
from bagkit.storage.paths import UrlPath

if TYPE_CHECKING:
    import numpy as np

# Messages laid out in one chunk for a back-end without chunks of its own.
MESSAGES_PER_CHUNK = 4_096


class BagReader:
    """Read a bag: a rosbag2 bag directory (split or not, with or without ``metadata.yaml``), a
    single ``.mcap`` or ``.db3`` file, or a ROS 1 ``.bag`` file (read as ROS 2, see
    :mod:`bagkit.bag.rosbag1_file`).

    Topics, counts and times come from the storage files (MCAP summaries when present, a salvage
    scan otherwise); ``metadata.yaml`` only fills in what the storage lacks (QoS, type hashes).
    ``definitions`` and ``topic_definitions`` are those of :class:`~bagkit.bag.storage.StorageFile`
    over all files (decode with ``MessageTypes.for_bag``: per topic where texts differ).
    Nothing is read before :meth:`open` (``with BagReader(path) as bag:`` opens it).

    Args:
        path: the bag.
        allow_empty: accept a bag without messages (by default EmptyBagError).
        check_crc: check each MCAP chunk's CRC when it is read; a damaged chunk's messages are
            then reported lost in ``problems`` instead of being decoded.
        max_chunk_size: the largest uncompressed MCAP chunk read; a chunk declaring more is a
            problem (its messages lost), so memory stays bounded whatever a file declares.
        distro: the ROS 2 distribution whose types define what the bag stores no definition
            of (default: ``BAGKIT_DISTRO``, else the bag's ``ros_distro``, else Jazzy).
    """

    def __init__(
        self,
        path: str | Path,
        *,
        allow_empty: bool = False,
        check_crc: bool = True,
        max_chunk_size: int = DEFAULT_MAX_CHUNK_SIZE,
        distro: str | None = None,
    ) -> None:
        self.path = bag_path(path)
        self.directory = self.path
        self.allow_empty = allow_empty
        self.check_crc = check_crc
        self.max_chunk_size = max_chunk_size
        self.files: list[Path] = []
        self.metadata: BagMetadata | None = None
        self.storage = ""
        self.topics: dict[str, TopicInfo] = {}
        self.distro = distro
        self._definitions: dict[str, str] = {}
        self._assumed: frozenset[str] = frozenset()
        self._completed = False
        self.topic_definitions: dict[str, str] = {}
        self.topic_counts: dict[str, int] = {}
        self.start_ns = 0
        self.end_ns = 0
        self._missing: list[str] = []
        self._storage: list[StorageFile] = []
        self._opened = False

    def open(self) -> BagReader:
        """Open the storage files and read what they hold; return self.

        Raises:
            BagNotFoundError, NotABagError, CorruptBagError, UnsupportedStorageError,
            EmptyBagError.
        """
        if self._opened:
            return self
        self.directory, self.files, self.metadata = find_storage_files(self.path)
        self._missing = [
            f"{name}: listed in {METADATA_FILENAME} but missing"
            for name in (self.metadata.relative_file_paths if self.metadata else [])
            if not listed_file(self.directory, name).is_file()
        ]
        try:
            self._open_storage()
        except BaseException:
            self.close()
            raise
        self._opened = True
        self._describe()
        if not self.allow_empty and self.message_count == 0:
            self.close()
            problems = "; ".join(self.problems)
            raise EmptyBagError(
                f"{self.path}: the bag holds no messages" + (f" ({problems})" if problems else "")
            )
        return self

    def _open_storage(self) -> None:
        unreadable: list[BagError] = []
        for file in self.files:
            try:
                self._storage.append(
                    open_storage_file(
                        file,
                        check_crc=self.check_crc,
                        max_chunk_size=self.max_chunk_size,
                        compression_mode=self.metadata.compression_mode if self.metadata else None,
                    )
                )
            except (NotABagError, CorruptBagError) as exc:
                # One bad file (a split the recorder was killed in) does not lose the rest.
                unreadable.append(exc)
                self._missing.append(f"{file.name}: unreadable, skipped ({exc})")
        if not self._storage:
            raise unreadable[0]
        self.files = [s.path for s in self._storage]

    def _describe(self) -> None:
        """Topics, definitions, counts and times of all storage files together."""
        contents = BagContents.of(self._storage, self.metadata)
        self.storage = contents.storage
        self.topics, self.topic_counts = contents.topics, contents.topic_counts
        self._definitions, self.topic_definitions = contents.definitions, contents.topic_definitions
        self.start_ns, self.end_ns = contents.start_ns, contents.end_ns

    @property
    def definitions(self) -> dict[str, str]:
        """``ros2msg`` text by type name: as stored, then for the types the bag stores none of
        (Foxy to Humble ``.db3``), its distribution's (see :mod:`bagkit.bag.distro_definitions`,
        asked for on first use: it may warn)."""
        if self._opened and not self._completed:
            self._completed = True
            missing = {t.type for t in self.topics.values()} - set(self._definitions)
            distro = self.metadata.ros_distro if self.metadata else ""
            found = distro_definitions(missing, distro, self.distro)
            self._definitions.update(found)
            self._assumed = frozenset(found)
        return self._definitions

    @property
    def assumed_types(self) -> frozenset[str]:
        """The types of :attr:`definitions` that the bag stores no definition of: a
        distribution's, which its payloads may not follow (a wrong guess of the distro)."""
        _ = self.definitions  # completes them, and with them the types assumed
        return self._assumed

    def __enter__(self) -> BagReader:
        return self.open()

    def __exit__(
        self,
        exc_type: type[BaseException] | None,
        exc: BaseException | None,
        tb: TracebackType | None,
    ) -> None:
        self.close()

    def _check_open(self) -> None:
        if not self._opened:
            raise BagError(f"{self.path}: the reader is not open (use open() or a with block)")

    def close(self) -> None:
        """Close the storage files."""
        for storage in self._storage:
            storage.close()

    @property
    def message_count(self) -> int:
        """Messages in the bag."""
        return sum(self.topic_counts.values())

    @property
    def problems(self) -> list[str]:
        """What could not be read (truncated files, unreadable chunks); grows while reading."""
        return self._missing + [p for s in self._storage for p in s.problems]

    @property
    def in_storage(self) -> bool:
        """True for a bag named by a URL (read by range requests), False for one on disk."""
        return isinstance(self.path, UrlPath)

    @property
    def storage_files(self) -> tuple[StorageFile, ...]:
        """The storage files opened (their indexes, for surgery not to read them again)."""
        return tuple(self._storage)

    @property
    def has_summary(self) -> bool:
        """True when no file had to be salvaged (every MCAP file's summary was used)."""
        return all(s.has_summary for s in self._storage)

    @property
    def size_bytes(self) -> int:
        """Total size of the storage files."""
        return sum(f.stat().st_size for f in self.files)

    @property
    def compression(self) -> str:
        """Chunk compressions used (``zstd``, ``lz4``, ``none``, comma-separated), or ``""``;
        rosbag2's zstd of files or payloads among them (apart: :attr:`compression_mode`)."""
        kinds = {k for s in self._storage for k in s.compression.split(",") if k}
        return ",".join(sorted(kinds))

    @property
    def compression_mode(self) -> str:
        """rosbag2's own compression (zstd, ``--compression-mode``): ``file`` (``.zstd``
        files), ``message`` (each payload), or ``""``."""
        modes = {s.mode for s in self._storage if isinstance(s, Decompression)}
        if any(f.name.endswith(COMPRESSED_STORAGE_SUFFIXES) for f in self.files):
            modes.add("file")  # also a file in storage, decompressed while it was copied
        return ",".join(sorted(modes))

    @property
    def chunk_compression(self) -> str:
        """The compressions of the storage's own chunks (MCAP's, ROS 1's: ``zstd``, ``lz4``,
        ``none``, comma-separated), or ``""`` (sqlite3), whatever rosbag2 compressed."""
        stores = [s.inner if isinstance(s, Decompression) else s for s in self._storage]
        kinds = {k for s in stores for k in s.compression.split(",") if k}
        return ",".join(sorted(kinds))

    @property
    def compression_label(self) -> str:
        """How the bag is compressed, in one line (:attr:`CompressionWords.label`)."""
        from bagkit.bag.compression_words import CompressionWords  # the catalogue's, not at start

        return CompressionWords.of(self.compression_mode, self.chunk_compression).label

    @property
    def compressed_size(self) -> int:
        """Bytes of chunk data as stored."""
        return sum(s.compressed_size for s in self._storage)

    @property
    def uncompressed_size(self) -> int:
        """Bytes of chunk data once decompressed."""
        return sum(s.uncompressed_size for s in self._storage)

    def messages(
        self,
        topics: Iterable[str] | None = None,
        start_ns: int | None = None,
        end_ns: int | None = None,
    ) -> Iterator[BagMessage]:
        """Yield messages in log-time order across all files (ties keep file order).

        Args:
            topics: only these topics (all when None).
            start_ns: only messages with ``log_time >= start_ns``.
            end_ns: only messages with ``log_time < end_ns``.
        """
        self._check_open()
        wanted = set(topics) if topics is not None else None
        streams = [s.messages(wanted, start_ns, end_ns) for s in self._storage]
        if len(streams) == 1:
            yield from streams[0]
        else:
            yield from heapq.merge(*streams, key=lambda m: m.log_time)

    def last_messages(self, topics: Iterable[str], before_ns: int) -> dict[str, BagMessage]:
        """The last message with ``log_time < before_ns`` of each of ``topics`` that has one.

        From the indexes of each file (MCAP Message Index records, an SQL query), not by
        reading the bag from its start; over several files, the latest (ties: the later file,
        as :meth:`messages` yields it last). See :mod:`bagkit.bag.latched`.
        """
        self._check_open()
        wanted = set(topics)
        found: dict[str, BagMessage] = {}
        for storage in self._storage:
            for topic, message in storage.last_messages(wanted, before_ns).items():
                if topic not in found or message.log_time >= found[topic].log_time:
                    found[topic] = message
        return found

    def largest_message(self, topics: Iterable[str]) -> int:
        """Payload bytes of the largest message of ``topics`` near the bag's end (0: none).

        A topic's messages are taken to be of one size (images, point clouds of one sensor):
        MCAP files answer from the Message Index records of the last chunk holding each topic,
        without numpy or decompression (the player sizes its shared-memory segment by this
        before its participant exists); other files by each topic's last message.
        """
        self._check_open()
        wanted = set(topics)
        largest = 0
        for storage in self._storage:
            sizes = storage.largest_messages(wanted) if isinstance(storage, McapFile) else None
            if sizes is None:
                last = storage.last_messages(wanted, storage.end_ns + 1)
                sizes = {topic: len(message.data) for topic, message in last.items()}
            largest = max(largest, *sizes.values(), 0)
        return largest

    def chunks(
        self,
        topics: Iterable[str] | None = None,
        start_ns: int | None = None,
        end_ns: int | None = None,
    ) -> Iterator[BagChunk]:
        """Yield the decompressed chunks holding ``topics``, file by file, in file order.

        For bulk decoding: each :class:`BagChunk` carries the message-index entries per topic.
        SQLite3 files yield their rows laid out as chunks, in log-time order; a back-end that
        yields no chunk although it holds messages of ``topics`` has its messages laid out so.
        Chunks wholly outside ``start_ns <= log_time < end_ns`` are not read (nor reported
        lost); those read may hold messages outside it (see ``StorageFile.chunks``).
        """
        self._check_open()
        wanted = set(topics) if topics is not None else None
        for storage in self._storage:
            found = False
            for chunk in storage.chunks(wanted, start_ns, end_ns):
                found = True
                yield chunk
            if not found and any(
                n for t, n in storage.topic_counts.items() if wanted is None or t in wanted
            ):
                messages = storage.messages(wanted, start_ns, end_ns)
                yield from _chunks_of_messages(storage.path, messages)

    def topic_spans(self, *, message_indexes: bool | None = None) -> dict[str, Span]:
        """(first, last) log time of each topic with messages, from indexes (no message read).

        See :meth:`bagkit.bag.storage.StorageFile.topic_spans`; over all files.
        ``message_indexes``: read the Message Index records of the chunks at each topic's ends
        (exact spans); False: the chunk bounds that the summary gives (a span holding the true
        one). Default: True for a bag on disk, False for one in storage (a range request
        more per file, and as many bytes as its summary on a one-chunk bag).
        """
        self._check_open()
        if message_indexes is None:
            message_indexes = not self.in_storage
        spans: dict[str, Span] = {}
        for storage in self._storage:
            for topic, (first, last) in storage.topic_spans(
                message_indexes=message_indexes
            ).items():
                widen(spans, topic, first, last)
        return spans

    def index_log_times(
        self, topic: str, start_ns: int | None = None, end_ns: int | None = None
    ) -> np.ndarray | None:
        """The log times of ``topic``'s messages with ``start_ns <= t < end_ns``, ascending,
        from indexes (no message read); None when a file's indexes do not tell (see
        :meth:`bagkit.bag.storage.StorageFile.index_log_times`)."""
        import numpy as np

        self._check_open()
        parts = []
        for storage in self._storage:
            times = storage.index_log_times(topic)
            if times is None:
                return None
            parts.append(times)
        times = np.sort(np.concatenate([np.zeros(0, np.int64), *parts]), kind="stable")
        lower = 0 if start_ns is None else np.searchsorted(times, start_ns)
        upper = len(times) if end_ns is None else np.searchsorted(times, end_ns)
        return times[lower:upper]


def _chunks_of_messages(file: Path, messages: Iterator[BagMessage]) -> Iterator[BagChunk]:
    """``messages`` laid out as chunks of :data:`MESSAGES_PER_CHUNK` Message records."""
    while batch := list(itertools.islice(messages, MESSAGES_PER_CHUNK)):
        yield chunk_of_rows(
            file, [m.topic for m in batch], [m.log_time for m in batch], [m.data for m in batch]
        )
