"""A topic of a bag read for a condition over time: log times and the columns its terms read.

The columns are decoded in bulk (:class:`bagkit.data.scan.Scan`) and the condition is
evaluated over them by :func:`bagkit.selection.temporal.evaluate`. A topic is a *state topic*
(each message's value holds until the next one) when its publishers offered transient-local
durability (latched), or when named in ``state_topics``.
"""

from __future__ import annotations

from collections.abc import Sequence
from typing import NamedTuple

import numpy as np

from bagkit.bag import BagReader
from bagkit.data.columns import TopicColumns
from bagkit.data.errors import DataError, UndecodableTopicError
from bagkit.data.matching import match_topic
from bagkit.data.scan import Scan
from bagkit.decode import DecodeError, LeafField, MessageTypes, leaf_fields
from bagkit.selection import intervals
from bagkit.selection.condition_terms import (
    Expression,
    For,
    Node,
    Path,
    is_stateless,
    path_text,
)
from bagkit.selection.conditions import Condition, subtree_leaves
from bagkit.selection.errors import SelectionError, UnknownFieldError
from bagkit.selection.temporal import Scope, evaluate
from bagkit.selection.topics import require_topics
from bagkit.selection.windows import Window
from bagkit.words import counted


class BagStream:
    """One topic of an open bag, as :class:`bagkit.selection.temporal.StreamData`.

    Raises:
        UnknownTopicError, UnknownFieldError, UndecodableTopicError.
    """

    def __init__(
        self, reader: BagReader, topic: str, conditions: Sequence[Condition], window: Window
    ) -> None:
        self.reader = reader
        self.topic = topic
        self.window = window
        self.types = MessageTypes.for_bag(reader)
        condition = Condition(
            " or ".join(f"({c.text})" for c in conditions),
            Node("or", tuple(c.tree for c in conditions)),
        )
        self.condition = condition
        # Each condition is evaluated on its own: the columns are those its own stateless parts
        # read in bulk (all of them together may need a sequence, and so none).
        parts = [part for c in conditions for part in _stateless_parts(c.tree)]
        # Only times (gap, rate): nothing is decoded, so no definition is needed.
        timing = all(not c.comparisons() and not c.paths() for c in conditions)
        paths = [] if timing else self._leaf_paths(topic)
        condition.check_fields(topic, paths)
        wanted: list[str] = []
        for subtree in parts:
            reads = Condition(condition.text, subtree).bulk_columns(paths)
            if reads is not None:
                wanted.extend(name for names in reads.values() for name in names)
        for path in condition.paths():
            wanted.extend(_numeric(self._numeric_paths(topic), subtree_leaves(path, paths)))
        self._paths = paths
        self.problems: list[str] = []
        self.log_times, self._columns, self.undecodable = self._read(topic, sorted(set(wanted)))
        """Its messages that did not decode (not in the log times)."""
        self.arrival_times = self._arrivals(topic) if self.undecodable else self.log_times

    def _leaf_paths(self, topic: str) -> list[str]:
        return [leaf.path for leaf in self._leaves(topic)]

    def _leaves(self, topic: str) -> list[LeafField]:
        info = self.reader.topics[topic]
        try:
            if info.serialization_format != "cdr":  # as echo refuses it
                raise DecodeError(f"serialization format {info.serialization_format!r} is not CDR")
            types = self.types.for_topic(topic)
            return leaf_fields(types.typestore, types.resolve(info.type))
        except DecodeError as exc:
            raise UndecodableTopicError(f"{topic} cannot be decoded: {exc}") from None

    def _numeric_paths(self, topic: str) -> set[str]:
        return {
            leaf.path
            for leaf in self._leaves(topic)
            if not leaf.pooled and leaf.base not in ("string", "wstring")
        }

    def _read(self, topic: str, names: list[str]) -> tuple[np.ndarray, dict[str, np.ndarray], int]:
        """Log times and columns of the messages that decoded, and how many did not."""
        if not names:  # only log times (gap, rate): no message decoded
            return self._arrivals(topic), {}, 0
        leaves = [leaf for leaf in self._leaves(topic) if leaf.path in names]
        info = self.reader.topics[topic]
        columns = TopicColumns(self.types.for_topic(topic), topic, info.type, leaves)
        scan = Scan(self.reader, self.window, {topic: columns})
        arrays = scan.table(topic).columns()
        self.problems.extend(scan_problems(columns))
        values = {leaf.path: a for leaf, a in zip(leaves, arrays[2:], strict=True)}
        return arrays[0], values, columns.undecodable

    def _arrivals(self, topic: str) -> np.ndarray:
        """Every message's log time in the window, decoded or not."""
        start, end = self.window.start_ns, self.window.end_ns
        times = self.reader.index_log_times(topic, start, end)
        if times is not None:
            return times
        found = (m.log_time for m in self.reader.messages([topic], start, end))
        return np.fromiter(found, np.int64)

    def mask(self, node: Expression) -> np.ndarray:
        """Which messages satisfy a stateless part of the condition."""
        condition = Condition(self.condition.text, node)
        reads = condition.bulk_columns(self._paths)
        if reads is not None:
            with np.errstate(over="ignore", invalid="ignore"):
                return condition.mask(self._columns, reads)
        matches = match_topic(self.reader, self.topic, condition, self.window)
        if len(matches.log_times) != len(self.log_times):
            raise DataError(f"{self.topic}: messages that do not decode: cannot follow the stream")
        return matches.matched

    def values(self, path: Path | None) -> np.ndarray:
        """The numeric leaves at or below ``path`` as float64 (messages, leaves)."""
        below = subtree_leaves(path, self._paths)
        names = _numeric(self._numeric_paths(self.topic), below)
        if not names:
            if any("[]" in name for name in below):  # a message's values, not one per message
                raise SelectionError(
                    f"{path_text(path)} of {self.topic} is in a sequence: delta, unchanged and "
                    "age compare fields that each message has once"
                )
            raise SelectionError(f"{path_text(path)} of {self.topic} holds no number")
        return np.stack([self._columns[n].astype(np.float64) for n in names], axis=1)

    def source(self, topic: str, path: Path) -> tuple[np.ndarray, np.ndarray]:
        """Another topic's log times and stamps at ``path`` (latency)."""
        from bagkit.selection.temporal import stamps

        (topic,) = require_topics([topic], self.reader.topics)
        names = _numeric(self._numeric_paths(topic), subtree_leaves(path, self._leaf_paths(topic)))
        if not names:
            raise UnknownFieldError(f"no field {path_text(path)!r} in {topic}")
        times, columns, _ = self._read(topic, names)
        values = np.stack([columns[n].astype(np.float64) for n in names], axis=1)
        return times, stamps(values)


class IntervalFilter:
    """The messages of a topic inside the intervals where a condition over time holds (a
    :class:`bagkit.surgery.select.PayloadFilter` for ``filter --where``)."""

    problem: str | None = None

    def __init__(self, spans: np.ndarray) -> None:
        self.spans = spans

    def mask_records(
        self,
        records: bytes,
        starts: np.ndarray,
        lengths: np.ndarray,
        log_times: np.ndarray | None = None,
    ) -> np.ndarray:
        """Whether each message's log time is inside an interval."""
        assert log_times is not None  # the copy passes them
        return intervals.contains(self.spans, log_times)


def scan_problems(columns: TopicColumns) -> list[str]:
    """What a scan of one topic could not read."""
    found = []
    if columns.failures:
        found.append(
            f"{columns.topic}: {counted(columns.failures, 'message')} could not be decoded"
        )
    if columns.unindexed:
        found.append(
            f"{columns.topic}: {columns.unindexed} index entries point outside their chunk"
        )
    return found


class TopicIntervals(NamedTuple):
    """Where a condition over time holds over a topic (:func:`temporal_intervals`)."""

    found: np.ndarray
    """The intervals (:mod:`bagkit.selection.intervals`)."""
    log_times: np.ndarray
    """The log times of the topic's messages that decoded."""
    problems: list[str]
    """What could not be read, one line each."""
    undecodable: int
    """The topic's messages that did not decode."""


def temporal_intervals(
    reader: BagReader,
    topic: str,
    condition: Condition,
    window: Window,
    state: bool = False,
) -> TopicIntervals:
    """Where ``condition`` holds over ``topic`` in ``window`` of an open bag.

    Raises:
        UnknownTopicError, UnknownFieldError, UndecodableTopicError, SelectionError.
    """
    (found,), stream = _evaluate(reader, topic, [condition], window, state)
    problems = [*reader.problems, *stream.problems]
    return TopicIntervals(found, stream.log_times, problems, stream.undecodable)


def intervals_of_each(
    reader: BagReader,
    topic: str,
    conditions: Sequence[Condition],
    window: Window,
    state: bool = False,
) -> tuple[list[np.ndarray], list[np.ndarray], list[str]]:
    """:func:`temporal_intervals` of several conditions over one topic, its columns read once
    (what ``bagkit check`` evaluates for each topic of a contract): each condition's intervals
    and the log times it was evaluated over. Those that read no field (``gap``, ``rate``) are
    evaluated over every message: one that does not decode still arrived, and is no gap.

    Raises:
        UnknownTopicError, UnknownFieldError, UndecodableTopicError, SelectionError.
    """
    timing = [i for i, c in enumerate(conditions) if not c.comparisons() and not c.paths()]
    groups = [timing, [i for i in range(len(conditions)) if i not in timing]]
    found: list[np.ndarray] = [intervals.NONE] * len(conditions)
    times: list[np.ndarray] = [np.empty(0, np.int64)] * len(conditions)
    problems = list(reader.problems)
    for group in (g for g in groups if g):
        each, stream = _evaluate(reader, topic, [conditions[i] for i in group], window, state)
        for i, where in zip(group, each, strict=True):
            found[i], times[i] = where, stream.log_times
        problems.extend(p for p in stream.problems if p not in problems)
    return found, times, problems


def _evaluate(
    reader: BagReader,
    topic: str,
    conditions: Sequence[Condition],
    window: Window,
    state: bool,
) -> tuple[list[np.ndarray], BagStream]:
    """The intervals of each condition, and the stream they were evaluated over."""
    (topic,) = require_topics([topic], reader.topics)
    stream = BagStream(reader, topic, conditions, window)
    start = max(window.start_ns or reader.start_ns, reader.start_ns)
    end = min(window.end_ns - 1 if window.end_ns is not None else reader.end_ns, reader.end_ns)
    scope = Scope(topic, start, max(start, end), state)
    found = [
        evaluate(c.tree, stream, scope) if reader.message_count else intervals.NONE
        for c in conditions
    ]
    return found, stream


def _stateless_parts(tree: Expression) -> list[Expression]:
    """The largest stateless parts of ``tree`` (evaluated as masks over columns)."""
    if is_stateless(tree):
        return [tree]
    if isinstance(tree, Node):
        return [part for item in tree.items for part in _stateless_parts(item)]
    if isinstance(tree, For):
        return _stateless_parts(tree.item)
    return []


def _numeric(numeric: set[str], names: list[str]) -> list[str]:
    return [name for name in names if name in numeric]
