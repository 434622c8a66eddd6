"""The records of an MCAP file's data section, walked one header at a time (salvage, doctor)."""

from __future__ import annotations

from collections.abc import Iterator

from bagkit.bag.mcapio.records import MAGIC, RECORD_HEADER
from bagkit.bag.mcapio.source import Source


class DataSection:
    """Iterate ``(offset, opcode, length)`` of the records after the magic, each header and
    length checked against the file's size before it is yielded.

    The closing record (Data End or Footer) is yielded like any other: the caller stops there.
    After the iteration, ``cut_at`` is where the file is cut (None: it is not), at a header that
    does not fit or at a record (``cut_opcode``) whose declared length (``cut_length``) runs past
    the end.
    """

    def __init__(self, source: Source) -> None:
        self.source = source
        self.cut_at: int | None = None
        self.cut_length: int | None = None
        self.cut_opcode: int | None = None

    def __iter__(self) -> Iterator[tuple[int, int, int]]:
        source = self.source
        pos, size = len(MAGIC), source.size
        while pos < size:
            if pos + RECORD_HEADER.size > size:
                self.cut_at, self.cut_opcode = pos, source.read(pos, 1)[0]
                return
            opcode, length = RECORD_HEADER.unpack(source.read(pos, RECORD_HEADER.size))
            if length > size - pos - RECORD_HEADER.size:
                self.cut_at, self.cut_length, self.cut_opcode = pos, length, opcode
                return
            yield pos, opcode, length
            pos += RECORD_HEADER.size + length
