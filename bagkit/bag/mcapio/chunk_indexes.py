"""The Chunk Index records of a file, held column by column.

A reader keeps a file's chunk indexes for as long as it reads the file. As one ``ChunkIndex``
object each (with its dict of Message Index offsets) they cost about 680 bytes a chunk, 0.7 MiB
per GB of bag (benchmarks/README.md, "Memory over 0.3 - 10 GB"); here a chunk costs 64 bytes
plus 10 per channel in it. Columns are ``array.array`` (standard library: ``bagkit info`` reads
summaries without numpy, see benchmarks/README.md, start-up); ``np.frombuffer`` views them
without a copy where a computation wants numpy. A row is made a ``ChunkIndex`` when it is used.
"""

from __future__ import annotations

import struct
from array import array
from collections.abc import Iterable, Iterator, Sequence
from typing import overload

from bagkit.bag.errors import CorruptBagError
from bagkit.bag.mcapio.records import ChunkIndex

# A Chunk Index record's content: start, end, chunk offset, chunk length, then the byte length
# of its map of Message Index offsets (Map<uint16, uint64>).
_PREFIX = struct.Struct("<QQQQI")
_MAP_ENTRY = struct.Struct("<HQ")
# After the map: message index length, compression name length (the name follows).
_AFTER_MAP = struct.Struct("<QI")
# After the name: compressed size, uncompressed size.
_SIZES = struct.Struct("<QQ")


class ChunkIndexes(Sequence[ChunkIndex]):
    """A file's chunk indexes as columns; ``table[row]`` is one as a ``ChunkIndex``.

    Attributes:
        start_times, end_times: ``message_start_time``, ``message_end_time`` per row.
        chunk_offsets, chunk_lengths: where each Chunk record is (``chunk_start_offset``,
            ``chunk_length``).
        index_lengths: ``message_index_length`` (bytes of Message Index records after it).
        compressed_sizes, uncompressed_sizes: the chunk's sizes.
        compression_ids: per row, the position of its compression name in ``compressions``.
        channel_starts: row ``i``'s Message Index entries are
            ``channel_ids[channel_starts[i]:channel_starts[i + 1]]`` with the offsets
            ``index_offsets`` at the same positions (one entry per channel, file order).
    """

    __slots__ = (
        "_compression_ids_by_name",
        "channel_ids",
        "channel_starts",
        "chunk_lengths",
        "chunk_offsets",
        "compressed_sizes",
        "compression_ids",
        "compressions",
        "end_times",
        "index_lengths",
        "index_offsets",
        "start_times",
        "uncompressed_sizes",
    )

    def __init__(self) -> None:
        self.start_times = array("Q")
        self.end_times = array("Q")
        self.chunk_offsets = array("Q")
        self.chunk_lengths = array("Q")
        self.index_lengths = array("Q")
        self.compressed_sizes = array("Q")
        self.uncompressed_sizes = array("Q")
        self.compression_ids = array("I")
        self.compressions: list[str] = []
        self._compression_ids_by_name: dict[str, int] = {}
        self.channel_starts = array("Q", [0])
        self.channel_ids = array("H")
        self.index_offsets = array("Q")

    def __len__(self) -> int:
        return len(self.start_times)

    @overload
    def __getitem__(self, row: int) -> ChunkIndex: ...
    @overload
    def __getitem__(self, row: slice) -> list[ChunkIndex]: ...
    def __getitem__(self, row: int | slice) -> ChunkIndex | list[ChunkIndex]:
        if isinstance(row, slice):
            return [self[i] for i in range(*row.indices(len(self)))]
        if row < 0:
            row += len(self)
        if not 0 <= row < len(self):
            raise IndexError("chunk index row out of range")
        first, last = self.channel_starts[row], self.channel_starts[row + 1]
        return ChunkIndex(
            message_start_time=self.start_times[row],
            message_end_time=self.end_times[row],
            chunk_start_offset=self.chunk_offsets[row],
            chunk_length=self.chunk_lengths[row],
            message_index_offsets=dict(
                zip(self.channel_ids[first:last], self.index_offsets[first:last], strict=True)
            ),
            message_index_length=self.index_lengths[row],
            compression=self.compressions[self.compression_ids[row]],
            compressed_size=self.compressed_sizes[row],
            uncompressed_size=self.uncompressed_sizes[row],
        )

    def __iter__(self) -> Iterator[ChunkIndex]:
        for row in range(len(self)):
            yield self[row]

    def channels(self, row: int) -> array[int]:
        """The channel ids with Message Index records after the chunk of ``row``."""
        return self.channel_ids[self.channel_starts[row] : self.channel_starts[row + 1]]

    def indexed(self, row: int) -> bool:
        """Whether the chunk of ``row`` has Message Index records."""
        return self.channel_starts[row + 1] > self.channel_starts[row]

    def empty(self, row: int) -> bool:
        """A chunk without messages (rosbags' writer closes an empty bag with one): its times
        are the writer's initial values, its start after its end."""
        return self.start_times[row] > self.end_times[row] and not self.indexed(row)

    def append(self, chunk: ChunkIndex) -> None:
        """Add a row (a chunk index found by a scan, or written)."""
        self._add(
            chunk.message_start_time,
            chunk.message_end_time,
            chunk.chunk_start_offset,
            chunk.chunk_length,
            chunk.message_index_offsets,
            chunk.message_index_length,
            chunk.compression,
            chunk.compressed_size,
            chunk.uncompressed_size,
        )

    def append_record(self, content: bytes | memoryview) -> None:
        """Add the row of a Chunk Index record's content, every length checked against it.

        Raises:
            CorruptBagError: a field runs past the end of the record, or the map is not whole
                entries, or the compression name is not UTF-8.
        """
        size = len(content)
        if size < _PREFIX.size:
            raise _overrun(_PREFIX.size, 0, size)
        start, end, offset, length, map_size = _PREFIX.unpack_from(content)
        at = _PREFIX.size
        if map_size > size - at:
            raise _overrun(map_size, at, size)
        if map_size % _MAP_ENTRY.size:
            raise CorruptBagError(f"a map of {map_size} bytes is not whole entries")
        view = memoryview(content)
        # A dict, as the map is read everywhere: a channel listed twice keeps its last offset.
        offsets = dict(_MAP_ENTRY.iter_unpack(view[at : at + map_size]))
        at += map_size
        if size - at < _AFTER_MAP.size:
            raise _overrun(_AFTER_MAP.size, at, size)
        index_length, name_size = _AFTER_MAP.unpack_from(content, at)
        at += _AFTER_MAP.size
        if name_size > size - at:
            raise _overrun(name_size, at, size)
        try:
            compression = str(view[at : at + name_size], "utf-8")
        except UnicodeDecodeError as exc:
            raise CorruptBagError(f"a string is not UTF-8 ({exc.reason})") from None
        at += name_size
        if size - at < _SIZES.size:
            raise _overrun(_SIZES.size, at, size)
        compressed, uncompressed = _SIZES.unpack_from(content, at)
        self._add(
            start, end, offset, length, offsets, index_length, compression, compressed, uncompressed
        )

    def _add(  # noqa: PLR0917 (a record's fields, in its order)
        self,
        start: int,
        end: int,
        offset: int,
        length: int,
        index_offsets: dict[int, int],
        index_length: int,
        compression: str,
        compressed_size: int,
        uncompressed_size: int,
    ) -> None:
        compression_id = self._compression_ids_by_name.get(compression)
        if compression_id is None:
            compression_id = self._compression_ids_by_name[compression] = len(self.compressions)
            self.compressions.append(compression)
        self.start_times.append(start)
        self.end_times.append(end)
        self.chunk_offsets.append(offset)
        self.chunk_lengths.append(length)
        self.index_lengths.append(index_length)
        self.compressed_sizes.append(compressed_size)
        self.uncompressed_sizes.append(uncompressed_size)
        self.compression_ids.append(compression_id)
        self.channel_ids.extend(index_offsets.keys())
        self.index_offsets.extend(index_offsets.values())
        self.channel_starts.append(len(self.channel_ids))

    def take(self, rows: Iterable[int]) -> ChunkIndexes:
        """A table of ``rows`` in that order (to sort, or to leave rows out)."""
        taken = ChunkIndexes()
        taken.compressions = list(self.compressions)
        taken._compression_ids_by_name = dict(self._compression_ids_by_name)
        starts = self.channel_starts
        for row in rows:
            taken.start_times.append(self.start_times[row])
            taken.end_times.append(self.end_times[row])
            taken.chunk_offsets.append(self.chunk_offsets[row])
            taken.chunk_lengths.append(self.chunk_lengths[row])
            taken.index_lengths.append(self.index_lengths[row])
            taken.compressed_sizes.append(self.compressed_sizes[row])
            taken.uncompressed_sizes.append(self.uncompressed_sizes[row])
            taken.compression_ids.append(self.compression_ids[row])
            first, last = starts[row], starts[row + 1]
            taken.channel_ids.extend(self.channel_ids[first:last])
            taken.index_offsets.extend(self.index_offsets[first:last])
            taken.channel_starts.append(len(taken.channel_ids))
        return taken

    def rows_by(self, column: array[int], then: array[int] | None = None) -> array[int]:
        """The rows sorted by ``column``, then by ``then`` on ties (stable), as an array.

        The key of a row is one integer (``then`` below ``column``'s bits), not a tuple: a
        summary may hold millions of chunk indexes.
        """
        rows = range(len(self))
        if then is None:
            return array("Q", sorted(rows, key=column.__getitem__))
        return array("Q", sorted(rows, key=lambda row: column[row] << 64 | then[row]))


def _overrun(size: int, at: int, record_size: int) -> CorruptBagError:
    return CorruptBagError(
        f"a field of {size} bytes at byte {at} runs past the end of its {record_size}-byte record"
    )
