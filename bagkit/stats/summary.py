"""``summarize``: per-topic counts and rates, per-numeric-field exact statistics, over bags.

One pass over each bag, one decompressed chunk at a time (memory does not grow with the bag).
Topics whose type has a CDR layout (see :mod:`bagkit.decode.layout`) are decoded in bulk from
each chunk with numpy; every other message goes through rosbags' deserializer and
:func:`~bagkit.decode.field_getter`. Both feed the same :class:`~bagkit.stats.moments.Moments`.
"""

from __future__ import annotations

import re
from collections.abc import Callable, Iterable, Sequence
from contextlib import closing
from dataclasses import asdict, dataclass, field
from pathlib import Path
from typing import TYPE_CHECKING, Any

import numpy as np

from bagkit.bag import BagChunk, BagReader
from bagkit.bag.definitions import INTEGER_TYPES
from bagkit.bag.mcap import MESSAGE_DATA_OFFSET, MESSAGE_PREFIX
from bagkit.decode import DecodeError, LeafField, MessageTypes, leaf_fields
from bagkit.decode.direct import ValueReader
from bagkit.decode.layout import CdrLayout, ResolvedLayout
from bagkit.stats.bulk import decode_bulk, read_u64
from bagkit.stats.errors import NothingToSummarizeError, StatsError, UnknownTopicError
from bagkit.stats.moments import Moments
from bagkit.stats.prefetch import prefetch

if TYPE_CHECKING:
    import pandas as pd

# Messages decoded one by one are buffered this many at a time before their moments are taken,
# or fewer when their pooled arrays (an image's data[]) hold more than POOLED_BATCH values.
ROW_BATCH = 4096
POOLED_BATCH = 1 << 20

ProgressCallback = Callable[[int, int], None]
"""Called with (messages done, messages in total) as the summary advances."""


@dataclass(frozen=True, slots=True)
class FieldStats:
    """Statistics of one numeric leaf field (NaN values are counted apart, as pandas does).

    ``min``/``max``/``mean`` are None without values, ``std`` (ddof=1) below two values;
    ``min``/``max`` are ints for integer and boolean fields.
    """

    field: str
    count: int
    nan_count: int
    min: float | int | None
    max: float | int | None
    mean: float | None
    std: float | None


@dataclass(frozen=True, slots=True)
class TopicStats:
    """Count, rate and field statistics of one topic.

    ``rate_hz`` is (count - 1) / (last - first log time), None below two messages.
    """

    topic: str
    type: str
    count: int
    rate_hz: float | None
    fields: tuple[FieldStats, ...]


@dataclass(frozen=True, slots=True)
class Summary:
    """What :func:`summarize` found.

    Attributes:
        bags: the bags summarized, as given.
        start_ns, end_ns: first and last log time of the summarized messages.
        topics: per topic, in name order.
        skipped: topic -> why it could not be decoded (not in ``topics``).
        problems: what could not be read (salvaged files, messages that do not decode).
    """

    bags: tuple[str, ...]
    start_ns: int
    end_ns: int
    topics: tuple[TopicStats, ...]
    skipped: dict[str, str] = field(default_factory=dict)
    problems: tuple[str, ...] = ()

    @property
    def duration_s(self) -> float:
        """Seconds from the first to the last summarized message."""
        return (self.end_ns - self.start_ns) / 1e9

    def to_dict(self) -> dict[str, Any]:
        """The JSON document of ``bagkit stats summary --format json``."""
        return {
            "bags": list(self.bags),
            "start_ns": self.start_ns,
            "end_ns": self.end_ns,
            "duration_s": self.duration_s,
            "topics": [
                {
                    "topic": t.topic,
                    "type": t.type,
                    "count": t.count,
                    "rate_hz": t.rate_hz,
                    "fields": [asdict(f) for f in t.fields],
                }
                for t in self.topics
            ],
        }

    def to_dataframe(self) -> pd.DataFrame:
        """One row per (topic, field): columns topic, type, field, count ... std."""
        import pandas as pd

        rows = [
            {"topic": t.topic, "type": t.type, **asdict(f)} for t in self.topics for f in t.fields
        ]
        columns = ["topic", "type", "field", "count", "nan_count", "min", "max", "mean", "std"]
        frame = pd.DataFrame(rows, columns=columns)
        return frame.astype({c: "float64" for c in ("min", "max", "mean", "std")})


def field_matcher(patterns: Sequence[str] | None) -> Callable[[str], bool]:
    """A predicate for field paths matching any of the globs in ``patterns`` (all when None).

    Only ``*`` and ``?`` are wildcards: brackets are literal so that ``covariance[0]`` and
    ``ranges[]`` can be named as they are printed.
    """
    if not patterns:
        return lambda _path: True
    regex = re.compile(
        "|".join(
            "".join(".*" if c == "*" else "." if c == "?" else re.escape(c) for c in pattern)
            for pattern in patterns
        )
    )
    return lambda path: regex.fullmatch(path) is not None


class _TopicAccumulator:
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

    def __getstate__(self) -> dict[str, Any]:
        """The figures only (bagkit.fleet ships them between processes): no decoder, no buffer."""
        self.flush()
        caches = ("read_values", "layout", "_plans")
        return {k: v for k, v in self.__dict__.items() if k not in caches}

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


@dataclass(slots=True)
class _Run:
    """The state of one :func:`summarize` call across its bags."""

    types: MessageTypes
    select_field: Callable[[str], bool]
    fields_given: bool
    start_ns: int | None
    end_ns: int | None
    bulk: bool
    accumulators: dict[str, _TopicAccumulator] = field(default_factory=dict)
    skipped: dict[str, str] = field(default_factory=dict)
    problems: list[str] = field(default_factory=list)

    def accumulator(
        self, topic: str, type_name: str, encoding: str, bag: str
    ) -> _TopicAccumulator | None:
        """The accumulator of ``topic``, or None when ``bag``'s messages on it cannot be decoded.

        Raises:
            StatsError: the topic has another type, or another definition of its type, in a
                bag summarized before ``bag``.
        """
        existing = self.accumulators.get(topic)
        if existing is not None:
            if existing.type_name != type_name:
                raise StatsError(
                    f"topic {topic} has type {existing.type_name} in one bag "
                    f"and {type_name} in another"
                )
            if encoding != "cdr":
                why = f"serialization format {encoding!r} is not CDR"
                self.problems.append(f"{bag}: messages on {topic} not read: {why}")
                return None
            try:
                canonical = self.types.resolve(type_name)
            except DecodeError as exc:
                self.problems.append(f"{bag}: messages on {topic} not read: {exc}")
                return None
            if tuple(leaf_fields(self.types.typestore, canonical)) != existing.signature:
                raise StatsError(
                    f"{type_name} of topic {topic} is defined differently in {bag} than in "
                    "the bags before it: summarize them separately"
                )
            existing.read_values = existing.value_reader(self.types)
            return existing
        if topic in self.skipped:
            return None
        if encoding != "cdr":
            self.skipped[topic] = f"serialization format {encoding!r} is not CDR"
            return None
        try:
            canonical = self.types.resolve(type_name)
        except DecodeError as exc:
            self.skipped[topic] = str(exc)
            return None
        signature = tuple(leaf_fields(self.types.typestore, canonical))
        leaves = [leaf for leaf in signature if leaf.numeric and self.select_field(leaf.path)]
        layout = CdrLayout.of(self.types.typestore, canonical) if self.bulk else None
        accumulator = _TopicAccumulator(
            topic, type_name, leaves, layout=layout, types=self.types, signature=signature
        )
        self.accumulators[topic] = accumulator
        return accumulator

    def in_window(self, log_times: np.ndarray) -> np.ndarray:
        mask = np.ones(len(log_times), dtype=bool)
        if self.start_ns is not None:
            mask &= log_times >= self.start_ns
        if self.end_ns is not None:
            mask &= log_times < self.end_ns
        return mask

    def add_chunk(self, chunk: BagChunk, accumulators: dict[str, _TopicAccumulator]) -> int:
        """Add the messages of ``chunk`` on the accumulated topics; return how many were seen."""
        buf = np.frombuffer(chunk.records, dtype=np.uint8)
        seen = 0
        for topic, index in chunk.message_index.items():
            accumulator = accumulators.get(topic)
            if accumulator is None:
                continue
            seen += len(index)
            entries = index
            log_times = entries["log_time"]
            if self.start_ns is not None or self.end_ns is not None:
                keep = self.in_window(log_times)
                entries, log_times = entries[keep], log_times[keep]
            accumulator.add_times(log_times)
            if not len(entries) or not accumulator.leaves:  # counted; no field to decode
                continue
            offsets = entries["offset"].astype(np.int64)
            starts = offsets + MESSAGE_DATA_OFFSET
            lengths = read_u64(buf, offsets + 1).astype(np.int64) - MESSAGE_PREFIX.size
            if accumulator.layout is not None:
                groups, leftover = decode_bulk(buf, starts, lengths, accumulator.layout)
                for group in groups:
                    accumulator.add_bulk(group.layout, group.values)
            else:
                leftover = np.arange(len(starts))
            # Views, not copies: add_payloads keeps nothing that points into the chunk.
            records = memoryview(chunk.records)
            accumulator.add_payloads(
                records[begin : begin + length]
                for begin, length in zip(
                    starts[leftover].tolist(), lengths[leftover].tolist(), strict=True
                )
            )
        return seen


def summarize(
    bags: Iterable[str | Path],
    *,
    topics: Sequence[str] | None = None,
    fields: Sequence[str] | None = None,
    start_ns: int | None = None,
    end_ns: int | None = None,
    progress: ProgressCallback | None = None,
    bulk: bool = True,
) -> Summary:
    """Count, rate and exact statistics of every numeric field, pooled over ``bags``.

    Args:
        bags: bag directories or single ``.mcap``/``.db3`` files.
        topics: only these topics (all when None).
        fields: only fields matching one of these globs (``*``, ``?``; brackets literal).
        start_ns: only messages with ``log_time >= start_ns``.
        end_ns: only messages with ``log_time < end_ns``.
        progress: called with (messages done, messages in total).
        bulk: decode fixed-layout messages in bulk with numpy; False decodes every message
            with the general decoder (slower; to cross-check the bulk path).

    Raises:
        BagError: a bag cannot be opened (see ``bagkit.bag``).
        UnknownTopicError: a topic in ``topics`` is in none of the bags.
        NothingToSummarizeError: no message in the selection, or no topic can be decoded.
        StatsError: a topic has different types in different bags.
    """
    paths = [str(bag) for bag in bags]
    if not paths:
        raise StatsError("no bag given")
    run = _Run(MessageTypes(), field_matcher(fields), bool(fields), start_ns, end_ns, bulk)
    readers: list[BagReader] = []
    try:
        for path in paths:
            readers.append(BagReader(path, allow_empty=True))
        _check_topics({name for reader in readers for name in reader.topics}, topics)
        _accumulate(run, readers, topics, progress)
    finally:
        for reader in readers:
            reader.close()
    return _finish(run, paths)


def _accumulate(
    run: _Run,
    readers: list[BagReader],
    topics: Sequence[str] | None,
    progress: ProgressCallback | None,
) -> None:
    """Add the messages of ``readers`` on ``topics`` to ``run`` (also one bag of a fleet run)."""
    total = sum(
        count
        for reader in readers
        for topic, count in reader.topic_counts.items()
        if topics is None or topic in topics
    )
    done = 0
    for reader in readers:
        # Each bag is decoded with its own definitions (pooled bags must agree on them).
        run.types = MessageTypes.from_definitions(reader.definitions)
        wanted: dict[str, _TopicAccumulator] = {}
        for name, info in reader.topics.items():
            if topics is not None and name not in topics:
                continue
            accumulator = run.accumulator(
                name, info.type, info.serialization_format, str(reader.path)
            )
            if accumulator is not None:
                wanted[name] = accumulator
            else:  # skipped: its messages are not read
                total -= reader.topic_counts.get(name, 0)
        if not wanted:
            continue
        if reader.storage == "mcap":
            # closing(): the reading thread stops before the reader is closed, also on error.
            with closing(prefetch(reader.chunks(wanted))) as chunks:
                for chunk in chunks:
                    done += run.add_chunk(chunk, wanted)
                    if progress is not None:
                        progress(done, total)
        else:
            for message in reader.messages(wanted, run.start_ns, run.end_ns):
                accumulator = wanted[message.topic]
                accumulator.add_times(np.array([message.log_time]))
                if accumulator.leaves:
                    accumulator.add_payloads((message.data,))
                done += 1
                if progress is not None and done % ROW_BATCH == 0:
                    progress(done, total)
        run.problems.extend(reader.problems)
    if progress is not None:
        progress(total, total)


def _check_topics(known: set[str], topics: Sequence[str] | None) -> None:
    """Raise UnknownTopicError unless every topic of ``topics`` is among the ``known`` ones."""
    if topics is None:
        return
    missing = [topic for topic in topics if topic not in known]
    if missing:
        raise UnknownTopicError(
            f"topic {', '.join(missing)} not in the bag (it has {', '.join(sorted(known))})"
        )


def _finish(run: _Run, paths: list[str]) -> Summary:
    results = []
    for topic in sorted(run.accumulators):
        accumulator = run.accumulators[topic]
        if accumulator.failures:
            run.problems.append(
                f"{topic}: {accumulator.failures} messages could not be decoded "
                f"({accumulator.first_failure})"
            )
        if run.fields_given and not accumulator.leaves:
            continue
        results.append(accumulator.result())
    counted = [a for a in run.accumulators.values() if a.first_ns is not None]
    if not counted:
        bags = ", ".join(paths)
        if run.skipped and not run.accumulators:
            reasons = "; ".join(f"{t}: {why}" for t, why in sorted(run.skipped.items()))
            raise NothingToSummarizeError(f"no topic of {bags} can be decoded ({reasons})")
        windowed = run.start_ns is not None or run.end_ns is not None
        where = " in the selected time range" if windowed else ""
        raise NothingToSummarizeError(f"no messages to summarize in {bags}{where}")
    if run.fields_given and not results:
        raise NothingToSummarizeError("no numeric field matches --fields")
    return Summary(
        bags=tuple(paths),
        start_ns=min(a.first_ns for a in counted if a.first_ns is not None),
        end_ns=max(a.last_ns for a in counted if a.last_ns is not None),
        topics=tuple(results),
        skipped=dict(sorted(run.skipped.items())),
        problems=tuple(run.problems),
    )
