"""rosbag2's compression, a layer between a storage file and its back-end.

rosbag2 compresses with zstd in one of two modes (``metadata.yaml``'s ``compression_mode``):

- ``file``: each storage file is one zstd stream (``name_0.db3.zstd``). It is decompressed
  into a temporary file that the back-end then opens, bounded by the free space of the
  temporary directory (and by what its frame declares), deleted when the file is closed.
- ``message``: each payload is one zstd frame; :class:`MessageDecompression` wraps the
  back-end and decompresses payloads as they are read, in chunks too (the bulk decoders see
  plain CDR). Without ``metadata.yaml`` the mode is found from a SQLite3 file's payloads
  (a CDR payload starts with a zero byte, a zstd frame with its magic number) or an MCAP
  file's own ``rosbag2`` Metadata record.

The bytes are the bag's, untrusted: a frame that declares or yields more than the bound is
refused (a file) or counted lost (a payload), never allocated.
"""

from __future__ import annotations

import shutil
from collections.abc import Callable, Iterator
from pathlib import Path
from typing import TYPE_CHECKING, BinaryIO

import zstandard

from bagkit.bag.errors import CorruptBagError
from bagkit.bag.mcapio.message_index import Span
from bagkit.bag.mcapio.records import MESSAGE_PREFIX, MESSAGE_RECORD_HEADER
from bagkit.bag.messages import BagMessage, make_message
from bagkit.bag.storage import BagChunk, FiltersPayloads, StorageFile
from bagkit.words import counted

if TYPE_CHECKING:
    import numpy as np

ZSTD_MAGIC = b"\x28\xb5\x2f\xfd"
# Room left free in the temporary directory when a file is decompressed into it.
DISK_RESERVE = 256 << 20
_COPY_BLOCK = 1 << 20


def is_zstd(head: bytes) -> bool:
    """True when ``head`` starts a zstd frame."""
    return head[:4] == ZSTD_MAGIC


def decompressed_copy(path: Path, limit: int | None = None) -> Path:
    """Decompress the zstd file ``path`` into a new temporary directory; return the copy
    (named as ``path`` without ``.zstd``: problems name it so).

    Args:
        path: a rosbag2 file-compressed storage file.
        limit: the most bytes written; by default the free space of the temporary directory
            less :data:`DISK_RESERVE`.

    Raises:
        CorruptBagError: not a whole zstd stream, or it declares or yields more than ``limit``.
    """
    import tempfile  # file-compressed bags only: a command on an MCAP bag starts without it

    directory = tempfile.gettempdir()
    if limit is None:
        limit = max(shutil.disk_usage(directory).free - DISK_RESERVE, 0)
    with path.open("rb") as source:  # a UrlPath's is read by ranges, with read-ahead
        declared = zstandard.frame_content_size(source.read(18))
        if declared > limit:
            raise CorruptBagError(
                f"{path}: decompresses to {declared} bytes, more than the {limit} bytes free "
                f"in {directory}"
            )
        source.seek(0)
        copy = Path(tempfile.mkdtemp(prefix="bagkit-")) / path.stem
        try:
            with open(copy, "wb") as out:
                _copy_bounded(source, out, limit, path, directory)
        except BaseException:
            shutil.rmtree(copy.parent, ignore_errors=True)
            raise
    return copy


def _copy_bounded(source: BinaryIO, out: BinaryIO, limit: int, path: Path, directory: str) -> None:
    """Stream-decompress ``source`` into ``out``, stopping at ``limit`` bytes."""
    written = 0
    reader = zstandard.ZstdDecompressor().stream_reader(source, read_across_frames=True)
    try:
        while block := reader.read(_COPY_BLOCK):
            written += len(block)
            if written > limit:
                raise CorruptBagError(
                    f"{path}: decompresses to more than the {limit} bytes free in {directory}"
                )
            out.write(block)
    except zstandard.ZstdError as exc:
        raise CorruptBagError(f"{path}: not a whole zstd stream ({exc})") from None


class PayloadDecompressor:
    """Decompresses zstd payloads, each bounded by ``limit`` bytes; counts the failures."""

    def __init__(self, limit: int) -> None:
        self.limit = limit
        self.failures: dict[str, tuple[int, str]] = {}
        self._decompressor = zstandard.ZstdDecompressor()
        self._decompress = self._decompressor.decompress

    def __call__(self, topic: str, data: bytes | memoryview) -> bytes | None:
        """The payload decompressed (a payload not framed as zstd as it is), or None when the
        frame does not decompress within the bound (counted in ``failures``)."""
        if data[:4] != ZSTD_MAGIC:
            return bytes(data)
        try:
            declared = zstandard.frame_content_size(data)
            if declared > self.limit:
                raise ValueError(f"declares {declared} bytes, more than {self.limit}")
            return self._decompress(data, max_output_size=self.limit)
        except (zstandard.ZstdError, ValueError) as exc:
            count, first = self.failures.get(topic, (0, str(exc)))
            self.failures[topic] = (count + 1, first)
            return None

    def many(self, payloads: list[bytes], topic_of: Callable[[int], str]) -> list[bytes | None]:
        """Each of ``payloads`` as :meth:`__call__` gives it; all at once when every one is a
        frame that declares its size within the bound (rosbag2's and rosbags' frames do)."""
        try:
            sizes = list(map(zstandard.frame_content_size, payloads))
            if min(sizes, default=0) >= 0 and max(sizes, default=0) <= self.limit:
                return list(map(self._decompress, payloads))
        except zstandard.ZstdError:
            pass  # not all frames, or a broken one: each on its own, to count which
        return [self(topic_of(i), payload) for i, payload in enumerate(payloads)]

    def joined(
        self, stored: bytes, lengths: np.ndarray, topic_of: Callable[[int], str]
    ) -> Iterator[tuple[np.ndarray, bytes, np.ndarray]]:
        """The payloads stored back to back in ``stored`` (``lengths``, int64) decompressed, in
        pieces of consecutive payloads: (indices of the payloads kept, their bytes back to
        back, their lengths), each piece at most ``limit`` bytes.

        Runs of frames that declare their sizes within the bound (rosbag2's and rosbags' do)
        are decompressed in one call each, bounded by the sum they declare: zstd checks each
        frame's size against its declaration, so a frame that is not what it declares fails
        its run. A failed run and the payloads of other kinds go one by one as
        :meth:`__call__` takes them (failures counted, the others kept).
        """
        import numpy as np

        from bagkit.bag.zstd_frames import declared_sizes

        starts = np.cumsum(lengths) - lengths
        sizes = declared_sizes(np.frombuffer(stored, np.uint8), starts, lengths)
        if not len(sizes) or sizes.min() < 0 or sizes.max() > self.limit:
            yield from self._one_by_one(stored, starts, lengths, 0, topic_of)
            return
        ends = np.cumsum(sizes)
        first = 0
        while first < len(sizes):
            before = int(ends[first - 1]) if first else 0
            last = max(int(np.searchsorted(ends, before + self.limit, side="right")), first + 1)
            run = slice(first, last)
            end = int(starts[last - 1] + lengths[last - 1])
            data = self._run(
                memoryview(stored)[int(starts[first]) : end], int(ends[last - 1]) - before
            )
            if data is None:
                yield from self._one_by_one(stored, starts[run], lengths[run], first, topic_of)
            else:
                yield np.arange(first, last), data, sizes[run]
            first = last

    def _run(self, frames: memoryview, size: int) -> bytes | None:
        """``frames`` decompressed when they yield exactly ``size`` bytes, else None."""
        reader = self._decompressor.stream_reader(frames, read_across_frames=True)
        try:
            data = reader.read(size + 1)
        except zstandard.ZstdError:
            return None
        return data if len(data) == size else None

    def _one_by_one(
        self,
        stored: bytes,
        starts: np.ndarray,
        lengths: np.ndarray,
        first: int,
        topic_of: Callable[[int], str],
    ) -> Iterator[tuple[np.ndarray, bytes, np.ndarray]]:
        """The payloads at ``starts`` (numbered from ``first``) each through :meth:`__call__`,
        in pieces of at most ``limit`` bytes (or one payload)."""
        import numpy as np

        view = memoryview(stored)
        kept: list[int] = []
        parts: list[bytes] = []
        size = 0
        for number, (start, length) in enumerate(
            zip(starts.tolist(), lengths.tolist(), strict=True), first
        ):
            data = self(topic_of(number), view[start : start + length])
            if data is None:
                continue
            if parts and size + len(data) > self.limit:
                yield (
                    np.array(kept, np.int64),
                    b"".join(parts),
                    np.fromiter(map(len, parts), np.int64),
                )
                kept, parts, size = [], [], 0
            kept.append(number)
            parts.append(data)
            size += len(data)
        if parts:
            yield _piece(kept, parts)

    def problems(self, file: Path) -> list[str]:
        """One line per topic with payloads that did not decompress."""
        return [
            f"{file.name}: {counted(count, 'message')} of {topic} did not decompress "
            f"({first}): lost"
            for topic, (count, first) in self.failures.items()
        ]


def _piece(kept: list[int], parts: list[bytes]) -> tuple[np.ndarray, bytes, np.ndarray]:
    import numpy as np

    return np.array(kept, np.int64), b"".join(parts), np.fromiter(map(len, parts), np.int64)


class Decompression:
    """A :class:`~bagkit.bag.storage.StorageFile` read through the back-end ``inner``, which
    opened the decompressed copy of a compressed file, or whose payloads are zstd frames.

    Args:
        inner: the opened back-end.
        path: the file as the bag holds it (``inner.path`` is its temporary copy in file mode).
        payloads: decompress each payload (message mode).
        limit: the largest payload decompressed (a larger one is lost, with a problem).
        temporary: the directory of the decompressed copy, removed on :meth:`close`.
    """

    def __init__(
        self,
        inner: StorageFile,
        path: Path,
        *,
        payloads: bool,
        limit: int,
        temporary: Path | None = None,
    ) -> None:
        self.inner = inner
        self.path = path
        self.storage_identifier = inner.storage_identifier
        self.topics = inner.topics
        self.definitions = inner.definitions
        self.topic_definitions = inner.topic_definitions
        self.topic_counts = inner.topic_counts
        self.start_ns, self.end_ns = inner.start_ns, inner.end_ns
        self.problems = inner.problems
        self.has_summary = inner.has_summary
        self.compression = ",".join(k for k in ("zstd", inner.compression) if k)
        self.mode = "message" if payloads else "file"
        """rosbag2's compression mode (``metadata.yaml``'s ``compression_mode``)."""
        self.compressed_size = inner.compressed_size
        self.uncompressed_size = inner.uncompressed_size
        if temporary is not None:  # the file's own compression is the one said
            self.compressed_size = path.stat().st_size
            self.uncompressed_size = inner.path.stat().st_size
        self._temporary = temporary
        self._decompress = PayloadDecompressor(limit) if payloads else None
        self._filtered: PayloadDecompressor | None = None
        if self._decompress is not None and isinstance(inner, FiltersPayloads):
            # The back-end decompresses as it reads (no chunk laid out twice); problems below.
            inner.payload_filter = self._decompress
            self._filtered = self._decompress
            self._decompress = None

    def open(self) -> None:
        """Nothing: ``inner`` is open."""

    def close(self) -> None:
        """Close ``inner`` and remove the decompressed copy."""
        self.inner.close()
        if self._temporary is not None:
            shutil.rmtree(self._temporary, ignore_errors=True)

    def _report(self) -> None:
        decompress = self._decompress or self._filtered
        if decompress is None:
            return
        for problem in decompress.problems(self.path):
            if problem not in self.problems:
                self.problems.append(problem)

    def messages(
        self, topics: set[str] | None, start_ns: int | None, end_ns: int | None
    ) -> Iterator[BagMessage]:
        """The back-end's messages, decompressed (those that do not decompress left out)."""
        decompress = self._decompress
        if decompress is None:
            try:
                yield from self.inner.messages(topics, start_ns, end_ns)
            finally:
                self._report()
            return
        try:
            for message in self.inner.messages(topics, start_ns, end_ns):
                data = decompress(message.topic, message.data)
                if data is not None:
                    yield make_message(
                        message.topic,
                        data,
                        message.log_time,
                        message.publish_time,
                        message.sequence,
                    )
        finally:
            self._report()

    def last_messages(self, topics: set[str], before_ns: int) -> dict[str, BagMessage]:
        """The back-end's last messages, decompressed."""
        found = self.inner.last_messages(topics, before_ns)
        if self._decompress is None:
            self._report()
            return found
        for topic, message in list(found.items()):
            del found[topic]
            data = self._decompress(topic, message.data)
            if data is not None:
                found[topic] = make_message(
                    topic, data, message.log_time, message.publish_time, message.sequence
                )
        self._report()
        return found

    def chunks(
        self, topics: set[str] | None, start_ns: int | None = None, end_ns: int | None = None
    ) -> Iterator[BagChunk]:
        """The back-end's chunks with each Message record's payload decompressed."""
        if self._decompress is None:
            try:
                yield from self.inner.chunks(topics, start_ns, end_ns)
            finally:
                self._report()
            return
        try:
            for chunk in self.inner.chunks(topics, start_ns, end_ns):
                yield self._decompressed(chunk, topics)
        finally:
            self._report()

    def _decompressed(self, chunk: BagChunk, topics: set[str] | None) -> BagChunk:
        import numpy as np

        assert self._decompress is not None

        from bagkit.bag.mcapio.records import message_index_dtype

        records = bytearray()
        index: dict[str, np.ndarray] = {}
        unpack, pack = MESSAGE_RECORD_HEADER.unpack_from, MESSAGE_RECORD_HEADER.pack
        view = memoryview(chunk.records)
        for topic in chunk.message_index:
            if topics is not None and topic not in topics:
                continue
            log_times, starts, lengths = chunk.payloads(topic)
            entries: list[tuple[int, int]] = []
            for log_time, start, length in zip(
                log_times.tolist(), starts.tolist(), lengths.tolist(), strict=True
            ):
                data = self._decompress(topic, view[start : start + length])
                if data is None:
                    continue
                opcode, _, *prefix = unpack(view, start - MESSAGE_RECORD_HEADER.size)
                entries.append((log_time, len(records)))
                records += pack(opcode, MESSAGE_PREFIX.size + len(data), *prefix)
                records += data
            index[topic] = np.array(entries, dtype=message_index_dtype()).reshape(-1)
        problems = chunk.problems
        return BagChunk(chunk.file, bytes(records), index, problems)

    def topic_spans(self, *, message_indexes: bool = True) -> dict[str, Span]:
        """The back-end's spans (compression moves no message)."""
        return self.inner.topic_spans(message_indexes=message_indexes)

    def index_log_times(self, topic: str) -> np.ndarray | None:
        """The back-end's (compression moves no message)."""
        return self.inner.index_log_times(topic)


def sniff_message_compression(storage: StorageFile) -> bool:
    """True when the last message of a topic of ``storage`` is a zstd frame (a bag written in
    rosbag2's message mode whose ``metadata.yaml`` is gone)."""
    last = storage.last_messages(set(storage.topics), 1 << 63)
    return any(is_zstd(bytes(m.data[:4])) for m in last.values())
