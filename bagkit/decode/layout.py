"""CDR byte layouts of message types, as numpy structured dtypes for bulk decoding.

A ROS 2 CDR payload is a 4-byte encapsulation header followed by the fields in definition
order, each primitive aligned to its own size (at most 8) relative to the end of that header.
A type whose only variable parts are strings and sequences of primitives has a fixed layout once
the length prefix of each of those parts is known: :meth:`CdrLayout.resolve` takes the lengths
read so far and either asks for the next prefix or returns the dtype of the whole message.
"""

from __future__ import annotations

import struct
from collections.abc import Iterable
from dataclasses import dataclass, field
from typing import NamedTuple

import numpy as np

from bagkit.decode.errors import DecodeError
from bagkit.decode.msgdef import Nodetype, TypeDefinitions
from bagkit.decode.typegraph import check_registered

ENCAPSULATION_SIZE = 4
# Encapsulation header of little-endian plain CDR (what every ROS 2 middleware writes).
CDR_LE = b"\x00\x01"
U32 = struct.Struct("<I")
MAX_CACHED_MASKS = 1024

# numpy format of each CDR primitive (CDR aligns each to its own size).
PRIMITIVE_FORMATS: dict[str, str] = {
    "bool": "u1",
    "byte": "u1",
    "char": "u1",
    "int8": "i1",
    "uint8": "u1",
    "int16": "<i2",
    "uint16": "<u2",
    "int32": "<i4",
    "uint32": "<u4",
    "int64": "<i8",
    "uint64": "<u8",
    "float32": "<f4",
    "float64": "<f8",
}


@dataclass(frozen=True, slots=True)
class Slot:
    """A run of bytes in a message: one primitive, a fixed array, a string or a sequence.

    Attributes:
        path: leaf path (``orientation_covariance`` for the whole fixed array, ``ranges[]``).
        base: ROS primitive type name (``string`` for strings).
        count: elements of a fixed slot (1 for a scalar); ``None`` for a length-prefixed slot.
        array: a fixed-size array (its leaves are ``path[i]``), as opposed to a scalar.
    """

    path: str
    base: str
    count: int | None
    array: bool = False


@dataclass(frozen=True, slots=True)
class LeafColumn:
    """Where one leaf's values are in a :class:`ResolvedLayout`'s records.

    Attributes:
        path: the leaf path (``header.stamp.sec``, ``orientation_covariance[4]``, ``ranges[]``).
        name: the dtype field holding it.
        element: the element of a fixed array field, None for the whole field.
    """

    path: str
    name: str
    element: int | None


@dataclass(frozen=True, slots=True)
class ResolvedLayout:
    """The layout of the messages whose length prefixes all have given values.

    ``dtype`` has one field per slot with values, named by the slot's index in
    ``CdrLayout.slots`` (``"3"``), at its byte offset from the start of the payload
    (encapsulation header included): numbers as their numpy type (a sequence as a subarray),
    strings as ``S<length>`` (bytes, no NUL). Its ``itemsize`` is the exact payload size (CDR
    writers may add up to 3 bytes of padding). ``leaves`` says where each leaf is.
    """

    dtype: np.dtype
    leaves: tuple[LeafColumn, ...]

    def columns(self, records: np.ndarray, paths: Iterable[str]) -> dict[str, np.ndarray]:
        """The values of leaf ``paths`` in ``records`` (an array of ``dtype``), as views.

        A scalar leaf (and each element of a fixed array) is one value per record; a pooled
        leaf (``ranges[]``) a 2-D array, one row per record (all of one length in a layout);
        a string leaf ``S`` bytes. Paths that the layout has no values for (empty strings)
        are left out.
        """
        wanted = set(paths)
        found: dict[str, np.ndarray] = {}
        for leaf in self.leaves:
            if leaf.path in wanted:
                column = records[leaf.name]
                found[leaf.path] = column if leaf.element is None else column[:, leaf.element]
        return found


@dataclass(frozen=True, slots=True)
class NeedLength:
    """The offset in the payload of the next ``uint32`` length prefix to read.

    ``element_size`` is the size of one element of what it counts (1 for a string's bytes): a
    prefix saying more than the rest of the payload can hold is not a layout of that payload.
    """

    offset: int
    element_size: int


@dataclass(frozen=True, slots=True)
class CdrLayout:
    """The slots of a message type in CDR order."""

    slots: tuple[Slot, ...]
    # resolve()'s answers per set of length prefixes (up to MAX_CACHED_MASKS: the lengths
    # come from the payloads); every batch of a topic asks the same few again.
    _resolved: dict[tuple[int, ...], ResolvedLayout | NeedLength] = field(
        default_factory=dict, compare=False, repr=False
    )

    @classmethod
    def of(cls, typestore: TypeDefinitions, typename: str) -> CdrLayout | None:
        """The layout of ``typename``, or None when it has parts bulk decoding cannot place.

        Sequences of messages, sequences of strings and wide strings vary too freely to be
        grouped by a few length prefixes; such types are decoded message by message.

        Raises:
            SchemaError: the type is recursive or too large (:mod:`bagkit.decode.typegraph`).
        """
        check_registered(typestore, typename)
        slots: list[Slot] = []
        for name, desc in typestore.fielddefs[typename][1]:
            if not _collect(typestore, name, desc, slots):
                return None
        return cls(tuple(slots))

    def resolve(self, lengths: tuple[int, ...]) -> ResolvedLayout | NeedLength:
        """The dtype for messages with these length prefixes, or where the next prefix is.

        ``lengths`` are the values of the first prefixes in order (for strings: bytes including
        the terminating NUL, as CDR stores them).
        """
        found = self._resolved.get(lengths)
        if found is None:
            found = self._resolve(lengths)
            if len(self._resolved) < MAX_CACHED_MASKS:
                self._resolved[lengths] = found
        return found

    def _resolve(self, lengths: tuple[int, ...]) -> ResolvedLayout | NeedLength:
        placed = self._place(lengths)
        if isinstance(placed, NeedLength):
            return placed
        dtype = np.dtype(
            {
                "names": [str(p.slot) for p in placed.slots],
                "formats": [p.fmt for p in placed.slots],
                "offsets": [p.offset for p in placed.slots],
                "itemsize": placed.size,
            }
        )
        leaves: list[LeafColumn] = []
        for p in placed.slots:
            slot = self.slots[p.slot]
            if slot.array and slot.count is not None:
                leaves.extend(
                    LeafColumn(f"{slot.path}[{i}]", str(p.slot), i) for i in range(slot.count)
                )
            else:
                leaves.append(LeafColumn(slot.path, str(p.slot), None))
        return ResolvedLayout(dtype, tuple(leaves))

    def data_mask(self, lengths: tuple[int, ...]) -> int | NeedLength:
        """A mask of the bytes that hold data, or where the next length prefix is.

        The mask has all bits set in the bytes of the encapsulation header, the length prefixes,
        the strings and the primitives, read as a little-endian integer; the rest of a payload
        with these length prefixes is alignment padding.
        """
        placed = self._place(lengths)
        if isinstance(placed, NeedLength):
            return placed
        mask = (1 << (8 * ENCAPSULATION_SIZE)) - 1
        for offset, size in placed.data:
            mask |= ((1 << (8 * size)) - 1) << (8 * offset)
        return mask

    def _place(self, lengths: tuple[int, ...]) -> _Placement | NeedLength:
        pos = 0
        slots: list[_PlacedSlot] = []
        data: list[tuple[int, int]] = []
        known = iter(lengths)
        for index, slot in enumerate(self.slots):
            fmt = PRIMITIVE_FORMATS.get(slot.base, "u1")  # u1: the bytes of a string
            size = np.dtype(fmt).itemsize
            if slot.count is None:
                pos = _align(pos, 4)
                length = next(known, None)
                if length is None:
                    return NeedLength(ENCAPSULATION_SIZE + pos, size)
                data.append((ENCAPSULATION_SIZE + pos, 4))
                pos += 4
                count = length
            else:
                count = slot.count
            if slot.base == "string":
                data.append((ENCAPSULATION_SIZE + pos, count))
                if count > 1:  # the bytes before the NUL (a writer may omit an empty one's)
                    slots.append(_PlacedSlot(index, ENCAPSULATION_SIZE + pos, f"S{count - 1}"))
                pos += count
                continue
            if count:
                pos = _align(pos, size)
            shaped = fmt if not slot.array and slot.count == 1 else (fmt, (count,))
            slots.append(_PlacedSlot(index, ENCAPSULATION_SIZE + pos, shaped))
            data.append((ENCAPSULATION_SIZE + pos, size * count))
            pos += size * count
        return _Placement(tuple(slots), tuple(data), ENCAPSULATION_SIZE + pos)


# NamedTuples, not dataclasses: private records made per slot, whose classes every decoding
# command would otherwise build at start.
class _PlacedSlot(NamedTuple):
    """A numeric slot (``slot``: its index in ``CdrLayout.slots``) at its byte offset in the
    payload."""

    slot: int
    offset: int
    fmt: str | tuple[str, tuple[int, ...]]


class _Placement(NamedTuple):
    """Where everything of a message with known length prefixes is."""

    slots: tuple[_PlacedSlot, ...]
    data: tuple[tuple[int, int], ...]
    """(offset, size) of every length prefix, string and primitive run."""
    size: int


class PaddingZeroer:
    """Sets the alignment padding of CDR payloads of one type to zero.

    Writers leave padding as they please (rclpy's serializer leaves it uninitialized, so one
    message serializes to different bytes from run to run); with zeroed padding a message has
    one encoding, whichever writer produced it. Masks are cached per set of length prefixes
    (up to ``MAX_CACHED_MASKS`` of them: the lengths come from the payloads).
    """

    def __init__(self, layout: CdrLayout) -> None:
        self._layout = layout
        self._steps: dict[tuple[int, ...], int | NeedLength] = {}

    def __call__(self, data: bytes) -> bytes:
        """``data`` with every byte that is not header, length prefix or value set to zero.

        Raises:
            DecodeError: a length prefix says more than the payload holds.
        """
        lengths: tuple[int, ...] = ()
        steps = self._steps
        size = len(data)
        while True:
            step = steps.get(lengths)
            if step is None:
                step = self._layout.data_mask(lengths)
                if len(steps) < MAX_CACHED_MASKS:
                    steps[lengths] = step
            if isinstance(step, NeedLength):
                room = size - step.offset - 4
                length = U32.unpack_from(data, step.offset)[0] if room >= 0 else -1
                if not 0 <= length * step.element_size <= room:
                    raise DecodeError("a length prefix says more than the payload holds")
                lengths += (length,)
                continue
            return (int.from_bytes(data, "little") & step).to_bytes(size, "little")


def _align(pos: int, size: int) -> int:
    return (pos + size - 1) // size * size


def _collect(typestore: TypeDefinitions, path: str, desc: tuple, slots: list[Slot]) -> bool:
    kind, rest = desc
    if kind == Nodetype.BASE:
        base = rest[0]
        if base == "string":
            slots.append(Slot(path, base, None))
            return True
        if base not in PRIMITIVE_FORMATS:
            return False
        slots.append(Slot(path, base, 1))
        return True
    if kind == Nodetype.NAME:
        return all(
            _collect(typestore, f"{path}.{name}", sub, slots)
            for name, sub in typestore.fielddefs[rest][1]
        )
    sub, length = rest
    if kind == Nodetype.ARRAY:
        if sub[0] == Nodetype.BASE and sub[1][0] in PRIMITIVE_FORMATS:
            slots.append(Slot(path, sub[1][0], length, array=True))
            return True
        return all(_collect(typestore, f"{path}[{i}]", sub, slots) for i in range(length))
    if sub[0] == Nodetype.BASE and sub[1][0] in PRIMITIVE_FORMATS:
        slots.append(Slot(f"{path}[]", sub[1][0], None))
        return True
    return False
