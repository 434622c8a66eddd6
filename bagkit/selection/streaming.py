"""The intervals of :mod:`bagkit.selection.temporal`, computed message by message (live).

Each node of a condition is a small state machine (the terms on one topic's messages:
:mod:`~bagkit.selection.streaming_terms`) that knows its truth up to a time
(``settled``): final intervals before it (``closed``) and, maybe, one interval still going on
(``since``, holding through ``settled``). ``and``/``or``/``not`` combine their items over the
time all of them know, with the functions of :mod:`~bagkit.selection.intervals`, keeping only
what the episode in progress needs. A silence is known while it lasts (:meth:`advance`), so a
trigger on ``gap > 1s`` fires one second into a dropout, not when the sensor comes back.

Memory: a few values per term, ``rate`` at most ``R * W + 2`` log times, ``latency`` the
last :data:`~bagkit.selection.message_tests.LATENCY_STAMPS` stamps of its source topic,
``and``/``or``/``not`` the intervals of their items inside the episode in progress.
"""

from __future__ import annotations

import numpy as np

from bagkit.selection import intervals
from bagkit.selection.condition_terms import (
    Expression,
    For,
    Gap,
    Node,
    Rate,
    Unchanged,
    is_per_message,
)
from bagkit.selection.message_tests import Message
from bagkit.selection.streaming_terms import (
    GapTerm,
    RateTerm,
    RunsTerm,
    StreamNode,
    UnchangedTerm,
)


class _Parent(StreamNode):
    """A node over other nodes: what happens goes to them."""

    items: list[StreamNode]

    def push(self, time: int, message: Message) -> None:
        for item in self.items:
            item.push(time, message)

    def advance(self, now: int) -> None:
        for item in self.items:
            item.advance(now)

    def source(self, topic: str, time: int, stamp: int) -> None:
        for item in self.items:
            item.source(topic, time, stamp)

    def finish(self, end: int) -> None:
        for item in self.items:
            item.finish(end)
        self.poll()


class _For(_Parent):
    def __init__(self, item: StreamNode, ns: int) -> None:
        super().__init__()
        self.item = item
        self.items = [item]
        self.ns = ns

    def poll(self) -> None:
        item = self.item
        item.poll()
        self.closed.extend((s, e) for s, e in item.closed if e - s >= self.ns)
        item.closed.clear()
        if item.since is not None and item.settled - item.since < self.ns:
            self.since, self.settled = None, max(self.settled, item.since - 1)
        else:
            self.since, self.settled = item.since, item.settled


class _Combine(_Parent):
    """``and``/``or``/``not`` of items, over the time every item knows."""

    def __init__(self, kind: str, items: list[StreamNode], start: int) -> None:
        super().__init__()
        self.kind = kind
        self.items = items
        self.start = start
        self.low = start  # nothing before it matters any more
        self.held: list[list[tuple[int, int]]] = [[] for _ in items]

    def poll(self) -> None:
        for item, held in zip(self.items, self.held, strict=True):
            item.poll()
            held.extend(item.closed)
            item.closed.clear()
        settled = min(item.settled for item in self.items)
        if settled < self.low:
            return
        sets = []
        for item, held in zip(self.items, self.held, strict=True):
            spans = [(s, min(e, settled)) for s, e in held if e >= self.low and s <= settled]
            if item.since is not None and item.since <= settled:
                spans.append((item.since, settled))
            sets.append(
                intervals.intersect(
                    intervals.normal(np.array(spans, dtype=np.int64)),
                    np.array([[self.low, settled]], dtype=np.int64),
                )
            )
        if self.kind == "not":
            found = intervals.complement(sets[0], self.low, settled)
        elif self.kind == "or":
            found = intervals.union(*sets)
        else:
            found = sets[0]
            for other in sets[1:]:
                found = intervals.intersect(found, other)
        rows = found.tolist()
        self.since = None
        if rows and rows[-1][1] == settled:
            self.since = rows.pop()[0]
        self.closed.extend((s, e) for s, e in rows)
        self.settled = settled
        self.low = self.since if self.since is not None else settled + 1
        self.held = [[(s, e) for s, e in held if e >= self.low] for held in self.held]

    def finish(self, end: int) -> None:
        super().finish(end)
        self._close(end)


class StreamingCondition:
    """A condition over one topic's stream, fed message by message.

    Args:
        tree: the condition's tree (:attr:`bagkit.selection.conditions.Condition.tree`).
        start_ns: where the stream is looked at from (the recording's start).
        state: a state topic (each message holds until the next).
        keep: keep the episodes that ended (:attr:`episodes`; a recorder only counts them).
    """

    def __init__(
        self, tree: Expression, start_ns: int, *, state: bool = False, keep: bool = True
    ) -> None:
        self.root = _build(tree, start_ns, state)
        self.keep = keep
        self.episodes: list[tuple[int, int]] = []
        """Every episode that has ended, in time order."""
        self._reported: int | None = None  # the start of the last episode told of
        self._new = 0

    @property
    def since(self) -> int | None:
        """Where the episode going on began, if one is."""
        return self.root.since

    def push(self, time: int, message: Message) -> None:
        """A message of the topic, logged at ``time`` (ascending)."""
        self.root.push(time, message)
        self._poll()

    def source(self, topic: str, time: int, stamp: int) -> None:
        """A message of a latency's source topic, with its stamp (ns)."""
        self.root.source(topic, time, stamp)

    def advance(self, now: int) -> None:
        """No message of the topic until ``now`` (a silence is known while it lasts)."""
        self.root.advance(now)
        self._poll()

    def finish(self, end: int) -> list[tuple[int, int]]:
        """The stream ended at ``end``: every episode (they are all closed)."""
        self.root.finish(end)
        self._poll()
        return self.episodes

    def take_new(self) -> int:
        """How many episodes became known (began, or began and ended) since the last call."""
        new, self._new = self._new, 0
        return new

    def _poll(self) -> None:
        root = self.root
        root.poll()
        for start, _ in root.closed:
            if start != self._reported:
                self._new += 1
                self._reported = start
        if root.since is not None and root.since != self._reported:
            self._new += 1
            self._reported = root.since
        if self.keep:
            self.episodes.extend(root.closed)
        root.closed.clear()


def _build(node: Expression, start: int, state: bool) -> StreamNode:
    if is_per_message(node):
        return RunsTerm(node, state)
    if isinstance(node, For):
        return _For(_build(node.item, start, state), node.ns)
    if isinstance(node, Gap):
        return GapTerm(node, start)
    if isinstance(node, Rate):
        return RateTerm(node, start)
    if isinstance(node, Unchanged):
        return UnchangedTerm(node)
    assert isinstance(node, Node)
    return _Combine(node.kind, [_build(item, start, state) for item in node.items], start)
