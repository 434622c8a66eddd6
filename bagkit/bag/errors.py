"""Errors of the bag layer: unusable input (exit code 2) and write failures."""

from __future__ import annotations

from bagkit.errors import BagkitError
from bagkit.words import counted


class BagError(BagkitError):
    """A problem with a bag: reading it, writing it or finding what goes in it."""


class BagNotFoundError(BagError):
    """The path given as a bag does not exist."""


class NotABagError(BagError):
    """The path exists but is neither a rosbag2 bag directory nor a storage file we can read."""


class CorruptBagError(BagError):
    """A storage file is damaged beyond salvage (bad magic, unreadable header)."""


class EmptyBagError(BagError):
    """A bag that holds no topics and no messages."""


class UnsupportedStorageError(BagError):
    """A bag in a storage format bagkit does not read (only ``mcap`` and ``sqlite3``)."""


class UnknownMessageTypeError(BagError):
    """A message type whose ``.msg`` definition is not installed."""


class BagExistsError(BagError):
    """The output bag already exists: bagkit never overwrites a bag."""


class BagWriteError(BagError):
    """Writing failed (disk full, unwritable directory); what was flushed before stays readable.

    Attributes:
        reason: what failed, without the count of lost messages.
        lost_by_topic: messages accepted by ``write()`` that are not in the bag, per topic.
    """

    exit_code = 1

    def __init__(self, message: str, *, lost_by_topic: dict[str, int] | None = None) -> None:
        super().__init__(message)
        self.reason = message
        self.lost_by_topic = dict(lost_by_topic or {})

    def __str__(self) -> str:
        """The reason, with the count of ``lost_by_topic`` (one count, always the current one)."""
        lost = self.messages_lost
        return f"{self.reason} ({counted(lost, 'message')} lost)" if lost else self.reason

    @property
    def messages_lost(self) -> int:
        """Messages accepted by ``write()`` that are not in the bag."""
        return sum(self.lost_by_topic.values())


class ChunkError(CorruptBagError):
    """One MCAP chunk cannot be used (too large, does not decompress, bad CRC); the rest can."""
