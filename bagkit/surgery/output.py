"""The bag a surgery writes: a temp directory renamed at the end, split files, raw chunk copies.

An output named ``*.mcap`` is one MCAP file, not a bag directory (as ``mcap convert`` and
pymcap-cli write it): its rosbag2 record carries the metadata, no ``metadata.yaml`` is written.

Nothing appears under the output name before :meth:`OutputBag.commit`: files are written to a
hidden sibling directory that is renamed into place, so an error never leaves a half-written
bag, and an existing output is replaced only with ``force``.

A chunk built here is compressed on a worker thread while the next one is built, unless the
output is split by size or duration (:mod:`~bagkit.surgery.chunk_compression`).
"""

from __future__ import annotations

import os
import shutil
from pathlib import Path
from typing import TYPE_CHECKING, Protocol

from mcap.well_known import Profile

from bagkit.bag.bag_files import bag_metadata, compressor, file_information, finish_storage_file
from bagkit.bag.definitions import UNKNOWN_ENCODING, definition_encoding
from bagkit.bag.mcapio.chunk_builder import ChunkBuilder, ClosedChunk
from bagkit.bag.mcapio.file_writer import McapFileWriter
from bagkit.bag.mcapio.records import (
    MESSAGE_PREFIX,
    MESSAGE_RECORD_HEADER,
    Channel,
    Header,
    Opcode,
    Schema,
    message_record_dtype,
)
from bagkit.bag.messages import BagMessage, TopicInfo
from bagkit.bag.metadata import BagMetadata, FileInformation, write_metadata
from bagkit.bag.sizes import split_size_problem
from bagkit.bag.writer import DEFAULT_CHUNK_SIZE
from bagkit.bag.written_files import LIBRARY
from bagkit.selection.times import seconds_to_ns
from bagkit.surgery.chunk_compression import ChunkCompression
from bagkit.surgery.errors import SurgeryError
from bagkit.surgery.options import OutputOptions
from bagkit.surgery.output_paths import check_replaceable, single_file

if TYPE_CHECKING:
    import numpy as np

# The smallest chunk a split output gets: a split size holds four at least.
_MIN_CHUNK_SIZE = 4096


class MessageOutput(Protocol):
    """What a message-by-message copy needs of the bag it writes: :class:`OutputBag` or
    :class:`~bagkit.surgery.sqlite3_output.Sqlite3OutputBag`."""

    custom_data: dict[str, str]
    counts: dict[int, int]

    def add_topic(self, topic: TopicInfo, definition: str | None, preferred_id: int) -> int:
        """Add a topic (once per name) with its definition (None: not known); return its id
        in the output."""

    def topic_id(self, topic: str) -> int:
        """The id of a topic added."""

    def write_message(self, channel_id: int, message: BagMessage, log_time: int) -> None:
        """Append one message under ``channel_id`` at ``log_time``."""

    def write_messages(self, channel_ids: list[int], messages: list[BagMessage]) -> None:
        """Append messages at their log times, each under its id of ``channel_ids``."""

    def commit(self) -> list[Path]:
        """Finish, move the bag into place; return its files."""

    def abort(self) -> None:
        """Remove what was written."""


class OutputBag:
    """A rosbag2 MCAP bag written message by message or chunk by chunk.

    Args:
        path: the bag directory to create.
        compression: ``zstd``, ``lz4`` or ``none`` for the chunks built here.
        max_bag_size: split when a file reaches this many bytes (0: never).
        max_bag_duration_s: split when a file spans this much log time (0: never).
        force: replace ``path`` if it exists.
        single_file: ``path`` is the one MCAP file to write, without metadata.yaml (it is
            not split).

    Raises:
        SurgeryError: ``path`` exists without ``force``, or its parent does not.
    """

    def __init__(
        self,
        path: Path,
        *,
        compression: str = "zstd",
        max_bag_size: int = 0,
        max_bag_duration_s: float = 0,
        force: bool = False,
        single_file: bool = False,
    ) -> None:
        if not path.name or path.name == "..":
            raise SurgeryError(f"{str(path)!r} names no bag directory to write")
        if path.exists() or path.is_symlink():
            if not force:
                raise SurgeryError(f"{path} already exists", "output.force")
            check_replaceable(path)
        if not path.parent.is_dir():
            raise SurgeryError(f"{path.parent}: no such directory")
        self.path = path
        self._single_file = single_file
        self.compression, compress = compressor(compression)
        too_small = split_size_problem(max_bag_size, 4 * _MIN_CHUNK_SIZE)
        if too_small is not None:
            raise SurgeryError(too_small)
        self._max_size = max_bag_size
        self._max_duration = seconds_to_ns(max_bag_duration_s, max_bag_duration_s, SurgeryError)
        # Files end within one chunk of max_bag_size: small limits get smaller chunks.
        self._chunk_size = (
            min(DEFAULT_CHUNK_SIZE, max(max_bag_size // 4, _MIN_CHUNK_SIZE))
            if max_bag_size
            else DEFAULT_CHUNK_SIZE
        )
        self._temp = path.parent / f".{path.name}.partial-{os.getpid()}"
        shutil.rmtree(self._temp, ignore_errors=True)
        self._temp.mkdir()
        self.schemas: dict[tuple[str, str | None], Schema] = {}
        self.channels: dict[str, Channel] = {}
        self.topics: dict[str, TopicInfo] = {}
        self.counts: dict[int, int] = {}
        self._counts_before: dict[int, int] = {}  # self.counts when the open file began
        self.chunks_copied = 0
        self.custom_data: dict[str, str] = {}  # metadata.yaml's, as the caller merged them
        self._files: list[FileInformation] = []
        self._file: McapFileWriter | None = None
        self._chunk = ChunkBuilder()
        self._closed = ChunkCompression(
            self.compression,
            compress,
            self._write_chunk,
            threaded=not (max_bag_size or max_bag_duration_s),
        )

    @classmethod
    def create(cls, path: Path, options: OutputOptions) -> OutputBag:
        """The MCAP output ``options`` describe: a bag directory, or one file
        (:func:`~bagkit.surgery.output_paths.single_file`).

        Raises:
            SurgeryError: see :func:`~bagkit.surgery.output_paths.single_file` and the class.
        """
        return cls(
            path,
            compression=options.compression,
            max_bag_size=options.max_bag_size,
            max_bag_duration_s=options.max_bag_duration_s,
            force=options.force,
            single_file=single_file(path, options),
        )

    def add_topic(self, topic: TopicInfo, definition: str | None, preferred_id: int) -> int:
        """Add a topic (once per name); return its channel id (``preferred_id`` when free). A
        definition not known (None) is rosbag2's schema of encoding ``unknown``, without text."""
        channel = self.channels.get(topic.name)
        if channel is not None:
            return channel.id
        # One schema per text: two topics of one type name with different texts keep theirs.
        schema = self.schemas.get((topic.type, definition))
        if schema is None:
            schema = Schema(
                id=len(self.schemas) + 1,
                name=topic.type,
                encoding=UNKNOWN_ENCODING
                if definition is None
                else definition_encoding(definition),
                data=b"" if definition is None else definition.encode("utf-8"),
            )
            self.schemas[topic.type, definition] = schema
        used = {c.id for c in self.channels.values()}
        channel_id = preferred_id if 0 < preferred_id < 1 << 16 and preferred_id not in used else 0
        if not channel_id:
            channel_id = max(used, default=0) + 1
        metadata = {"offered_qos_profiles": topic.offered_qos_profiles}
        if topic.type_description_hash:
            metadata["topic_type_hash"] = topic.type_description_hash
        self.channels[topic.name] = Channel(
            id=channel_id,
            schema_id=schema.id,
            topic=topic.name,
            message_encoding=topic.serialization_format,
            metadata=metadata,
        )
        self.topics[topic.name] = topic
        self.counts[channel_id] = 0
        return channel_id

    def topic_id(self, topic: str) -> int:
        """The channel id of a topic added."""
        return self.channels[topic].id

    def write_records(
        self,
        data: bytes | bytearray | memoryview,
        offsets: np.ndarray,
        lengths: np.ndarray,
        channels: np.ndarray,
        times: np.ndarray,
    ) -> None:
        """Append whole Message records (channel ids already this bag's), chunk by chunk."""
        import numpy as np  # not imported where every chunk is copied as stored

        view = memoryview(data)  # slices without copies: the chunk copies what it takes
        ends = offsets + lengths
        i, n = 0, len(offsets)
        while i < n:
            self._split_if_due(int(times[i]), int(lengths[i]))
            chunk = self._chunk
            room = self._chunk_size - chunk.size
            j = max(i + 1, int(np.searchsorted(ends, offsets[i] + room, side="right")))
            if self._max_duration:
                j = self._within_duration(times, i, j)
            chunk.add_records(
                view[offsets[i] : ends[j - 1]],
                channels[i:j],
                times[i:j],
                offsets[i:j] - offsets[i],
            )
            if chunk.size >= self._chunk_size:
                self._close_chunk()
            i = j

    def write_message(self, channel_id: int, message: BagMessage, log_time: int) -> None:
        """Append one message under ``channel_id`` (this bag's) at ``log_time``, its publish
        time, sequence and payload as stored: the latched state written before a window."""
        self._split_if_due(log_time, len(message.data))
        self._chunk.add(channel_id, message.data, log_time, message.publish_time, message.sequence)
        if self._chunk.size >= self._chunk_size:
            self._close_chunk()

    def write_messages(self, channel_ids: list[int], messages: list[BagMessage]) -> None:
        """Append messages at their log times, each under its id of ``channel_ids``, as Message
        records packed at once (the message-by-message copy's bulk write)."""
        if not messages:
            return
        import numpy as np  # not imported where every chunk is copied as stored

        count = len(messages)
        lengths = np.fromiter((len(m.data) for m in messages), np.int64, count)
        times = np.fromiter((m.log_time for m in messages), np.uint64, count)
        channels = np.array(channel_ids, np.uint16)
        headers = np.empty(count, message_record_dtype())
        headers["opcode"] = Opcode.MESSAGE
        headers["length"] = lengths + MESSAGE_PREFIX.size
        headers["channel_id"] = channels
        headers["sequence"] = np.fromiter((m.sequence for m in messages), np.uint64, count)
        headers["log_time"] = times
        headers["publish_time"] = np.fromiter((m.publish_time for m in messages), np.uint64, count)
        packed = headers.tobytes()
        size = MESSAGE_RECORD_HEADER.size
        pieces = [b""] * (2 * count)
        pieces[::2] = [packed[i : i + size] for i in range(0, count * size, size)]
        pieces[1::2] = [m.data for m in messages]
        record_lengths = lengths + size
        offsets = np.zeros(count, np.int64)
        np.cumsum(record_lengths[:-1], out=offsets[1:])
        self.write_records(b"".join(pieces), offsets, record_lengths, channels, times)

    def takes_whole(self, start_ns: int, end_ns: int, length: int) -> bool:
        """Whether a chunk of these log times and record length fits one file of the split
        (a chunk copied as stored cannot be split): spans less than the duration, holds at most
        a quarter of the size, as the chunks built here do."""
        if self._max_duration and end_ns - start_ns >= self._max_duration:
            return False
        return not self._max_size or length <= self._max_size // 4

    def copy_chunk(self, chunk: ClosedChunk) -> None:
        """Append a chunk as it is stored (its channel ids must be this bag's)."""
        self._close_chunk()
        self._closed.flush()
        self._split_if_due(chunk.message_end_time, chunk.length)
        file = self._current_file()
        file.write_chunk(chunk, lost={})
        for channel_id, count in chunk.message_counts.items():
            self.counts[channel_id] += count
        self.chunks_copied += 1

    def commit(self) -> list[Path]:
        """Finish the last file and metadata.yaml, move the bag into place; return its files."""
        self._close_chunk()
        self._closed.flush()
        self._closed.stop()
        if self._file is None and not self._files:
            self._current_file()
        self._finish_file()
        if not self._single_file:
            write_metadata(self._temp, self._metadata())
        if self.path.exists() or self.path.is_symlink():
            if self.path.is_dir() and not self.path.is_symlink():
                shutil.rmtree(self.path)
            else:
                self.path.unlink()
        if self._single_file:
            (self._temp / self.path.name).rename(self.path)
            self._temp.rmdir()
            return [self.path]
        self._temp.rename(self.path)
        return [self.path / f.path for f in self._files]

    def abort(self) -> None:
        """Remove what was written (the output name is left untouched)."""
        self._closed.stop(discard=True)
        if self._file is not None:
            self._file.close()
            self._file = None
        shutil.rmtree(self._temp, ignore_errors=True)

    # -- internals --------------------------------------------------------------------------

    def _current_file(self) -> McapFileWriter:
        if self._file is None:
            name = (
                self.path.name if self._single_file else f"{self.path.name}_{len(self._files)}.mcap"
            )
            self._file = McapFileWriter.create(
                self._temp / name,
                Header(profile=Profile.ROS2, library=LIBRARY),
                self.schemas.values(),
                self.channels.values(),
            )
        return self._file

    def _within_duration(self, times: np.ndarray, i: int, j: int) -> int:
        """Where ``times[i:j]`` leaves the open file's duration (``j`` if it does not): the split
        comes before that message, not at the end of a chunk that holds the whole bag."""
        import numpy as np

        file = self._file
        starts = [int(times[i]), self._chunk.start]
        if file is not None and file.start_time is not None and file.message_count:
            starts.append(file.start_time)
        late = np.flatnonzero(times[i + 1 : j] >= min(starts) + self._max_duration)
        return i + 1 + int(late[0]) if len(late) else j

    def _split_if_due(self, log_time: int, size: int) -> None:
        if not (self._max_size or self._max_duration):
            return
        # The file opens when its first chunk closes: until then the open chunk is all of it.
        file, chunk = self._file, self._chunk
        if (file.message_count if file else 0) + chunk.count == 0:
            return
        offset = file.offset if file else 0
        due = bool(self._max_size) and offset + chunk.size + size >= self._max_size
        if self._max_duration:
            start = min(file.start_time or chunk.start, chunk.start) if file else chunk.start
            due = due or log_time - start >= self._max_duration
        if due:
            self._close_chunk()
            self._finish_file(last=False)

    def _close_chunk(self) -> None:
        chunk = self._chunk
        if not chunk.count:
            return
        self._chunk = ChunkBuilder()
        for channel_id, count in chunk.message_counts().items():
            self.counts[channel_id] += count
        self._closed.add(chunk)

    def _write_chunk(self, chunk: ClosedChunk) -> None:
        self._current_file().write_chunk(chunk, lost={})

    def _finish_file(self, *, last: bool = True) -> None:
        """Close the open file; its rosbag2 record describes the bag when it is the last, else
        the file alone (as :class:`~bagkit.bag.BagWriter`: no record listing every file)."""
        file = self._file
        if file is None:
            return
        self._files.append(file_information(file))
        if last:
            metadata = self._metadata()
        else:
            own = {c: n - self._counts_before.get(c, 0) for c, n in self.counts.items()}
            metadata = self._metadata([self._files[-1]], own)
        self._counts_before = dict(self.counts)
        finish_storage_file(
            file, metadata, list(self.schemas.values()), list(self.channels.values())
        )
        file.close()
        self._file = None

    def _metadata(
        self, files: list[FileInformation] | None = None, counts: dict[int, int] | None = None
    ) -> BagMetadata:
        counts = self.counts if counts is None else counts
        topics = [(t, counts[self.channels[n].id]) for n, t in self.topics.items()]
        return bag_metadata(self._files if files is None else files, topics, self.custom_data)
