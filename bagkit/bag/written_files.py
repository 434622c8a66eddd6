"""The storage files of a bag being written: the open one, the finished ones with their
messages' counts, numbering, and the oldest deleted (circular recording), for :class:`BagWriter`.
"""

from __future__ import annotations

from pathlib import Path

from mcap.well_known import Profile

from bagkit.bag.bag_files import bag_metadata, file_information, finish_storage_file
from bagkit.bag.bag_topics import BagTopics
from bagkit.bag.errors import BagWriteError
from bagkit.bag.mcapio.file_writer import McapFileWriter
from bagkit.bag.mcapio.records import Header
from bagkit.bag.metadata import BagMetadata, FileInformation
from bagkit.version import __version__

LIBRARY = f"bagkit {__version__}"


class WrittenFiles:
    """The files of the bag ``path`` (``PATH/PATH_0.mcap`` ...), over the writer's ``topics``.

    Attributes:
        open: the file being written, None before the first and after a failure.
        finished: the finished files that exist (a circular bag deletes the oldest).
        open_counts: messages per channel written to the open file.
    """

    def __init__(self, path: Path, topics: BagTopics) -> None:
        self.path = path
        self._topics = topics
        self.open: McapFileWriter | None = None
        self.finished: list[FileInformation] = []
        self.open_counts: dict[int, int] = {}
        self._finished_counts: list[dict[int, int]] = []  # messages per channel of each
        self._opened = 0

    def paths(self) -> list[Path]:
        """The files written so far, the open one included."""
        paths = [self.path / f.path for f in self.finished]
        if self.open is not None:
            paths.append(self.open.path)
        return paths

    def current(self, lost: dict[str, int]) -> McapFileWriter:
        """The open file.

        Raises:
            BagWriteError: none is open after an earlier error (``lost``: what that loses).
        """
        if self.open is None:
            raise BagWriteError(
                f"{self.path}: no file open after an earlier error", lost_by_topic=lost
            )
        return self.open

    def open_next(self) -> None:
        """Create the next file, with every schema and channel so far."""
        # Numbered on: a circular bag's deleted files leave gaps at the start.
        path = self.path / f"{self.path.name}_{self._opened}.mcap"
        self._opened += 1
        self.open = McapFileWriter.create(
            path,
            Header(profile=Profile.ROS2, library=LIBRARY),
            self._topics.schemas.values(),
            self._topics.channels.values(),
        )

    def count(self, counts: dict[int, int]) -> None:
        """Count messages per channel written to the open file (and to the bag)."""
        for channel_id, count in counts.items():
            self._topics.counts[channel_id] += count
            self.open_counts[channel_id] = self.open_counts.get(channel_id, 0) + count

    def delete_oldest(self) -> None:
        """Circular recording: the oldest finished file goes, with its messages' counts."""
        oldest = self.finished.pop(0)
        for channel_id, count in self._finished_counts.pop(0).items():
            self._topics.counts[channel_id] -= count
        (self.path / oldest.path).unlink(missing_ok=True)

    def metadata(self, custom_data: dict[str, str]) -> BagMetadata:
        """``metadata.yaml`` of the bag as written so far, the open file included."""
        files = list(self.finished)
        if self.open is not None:
            files.append(file_information(self.open))
        return bag_metadata(files, self._topics.with_counts(), custom_data)

    def finish(self, custom_data: dict[str, str], *, last: bool = True) -> None:
        """Write the open file's rosbag2 metadata record, summary and footer, and close it.

        The last file's record describes the bag, as ``metadata.yaml``; a file before a split
        describes itself alone: a record listing every file before it would grow the bag by
        the square of its file count.
        """
        storage = self.open
        if storage is None:
            return
        metadata = (
            self.metadata(custom_data)
            if last
            else bag_metadata(
                [file_information(storage)],
                self._topics.with_counts(self.open_counts),
                custom_data,
            )
        )
        try:
            finish_storage_file(
                storage,
                metadata,
                list(self._topics.schemas.values()),
                list(self._topics.channels.values()),
            )
        finally:
            self.finished.append(file_information(storage))
            self._finished_counts.append(self.open_counts)
            self.open_counts = {}
            self.open = None
            storage.close()
