"""Running statistics of one topic, fed by bulk-decoded columns or by payloads one at a time."""

from __future__ import annotations

from collections.abc import Iterable
from typing import Any

import numpy as np

from bagkit.bag.definitions import INTEGER_TYPES
from bagkit.bag.rates import pooled_rate
from bagkit.decode import DecodeError, LeafField, MessageTypes
from bagkit.decode.bulk import decode_bulk, spans_inside
from bagkit.decode.direct import ValueReader
from bagkit.decode.layout import CdrLayout
from bagkit.stats.moments import Moments
from bagkit.stats.result import FieldStats, TopicStats

# Messages decoded one by one are buffered this many at a time before their moments are taken,
# or fewer when their pooled arrays (an image's data[]) hold more than POOLED_BATCH values.
ROW_BATCH = 4096
POOLED_BATCH = 1 << 20


class TopicAccumulator:
    """Running statistics of one topic: one Moments over its scalar fields, one per pooled."""

    def __init__(
        self,
        topic: str,
        type_name: str,
        leaves: list[LeafField],
        *,
        layout: CdrLayout | None,
        types: MessageTypes,
        signature: tuple[LeafField, ...],
    ) -> None:
        self.topic = topic
        self.type_name = type_name
        self.leaves = leaves
        self.layout = layout
        self.scalar_paths = [leaf.path for leaf in leaves if not leaf.pooled]
        self.paths = [leaf.path for leaf in leaves]
        # The general path's reader is made when a payload needs it: a topic decoded in bulk
        # never does, and making one generates code (see bench_startup).
        self.types = types
        self.read_values: ValueReader | None = None
        self.column = {path: i for i, path in enumerate(self.scalar_paths)}
        self.scalars = Moments(len(self.scalar_paths))
        self.pooled = {leaf.path: Moments(1) for leaf in leaves if leaf.pooled}
        self.count = 0
        self.first_ns: int | None = None
        self.last_ns: int | None = None
        # Pooled over bags: intervals between messages and the time they span, bag by bag
        # (the time between bags is no interval); the open bag's (count, first, last).
        self.intervals = 0
        self.span_ns = 0
        self._bag: tuple[int, int, int] | None = None
        self.failures = 0
        self.first_failure = ""
        # Every leaf of the type as first seen: pooled bags must define the type the same way.
        self.signature = signature
        self._rows: list[list[Any]] = []
        self._pooled_rows: list[list[Any]] = []
        self._pooled_size = 0

    def __getstate__(self) -> dict[str, Any]:
        """The figures only (bagkit.fleet ships them between processes): no decoder, no buffer."""
        self.flush()
        skipped = ("read_values", "layout", "types")
        return {k: v for k, v in self.__dict__.items() if k not in skipped}

    def use_types(self, types: MessageTypes) -> None:
        """Decode the next bag's payloads with ``types`` (its own definitions)."""
        self.types = types
        self.read_values = None

    def value_reader(self) -> ValueReader:
        """payload -> the values of ``scalar_paths``, then of the pooled paths."""
        if self.read_values is None:
            pooled = [leaf.path for leaf in self.leaves if leaf.pooled]
            self.read_values = self.types.value_reader(
                self.type_name, [*self.scalar_paths, *pooled]
            )
        return self.read_values

    def add_times(self, log_times: np.ndarray) -> None:
        if not len(log_times):
            return
        self.count += len(log_times)
        first, last = int(log_times.min()), int(log_times.max())
        self.first_ns = first if self.first_ns is None else min(self.first_ns, first)
        self.last_ns = last if self.last_ns is None else max(self.last_ns, last)
        bag = self._bag or (0, first, last)
        self._bag = (bag[0] + len(log_times), min(bag[1], first), max(bag[2], last))

    def end_bag(self) -> None:
        """The bag being read is done: its intervals and span join the pooled ones."""
        if self._bag is not None:
            count, first, last = self._bag
            self.intervals += count - 1
            self.span_ns += last - first
            self._bag = None

    def add_spans(self, records: bytes, starts: np.ndarray, lengths: np.ndarray) -> None:
        """Add the payloads ``records[starts[i] : starts[i] + lengths[i]]`` (one chunk's).

        Decoded in bulk where the type has a layout, the rest one by one; a span that is not
        inside ``records`` counts as a message that could not be decoded.
        """
        with np.errstate(invalid="ignore"):  # casts of signalling NaNs (see Moments.add)
            self._add_spans(records, starts, lengths)

    def _add_spans(self, records: bytes, starts: np.ndarray, lengths: np.ndarray) -> None:
        buf = np.frombuffer(records, dtype=np.uint8)
        if self.layout is not None:
            groups, leftover = decode_bulk(buf, starts, lengths, self.layout)
            for group in groups:
                self.add_columns(group.columns(self.paths), len(group.indexes))
        else:
            leftover = np.arange(len(starts))
        if not len(leftover):
            return
        starts, lengths = starts[leftover], lengths[leftover]
        inside = spans_inside(len(buf), starts, lengths)
        if not inside.all():
            self.fail(DecodeError("payload outside its chunk"), int((~inside).sum()))
            starts, lengths = starts[inside], lengths[inside]
        # Views, not copies: add_payloads keeps nothing that points into the chunk.
        view = memoryview(records)
        self.add_payloads(
            view[begin : begin + length]
            for begin, length in zip(starts.tolist(), lengths.tolist(), strict=True)
        )

    def add_columns(self, columns: dict[str, np.ndarray], count: int) -> None:
        """Add ``count`` messages decoded in bulk: leaf path -> values (see ``BulkGroup``)."""
        # Column-major: filling a column and reducing along it are contiguous memory.
        matrix = np.empty((count, len(self.scalar_paths)), order="F")
        for path, values in columns.items():
            column = self.column.get(path)
            if column is None:
                self.pooled[path].add(values.reshape(-1, 1))
            else:
                matrix[:, column] = values
        if self.scalar_paths:
            self.scalars.add(matrix)

    def add_payloads(self, payloads: Iterable[bytes | memoryview]) -> None:
        """Decode messages one by one (the general path) and add them."""
        with np.errstate(invalid="ignore"):  # casts of signalling NaNs (see Moments.add)
            self._add_payloads(payloads)

    def _add_payloads(self, payloads: Iterable[bytes | memoryview]) -> None:
        read_values, rows = self.value_reader(), self._rows
        split = len(self.scalar_paths)
        for data in payloads:
            try:
                values = read_values(data)
            except DecodeError as exc:
                self.fail(exc)
                continue
            if self.pooled:
                rows.append(values[:split])
                # Copies: a decoded array may be a view of the chunk, which must not be kept.
                pooled = [np.array(v, dtype=np.float64) for v in values[split:]]
                self._pooled_rows.append(pooled)
                self._pooled_size += sum(len(v) for v in pooled)
            else:
                rows.append(values)
            if len(rows) >= ROW_BATCH or self._pooled_size >= POOLED_BATCH:
                self.flush()

    def flush(self) -> None:
        """Take the moments of the messages buffered by :meth:`add_payloads`."""
        if not self._rows:
            return
        with np.errstate(invalid="ignore"):  # casts of signalling NaNs (see Moments.add)
            self._flush()

    def _flush(self) -> None:
        if self.scalar_paths:
            # np.array of a list of rows converts faster than array('d') or np.fromiter.
            self.scalars.add(np.array(self._rows, dtype=np.float64))
        for j, moments in enumerate(self.pooled.values()):
            parts = [np.asarray(row[j], dtype=np.float64) for row in self._pooled_rows]
            moments.add(np.concatenate(parts).reshape(-1, 1))
        self._rows.clear()
        self._pooled_rows.clear()
        self._pooled_size = 0

    def fail(self, exc: Exception, count: int = 1) -> None:
        """Count ``count`` messages that could not be decoded (the first reason is kept)."""
        self.failures += count
        self.first_failure = self.first_failure or str(exc)

    def result(self) -> TopicStats:
        self.flush()
        std = self.scalars.std()
        fields = []
        for leaf in self.leaves:
            if leaf.pooled:
                moments, column = self.pooled[leaf.path], 0
                leaf_std = moments.std()[0]
            else:
                moments, column = self.scalars, self.column[leaf.path]
                leaf_std = std[column]
            as_int = leaf.base in INTEGER_TYPES
            fields.append(_field_stats(leaf.path, as_int, moments, column, float(leaf_std)))
        self.end_bag()
        rate = pooled_rate(self.count, self.intervals, self.span_ns)
        return TopicStats(
            self.topic, self.type_name, self.count, rate, tuple(fields), self.failures
        )


def value_stats(name: str, values: np.ndarray) -> FieldStats:
    """The statistics of one column of numbers, as those of a float field named ``name``."""
    moments = Moments(1)
    moments.add(np.asarray(values, dtype=np.float64).reshape(-1, 1))
    return _field_stats(name, False, moments, 0, float(moments.std()[0]))


def _field_stats(name: str, as_int: bool, moments: Moments, column: int, std: float) -> FieldStats:
    count = int(moments.count[column])
    nan_count = int(moments.nan_count[column])
    if count == 0:
        return FieldStats(name, 0, nan_count, None, None, None, None)
    low, high = float(moments.min[column]), float(moments.max[column])
    return FieldStats(
        name,
        count,
        nan_count,
        int(low) if as_int else low,
        int(high) if as_int else high,
        float(moments.mean[column]),
        None if np.isnan(std) and count < 2 else std,
    )
