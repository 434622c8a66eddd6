"""Where a condition holds over a topic's stream, as intervals, computed over numpy columns.

Every term means a set of closed log-time intervals (:mod:`bagkit.selection.intervals`):

- a per-message condition: the runs of consecutive messages satisfying it, from the first
  to the last (on a state topic to the next message, which changes the state, or the end);
- ``gap OP D``: each silence between consecutive messages whose length satisfies it, from the
  message before to the one after; with ``>``/``>=`` also the silence after the last message
  up to the end;
- ``rate OP R Hz over W``: the windows ``[t - W, t]`` whose message count ``c`` (messages in
  ``(t - W, t]``) satisfies ``c OP R * W``; only whole windows (``t >= start + W``) count;
- ``unchanged(f)``: each run of two or more consecutive messages with equal ``f``;
- ``X for D``: the intervals of X lasting at least D; ``and``/``or``/``not``: intersection,
  union, complement within the time looked at.

:mod:`bagkit.selection.streaming` computes the same incrementally (the live recorder).
"""

from __future__ import annotations

import operator
from collections.abc import Callable
from dataclasses import dataclass
from typing import Any, Protocol

import numpy as np

from bagkit.selection import intervals
from bagkit.selection.condition_terms import (
    Age,
    Delta,
    Expression,
    For,
    Gap,
    Latency,
    Node,
    Path,
    Rate,
    Unchanged,
    is_per_message,
    is_stateless,
)
from bagkit.selection.errors import SelectionError

OPERATORS: dict[str, Callable[[Any, Any], Any]] = {
    "==": operator.eq,
    "!=": operator.ne,
    "<=": operator.le,
    ">=": operator.ge,
    "<": operator.lt,
    ">": operator.gt,
}


class StreamData(Protocol):
    """What the evaluator reads of one topic (a bag's, or a table of test cases)."""

    log_times: np.ndarray
    """int64 ns, ascending: the messages the columns hold."""

    arrival_times: np.ndarray
    """int64 ns, ascending: every message, also those that did not decode (what ``gap`` and
    ``rate`` count: such a message still arrived)."""

    def mask(self, node: Expression) -> np.ndarray:
        """Which messages satisfy a stateless condition (:func:`is_stateless`)."""

    def values(self, path: Path | None) -> np.ndarray:
        """float64 (messages, leaves) of the numeric leaves ``path`` reads (None: all)."""

    def source(self, topic: str, path: Path) -> tuple[np.ndarray, np.ndarray]:
        """Another topic's log times and its stamps at ``path`` (ns), for ``latency``."""


@dataclass(frozen=True, slots=True)
class Scope:
    """Where a condition is evaluated: the topic, the time looked at, whether a state topic."""

    topic: str
    start_ns: int
    end_ns: int
    state: bool = False


def evaluate(node: Expression, data: StreamData, scope: Scope) -> np.ndarray:
    """The intervals where ``node`` holds (a normal set, see :mod:`~.intervals`).

    Raises:
        SelectionError: a term that does not fit the topic (latency of another topic).
    """
    times = data.log_times
    if is_per_message(node):
        until = None
        if scope.state:  # each message's state holds until the next one (or the end)
            until = np.concatenate((times[1:], [scope.end_ns])) if len(times) else times
        return intervals.runs(times, message_mask(node, data, scope), until)
    if isinstance(node, For):
        return intervals.lasting(evaluate(node.item, data, scope), node.ns)
    if isinstance(node, Gap):
        return gap_intervals(data.arrival_times, node, scope.start_ns, scope.end_ns)
    if isinstance(node, Rate):
        return rate_intervals(data.arrival_times, node, scope.start_ns, scope.end_ns)
    if isinstance(node, Unchanged):
        values = data.values(node.path)
        same = equal_rows(values[1:], values[:-1])
        return intervals.runs(times[:-1], same, times[1:]) if len(times) else intervals.NONE.copy()
    assert isinstance(node, Node)
    parts = [evaluate(item, data, scope) for item in node.items]
    if node.kind == "not":
        return intervals.complement(parts[0], scope.start_ns, scope.end_ns)
    if node.kind == "or":
        return intervals.union(*parts)
    result = parts[0]
    for part in parts[1:]:
        result = intervals.intersect(result, part)
    return result


def message_mask(node: Expression, data: StreamData, scope: Scope) -> np.ndarray:
    """Which messages satisfy a per-message condition (:func:`is_per_message`)."""
    if is_stateless(node):
        return np.asarray(data.mask(node), dtype=bool)
    if isinstance(node, Node):
        masks = [message_mask(item, data, scope) for item in node.items]
        if node.kind == "not":
            return ~masks[0]
        return (np.logical_or if node.kind == "or" else np.logical_and).reduce(masks)
    compare = OPERATORS[node.op]  # type: ignore[union-attr]
    times = data.log_times
    if isinstance(node, Delta):
        values = data.values(node.path)
        hit = np.zeros(len(times), dtype=bool)
        with np.errstate(invalid="ignore"):
            hit[1:] = compare(np.abs(values[1:] - values[:-1]), node.value).any(axis=1)
        return hit
    if isinstance(node, Age):
        return np.asarray(compare(times - stamps(data.values(node.path)), node.ns), dtype=bool)
    assert isinstance(node, Latency)
    if node.target != scope.topic:
        raise SelectionError(
            f"latency({node.source} -> {node.target}, ...) is a condition on {node.target}, "
            f"not on {scope.topic}"
        )
    latency = latencies(times, stamps(data.values(node.path)), *data.source(node.source, node.path))
    with np.errstate(invalid="ignore"):
        return np.asarray(compare(latency, node.ns), dtype=bool) & (latency >= 0)


def stamps(values: np.ndarray) -> np.ndarray:
    """ns of Time columns ``(sec, nanosec)``.

    Raises:
        SelectionError: the path is not a Time (two leaves, sec and nanosec).
    """
    if values.ndim != 2 or values.shape[1] != 2:
        raise SelectionError("age() and latency() read a stamp (builtin_interfaces/Time)")
    return values[:, 0].astype(np.int64) * 1_000_000_000 + values[:, 1].astype(np.int64)


def latencies(
    times: np.ndarray,
    target_stamps: np.ndarray,
    source_times: np.ndarray,
    source_stamps: np.ndarray,
) -> np.ndarray:
    """Each target message's log time minus that of the first source message with its stamp
    (-1 where no source message has it)."""
    order = np.argsort(source_stamps, kind="stable")
    ordered = source_stamps[order]
    at = np.searchsorted(ordered, target_stamps)
    found = at < len(ordered)
    found[found] = ordered[at[found]] == target_stamps[found]
    out = np.full(len(times), -1, dtype=np.int64)
    out[found] = times[found] - source_times[order[at[found]]]
    return out


def equal_rows(a: np.ndarray, b: np.ndarray) -> np.ndarray:
    """Whether each row of ``a`` equals that of ``b`` in every column (NaN equals NaN)."""
    return ((a == b) | (np.isnan(a) & np.isnan(b))).all(axis=1)


def gap_intervals(times: np.ndarray, gap: Gap, start: int, end: int) -> np.ndarray:
    """The silences satisfying ``gap``, message before to message after (or the end)."""
    compare = OPERATORS[gap.op]
    if not len(times):
        whole = np.array([[start, end]], dtype=np.int64)
        return whole if gap.op in (">", ">=") and compare(end - start, gap.ns) else intervals.NONE
    hit = np.flatnonzero(compare(np.diff(times), gap.ns))
    spans = [np.stack([times[hit], times[hit + 1]], axis=1)]
    if gap.op in (">", ">=") and compare(end - int(times[-1]), gap.ns):
        spans.append(np.array([[times[-1], end]], dtype=np.int64))
    return intervals.union(*spans)


def rate_intervals(times: np.ndarray, rate: Rate, start: int, end: int) -> np.ndarray:
    """The windows ``[t - W, t]`` (``t`` in ``[start + W, end]``) whose count satisfies ``rate``."""
    window = rate.window_ns
    points, counts = window_counts(times, window)
    # Segment k is [points[k], points[k + 1] - 1] with counts[k] messages in its windows;
    # before the first point no message is in the window.
    seg_starts = np.concatenate(([start + window], points))
    seg_ends = np.concatenate((points - 1, [end]))
    seg_counts = np.concatenate(([0], counts))
    seg_starts = np.maximum(seg_starts, start + window)
    seg_ends = np.minimum(seg_ends, end)
    hit = OPERATORS[rate.op](seg_counts, rate.hz * window / 1e9) & (seg_starts <= seg_ends)
    return intervals.normal(np.stack([seg_starts[hit] - window, seg_ends[hit]], axis=1))


def window_counts(times: np.ndarray, window: int) -> tuple[np.ndarray, np.ndarray]:
    """Where the count of messages in ``(t - window, t]`` changes, and the count from there.

    A message at ``t_i`` counts from ``t_i`` until ``t_i + window``.
    """
    # Both halves are sorted: merged by position (as a stable sort of the two would order
    # them, arrivals before departures at equal times) rather than by sorting 2n events.
    # Departures saturate at int64's end (a bag's times are untrusted): past any bag's end.
    ends = np.minimum(times, np.iinfo(np.int64).max - window) + window
    n = len(times)
    events = np.empty(2 * n, np.int64)
    steps = np.empty(2 * n, np.int64)
    arrive = np.arange(n) + np.searchsorted(ends, times, side="left")
    depart = np.arange(n) + np.searchsorted(times, ends, side="right")
    events[arrive], events[depart] = times, ends
    steps[arrive], steps[depart] = 1, -1
    totals = np.cumsum(steps)
    last = np.concatenate((events[1:] != events[:-1], [True])) if len(events) else events
    return events[last], totals[last]
