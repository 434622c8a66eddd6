"""An open MCAP file whose size bounds every read: no length from the file is trusted."""

from __future__ import annotations

from typing import BinaryIO

from bagkit.bag.errors import CorruptBagError


class Source:
    """A seekable binary file, its size and the name it has in messages.

    Args:
        f: the file, opened for binary reading.
        name: how the file is named in problems and errors.
    """

    __slots__ = ("f", "name", "size")

    def __init__(self, f: BinaryIO, name: str) -> None:
        self.f = f
        self.name = name
        f.seek(0, 2)
        self.size = f.tell()

    def holds(self, offset: int, length: int) -> bool:
        """True when ``length`` bytes from ``offset`` are inside the file."""
        return offset >= 0 and 0 <= length <= self.size - offset

    def read(self, offset: int, length: int) -> bytes:
        """Exactly ``length`` bytes from ``offset``.

        Raises:
            CorruptBagError: the span does not fit in the file.
        """
        if not self.holds(offset, length):
            raise CorruptBagError(
                f"{length} bytes at byte {offset} are past the end of the file ({self.size} bytes)"
            )
        self.f.seek(offset)
        data = self.f.read(length)
        if len(data) != length:  # the file shrank while being read
            raise CorruptBagError(f"file ends inside the {length} bytes at byte {offset}")
        return data
