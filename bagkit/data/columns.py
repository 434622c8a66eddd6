"""One topic's messages as Arrow record batches: ``log_time``, ``publish_time``, leaf fields.

The same engine as ``stats summary``: payloads of fixed-layout types are decoded a chunk at a
time with numpy structured dtypes (:func:`~bagkit.data.engine.decode_bulk`), and columns are
sliced straight out of them; every other payload (other types, messages the bulk decoder hands
back) goes through the general decoder (``MessageTypes.value_reader``). Columns:

- scalar leaves by their dotted path, in their ROS type (``float32`` stays ``float32``, ``bool``
  is boolean, ``byte``/``char`` are ``uint8``, strings are strings);
- fixed arrays one column per element (``orientation_covariance[0]``);
- variable-length sequences as list columns (``ranges[]``; ``status[].level`` holds the levels
  of every element of ``status``).
"""

from __future__ import annotations

import functools
from collections.abc import Callable, Iterable, Sequence
from typing import TYPE_CHECKING, Any

import numpy as np

from bagkit.data.engine import BulkGroup, Spans, decode_bulk, payload_spans
from bagkit.decode import DecodeError, LeafField, MessageTypes
from bagkit.decode.direct import ValueReader
from bagkit.decode.flatten import STRING_TYPES
from bagkit.decode.layout import PRIMITIVE_FORMATS, CdrLayout
from bagkit.decode.matcher import PayloadMatcher
from bagkit.decode.typegraph import check_registered
from bagkit.selection.windows import Window

if TYPE_CHECKING:
    import pyarrow as pa

# pyarrow is imported where Arrow is made: `find` and `check` read columns as numpy only.
TIME_COLUMNS = ("log_time", "publish_time")


@functools.cache
def _arrow_types() -> dict[str, pa.DataType]:
    import pyarrow as pa

    return {
        "bool": pa.bool_(),
        "byte": pa.uint8(),
        "char": pa.uint8(),
        "int8": pa.int8(),
        "uint8": pa.uint8(),
        "int16": pa.int16(),
        "uint16": pa.uint16(),
        "int32": pa.int32(),
        "uint32": pa.uint32(),
        "int64": pa.int64(),
        "uint64": pa.uint64(),
        "float32": pa.float32(),
        "float64": pa.float64(),
        "string": pa.string(),
        "wstring": pa.string(),
    }


def arrow_type(leaf: LeafField) -> pa.DataType:
    """The Arrow type of a leaf's column (a list type for a pooled leaf)."""
    import pyarrow as pa

    scalar = _arrow_types()[leaf.base]
    return pa.list_(scalar) if leaf.pooled else scalar


def arrow_schema(leaves: Sequence[LeafField]) -> pa.Schema:
    """``log_time``, ``publish_time`` (int64 ns), then one column per leaf."""
    import pyarrow as pa

    return pa.schema(
        [pa.field(name, pa.int64(), nullable=False) for name in TIME_COLUMNS]
        + [pa.field(leaf.path, arrow_type(leaf)) for leaf in leaves]
    )


def numpy_dtype(leaf: LeafField) -> np.dtype:
    """The numpy dtype a leaf's values are gathered in (object for strings and lists)."""
    if leaf.base in STRING_TYPES or leaf.pooled:
        return np.dtype(object)
    return np.dtype(bool) if leaf.base == "bool" else np.dtype(PRIMITIVE_FORMATS[leaf.base])


class Rows:
    """``n`` rows being filled (some from bulk groups, the rest one by one): times, one array
    per leaf, and which rows decoded (``ok``). The arrays may be views of a larger table."""

    def __init__(
        self,
        leaves: Sequence[LeafField],
        arrays: list[np.ndarray],
        times: tuple[np.ndarray, np.ndarray],
        ok: np.ndarray,
    ) -> None:
        self.leaves = leaves
        self.arrays = arrays
        self.log_times, self.publish_times = times
        self.ok = ok

    @classmethod
    def empty(cls, leaves: Sequence[LeafField], n: int) -> Rows:
        """Rows of their own (not part of a table)."""
        arrays = [np.empty(n, dtype=numpy_dtype(leaf)) for leaf in leaves]
        times = (np.empty(n, dtype=np.int64), np.empty(n, dtype=np.int64))
        return cls(leaves, arrays, times, np.ones(n, dtype=bool))

    def fill_rows(self, rows: list[list[Any]], positions: list[int]) -> None:
        """Set the rows at ``positions`` from per-message value lists."""
        if not rows:
            return
        where = np.array(positions, dtype=np.int64)
        for array, values in zip(self.arrays, zip(*rows, strict=True), strict=True):
            if array.dtype == object:
                column = np.empty(len(values), dtype=object)
                column[:] = values
                array[where] = column
            else:
                array[where] = np.array(values, dtype=array.dtype)

    def batch(self, schema: pa.Schema) -> pa.RecordBatch:
        """The rows that decoded, as a record batch of ``schema``."""
        import pyarrow as pa

        ok = self.ok if not self.ok.all() else slice(None)
        arrays = [self.log_times[ok], self.publish_times[ok], *(a[ok] for a in self.arrays)]
        return pa.RecordBatch.from_arrays(arrow_arrays(self.leaves, arrays, schema), schema=schema)


def arrow_arrays(
    leaves: Sequence[LeafField], arrays: Sequence[np.ndarray], schema: pa.Schema
) -> list[pa.Array]:
    """``log_time``, ``publish_time`` and the leaf arrays as Arrow arrays of ``schema``
    (numbers without a copy)."""
    import pyarrow as pa

    out = [pa.array(arrays[0]), pa.array(arrays[1])]
    for leaf, array, field in zip(leaves, arrays[2:], list(schema)[2:], strict=True):
        if leaf.pooled:
            out.append(list_array(array, leaf, field.type))
        else:
            out.append(pa.array(array, type=field.type))
    return out


def list_array(items: np.ndarray, leaf: LeafField, type_: pa.ListType) -> pa.Array:
    """A list column from per-message sequences (numpy arrays or lists), values copied."""
    import pyarrow as pa

    if leaf.base in STRING_TYPES:
        return pa.array([list(x) for x in items], type=type_)
    dtype = np.dtype(PRIMITIVE_FORMATS[leaf.base])
    lengths = np.fromiter((len(x) for x in items), dtype=np.int64, count=len(items))
    offsets = np.zeros(len(items) + 1, dtype=np.int32)
    np.cumsum(lengths, out=offsets[1:])
    parts = [np.asarray(x, dtype=dtype) for x in items]
    values = np.concatenate(parts) if parts else np.empty(0, dtype=dtype)
    flat = pa.array(values != 0 if leaf.base == "bool" else values, type=type_.value_type)
    return pa.ListArray.from_arrays(pa.array(offsets), flat, type=type_)


class TopicColumns:
    """Decodes the messages of one topic into record batches of :attr:`schema`.

    Args:
        types: the bag's message types.
        topic: the topic name (to find its message-index entries in chunks).
        type_name: its type as the bag names it.
        leaves: the fields to read (``leaf_fields`` of the type, maybe a selection).
        bulk: decode fixed-layout payloads with numpy (False: all through the general decoder).
        matcher: only the messages it matches (``--where``); those it cannot decode are
            counted in its ``failures``.

    It counts what it read: :attr:`messages` (in the window, before the matcher),
    :attr:`undecodable`, and :attr:`unindexed` index entries pointing outside their chunk.

    Raises:
        SchemaError: the type cannot be decoded.
    """

    def __init__(
        self,
        types: MessageTypes,
        topic: str,
        type_name: str,
        leaves: Sequence[LeafField],
        *,
        bulk: bool = True,
        matcher: PayloadMatcher | None = None,
    ) -> None:
        types = types.for_topic(topic)
        canonical = types.resolve(type_name)
        self.topic = topic
        self.matcher = matcher
        self.type_name = type_name
        self.leaves = list(leaves)
        paths = [leaf.path for leaf in self.leaves]
        check_registered(types.typestore, canonical)  # what the reader would raise, now
        self._types = types
        # The general reader is made when a payload needs it (a bulk-decoded topic never does).
        self._read_values: ValueReader | None = None
        self.layout = CdrLayout.of(types.typestore, canonical) if bulk and paths else None
        self._column_of = {leaf.path: j for j, leaf in enumerate(self.leaves)}
        self.messages = 0
        self.failures = 0
        self.first_failure = ""
        self.unindexed = 0

    @functools.cached_property
    def schema(self) -> pa.Schema:
        """The Arrow schema of the topic's batches (made on first use: imports pyarrow)."""
        return arrow_schema(self.leaves)

    @property
    def undecodable(self) -> int:
        """Of the :attr:`messages` read, those that did not decode (in the condition's matcher
        or into columns)."""
        return self.failures + (self.matcher.undecodable if self.matcher else 0)

    @property
    def first_undecodable(self) -> str:
        """Why the first of :attr:`undecodable` did not decode."""
        return self.first_failure or (self.matcher.first_failure if self.matcher else "")

    def decode_chunk(
        self, records: bytes, index: np.ndarray, window: Window, reserve: Callable[[int], Rows]
    ) -> Rows:
        """Decode the messages of this topic in one chunk into ``reserve(count)``."""
        spans = payload_spans(records, index, window.start_ns, window.end_ns)
        self.unindexed += spans.dropped
        self.messages += len(spans.starts)
        if self.matcher is not None:
            spans = spans.take(self.matcher.mask_records(records, spans.starts, spans.lengths))
        return self.decode_spans(records, spans, reserve)

    def decode_spans(self, records: bytes, spans: Spans, reserve: Callable[[int], Rows]) -> Rows:
        """Decode the payloads at ``spans`` of a chunk's records into ``reserve(count)``, in
        the order of ``spans``."""
        buf = np.frombuffer(records, dtype=np.uint8)
        columns = reserve(len(spans.starts))
        columns.log_times[:] = spans.log_times
        columns.publish_times[:] = spans.publish_times
        leftover = np.arange(len(spans.starts))
        if self.layout is not None and len(spans.starts):
            groups, leftover = decode_bulk(buf, spans.starts, spans.lengths, self.layout)
            for group in groups:
                if not self._fill_group(columns, group):
                    leftover = np.union1d(leftover, group.indexes)
        view = memoryview(records)
        starts, lengths = spans.starts[leftover].tolist(), spans.lengths[leftover].tolist()
        self._fill_general(
            columns,
            leftover.tolist(),
            (view[s : s + n] for s, n in zip(starts, lengths, strict=True)),
        )
        return columns

    def _fill_general(
        self, columns: Rows, positions: list[int], payloads: Iterable[bytes | memoryview]
    ) -> None:
        if not positions or not self.leaves:
            return
        if self._read_values is None:
            paths = [leaf.path for leaf in self.leaves]
            self._read_values = self._types.value_reader(self.type_name, paths)
        read = self._read_values
        rows: list[list[Any]] = []
        done: list[int] = []
        for position, data in zip(positions, payloads, strict=True):
            try:
                rows.append(read(data))
                done.append(position)
            except DecodeError as exc:
                columns.ok[position] = False
                self.failures += 1
                self.first_failure = self.first_failure or str(exc)
        columns.fill_rows(rows, done)

    def _fill_group(self, columns: Rows, group: BulkGroup) -> bool:
        """Fill the rows of one bulk group; False when one of its strings is not UTF-8."""
        rows = _as_slice(group.indexes)
        found = group.columns(self._column_of)
        for path, column in self._column_of.items():
            target = columns.arrays[column]
            leaf = self.leaves[column]
            source = found.get(path)
            if leaf.base in STRING_TYPES:
                # A layout holds no values for empty strings.
                texts = "" if source is None else _utf8(source)
                if texts is None:
                    return False
                target[rows] = texts
            elif source is None:
                continue
            elif leaf.pooled:
                rows_of = np.empty(len(group.indexes), dtype=object)
                rows_of[:] = list(source)
                target[rows] = rows_of
            else:
                target[rows] = source != 0 if target.dtype == bool else source
        return True


def _utf8(raw: np.ndarray) -> str | np.ndarray | None:
    """The texts of ``S`` bytes ``raw`` (one str when all are equal); None if one is not UTF-8."""
    try:
        if (raw == raw[0]).all():
            return bytes(raw[0]).decode()
        unique, inverse = np.unique(raw, return_inverse=True)
        texts = np.array([bytes(u).decode() for u in unique], dtype=object)
    except UnicodeDecodeError:
        return None
    return texts[inverse]


def _as_slice(indexes: np.ndarray) -> slice | np.ndarray:
    """A slice for ascending consecutive indexes (the usual group: assigning to it is a copy,
    not a scatter)."""
    if len(indexes) and int(indexes[-1]) - int(indexes[0]) == len(indexes) - 1:
        return slice(int(indexes[0]), int(indexes[-1]) + 1)
    return indexes
