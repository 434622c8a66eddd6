"""Running statistics of one topic, fed by bulk-decoded columns or by payloads one at a time."""

from __future__ import annotations

from collections.abc import Iterable
from typing import Any

import numpy as np

from bagkit.bag.definitions import INTEGER_TYPES
from bagkit.decode import DecodeError, LeafField, MessageTypes
from bagkit.decode.direct import ValueReader
from bagkit.decode.layout import CdrLayout, ResolvedLayout
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
        self.read_values = self.value_reader(types)
        self.column = {path: i for i, path in enumerate(self.scalar_paths)}
        self.scalars = Moments(len(self.scalar_paths))
        self.pooled = {leaf.path: Moments(1) for leaf in leaves if leaf.pooled}
        self.count = 0
        self.first_ns: int | None = None
        self.last_ns: int | None = None
        self.failures = 0
        self.first_failure = ""
        # Every leaf of the type as first seen: pooled bags must define the type the same way.
        self.signature = signature
        self._rows: list[list[Any]] = []
        self._pooled_rows: list[list[Any]] = []
        self._pooled_size = 0
        self._plans: dict[np.dtype, list[tuple[str, np.ndarray | None, np.ndarray | str]]] = {}

    def value_reader(self, types: MessageTypes) -> ValueReader:
        """payload -> the values of ``scalar_paths``, then of the pooled paths."""
        pooled = [leaf.path for leaf in self.leaves if leaf.pooled]
        return types.value_reader(self.type_name, [*self.scalar_paths, *pooled])

    def add_times(self, log_times: np.ndarray) -> None:
        if not len(log_times):
            return
        self.count += len(log_times)
        first, last = int(log_times.min()), int(log_times.max())
        self.first_ns = first if self.first_ns is None else min(self.first_ns, first)
        self.last_ns = last if self.last_ns is None else max(self.last_ns, last)

    def _plan(self, resolved: ResolvedLayout) -> list[tuple[str, np.ndarray | None, Any]]:
        """Where each dtype field goes: (name, source columns or None, target columns | path)."""
        plan = self._plans.get(resolved.dtype)
        if plan is not None:
            return plan
        assert self.layout is not None
        plan = []
        for index in resolved.slot_indexes:
            slot = self.layout.slots[index]
            name = str(index)
            if slot.count is None:
                if slot.path in self.pooled:
                    plan.append((name, None, slot.path))
            elif slot.array:
                paths = [f"{slot.path}[{i}]" for i in range(slot.count)]
                source = [i for i, p in enumerate(paths) if p in self.column]
                if source:
                    targets = np.array([self.column[paths[i]] for i in source])
                    plan.append((name, np.array(source), targets))
            elif slot.path in self.column:
                plan.append((name, None, np.array([self.column[slot.path]])))
        self._plans[resolved.dtype] = plan
        return plan

    def add_bulk(self, resolved: ResolvedLayout, values: np.ndarray) -> None:
        """Add messages decoded in bulk (a structured array of ``resolved.dtype``)."""
        # Column-major: filling a column and reducing along it are contiguous (2x faster).
        matrix = np.empty((len(values), len(self.scalar_paths)), order="F")
        for name, source, target in self._plan(resolved):
            column = values[name]
            if isinstance(target, str):
                self.pooled[target].add(column.reshape(-1, 1))
            elif source is None:
                matrix[:, target[0]] = column
            else:
                matrix[:, target] = column[:, source]
        if self.scalar_paths:
            self.scalars.add(matrix)

    def add_payloads(self, payloads: Iterable[bytes | memoryview]) -> None:
        """Decode messages one by one (the general path) and add them."""
        read_values, rows = self.read_values, self._rows
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
        if self.scalar_paths:
            # np.array of a list of rows converts faster than array('d') or np.fromiter.
            self.scalars.add(np.array(self._rows, dtype=np.float64))
        for j, moments in enumerate(self.pooled.values()):
            parts = [np.asarray(row[j], dtype=np.float64) for row in self._pooled_rows]
            moments.add(np.concatenate(parts).reshape(-1, 1))
        self._rows.clear()
        self._pooled_rows.clear()
        self._pooled_size = 0

    def fail(self, exc: Exception) -> None:
        self.failures += 1
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
            fields.append(_field_stats(leaf, moments, column, float(leaf_std)))
        rate = None
        if self.count > 1 and self.first_ns is not None and self.last_ns is not None:
            span = (self.last_ns - self.first_ns) / 1e9
            rate = (self.count - 1) / span if span > 0 else None
        return TopicStats(self.topic, self.type_name, self.count, rate, tuple(fields))


def _field_stats(leaf: LeafField, moments: Moments, column: int, std: float) -> FieldStats:
    count = int(moments.count[column])
    nan_count = int(moments.nan_count[column])
    if count == 0:
        return FieldStats(leaf.path, 0, nan_count, None, None, None, None)
    low, high = float(moments.min[column]), float(moments.max[column])
    as_int = leaf.base in INTEGER_TYPES
    return FieldStats(
        leaf.path,
        count,
        nan_count,
        int(low) if as_int else low,
        int(high) if as_int else high,
        float(moments.mean[column]),
        None if np.isnan(std) and count < 2 else std,
    )
