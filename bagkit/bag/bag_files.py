"""What every writer of a rosbag2 MCAP bag does alike: compress chunks, describe and finish files.

:class:`~bagkit.bag.writer.BagWriter` (messages) and bag surgery's output (records and chunks
copied as stored) write the same bags: the same compressors, the same ``FileInformation`` per
file, the same ``metadata.yaml`` totals, and the rosbag2 metadata record before each summary.
"""

from __future__ import annotations

from collections.abc import Sequence

import lz4.frame
import zstandard

from bagkit.bag.errors import BagError
from bagkit.bag.mcapio.chunk_builder import Buffer, Compress
from bagkit.bag.mcapio.file_writer import McapFileWriter
from bagkit.bag.mcapio.records import Channel, Metadata, Schema
from bagkit.bag.messages import TopicInfo
from bagkit.bag.metadata import BagMetadata, FileInformation

COMPRESSIONS = ("zstd", "lz4", "none")


def compressor(compression: str) -> tuple[str, Compress]:
    """The chunk compression's name in MCAP (``""`` for none) and its function.

    The function takes a chunk's records in pieces and returns the compressed data in pieces:
    one zstd or LZ4 frame that declares its size, or for ``none`` the pieces themselves (no
    copy).

    Raises:
        BagError: not one of :data:`COMPRESSIONS`.
    """
    if compression == "zstd":
        compress_one = zstandard.ZstdCompressor(level=1).compress
    elif compression == "lz4":
        compress_one = lz4.frame.compress
    elif compression == "none":
        return "", _uncompressed
    else:
        raise BagError(
            f"unknown compression {compression!r} (choose from {', '.join(COMPRESSIONS)})"
        )

    def compress(pieces: Sequence[Buffer]) -> list[bytes]:
        # One copy into a buffer of the right size and a one-shot compression: a streaming
        # compressor copies its input into its own window anyway, and was no faster.
        return [compress_one(pieces[0] if len(pieces) == 1 else b"".join(pieces))]

    return compression, compress


def _uncompressed(pieces: Sequence[Buffer]) -> Sequence[Buffer]:
    return pieces


def file_information(storage: McapFileWriter) -> FileInformation:
    """The ``metadata.yaml`` entry of one storage file as written so far."""
    start = storage.start_time or 0
    return FileInformation(
        path=storage.path.name,
        starting_time=start,
        duration=storage.end_time - start if storage.message_count else 0,
        message_count=storage.message_count,
    )


def bag_metadata(
    files: Sequence[FileInformation],
    topics: list[tuple[TopicInfo, int]],
    custom_data: dict[str, str] | None = None,
) -> BagMetadata:
    """A bag's metadata from its files and its topics with their message counts."""
    with_messages = [f for f in files if f.message_count]
    start = min((f.starting_time for f in with_messages), default=0)
    end = max((f.starting_time + f.duration for f in with_messages), default=0)
    return BagMetadata(
        storage_identifier="mcap",
        relative_file_paths=[f.path for f in files],
        starting_time=start,
        duration=end - start,
        message_count=sum(f.message_count for f in files),
        topics=topics,
        files=list(files),
        custom_data=dict(custom_data or {}),
    )


def finish_storage_file(
    storage: McapFileWriter,
    metadata: BagMetadata,
    schemas: Sequence[Schema],
    channels: Sequence[Channel],
) -> None:
    """Write rosbag2's metadata record (what ``ros2 bag`` reads back), the summary and the
    footer; the caller closes the file."""
    serialized = metadata.dump(root=False)
    storage.add_metadata(Metadata(name="rosbag2", metadata={"serialized_metadata": serialized}))
    storage.finish(list(schemas), list(channels))
