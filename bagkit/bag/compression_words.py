"""How a bag is compressed, in words: one source for ``bagkit info``'s rows and the one-line
:attr:`~bagkit.bag.reader.BagReader.compression_label` (the fleet catalogue's)."""

from __future__ import annotations

from dataclasses import dataclass


@dataclass(frozen=True, slots=True)
class CompressionWords:
    """rosbag2's compression and the storage's own chunks', in words.

    Attributes:
        rosbag2: rosbag2's zstd (``zstd, file mode``, ``zstd, message mode``), or ``""``.
        chunks: the chunks' compressions (``zstd``, ``lz4,zstd``, ``none``), or ``""``
            (sqlite3).
    """

    rosbag2: str
    chunks: str

    @classmethod
    def of(cls, mode: str, chunks: str) -> CompressionWords:
        """The words for rosbag2's compression ``mode`` (``file``, ``message`` or ``""``) and
        the chunks' compressions ``chunks``."""
        return cls(f"zstd, {mode} mode" if mode else "", chunks)

    @property
    def label(self) -> str:
        """One line: rosbag2's first, with the chunks' apart (``zstd, file mode; chunks
        none``); else the chunks' (``zstd``, ``none``), or ``""``."""
        if not self.rosbag2:
            return self.chunks
        return f"{self.rosbag2}; chunks {self.chunks}" if self.chunks else self.rosbag2
