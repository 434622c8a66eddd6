"""The intervals of :mod:`bagkit.selection.temporal`, computed message by message (live).

Each node of a condition is a small state machine that knows its truth up to a time
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

import collections

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
from bagkit.selection.message_tests import Message, MessageTest
from bagkit.selection.temporal import OPERATORS

NEVER = -(2**62)


class _Node:
    """Truth known on ``(-inf, settled]``: ``closed`` intervals, and ``[since, settled]``."""

    def __init__(self) -> None:
        self.settled = NEVER
        self.since: int | None = None
        self.closed: list[tuple[int, int]] = []

    def push(self, time: int, message: Message) -> None:
        """A message of the topic, logged at ``time``."""

    def advance(self, now: int) -> None:
        """No message until ``now``."""

    def finish(self, end: int) -> None:
        """The stream ended at ``end``: everything is settled, nothing is open."""

    def source(self, topic: str, time: int, stamp: int) -> None:
        """A message of another topic (a latency's source) with its stamp."""

    def poll(self) -> None:
        """Bring ``settled``/``since``/``closed`` up to date (combinations)."""

    def _open(self, start: int) -> None:
        if self.since is None:
            self.since = start

    def _close(self, end: int) -> None:
        if self.since is not None:
            self.closed.append((self.since, end))
            self.since = None


class _Runs(_Node):
    """A per-message condition: runs of matching messages (on a state topic, each holding
    until the next message)."""

    def __init__(self, node: Expression, state: bool) -> None:
        super().__init__()
        self.test = MessageTest(node)
        self.state = state
        self.last: int | None = None

    def push(self, time: int, message: Message) -> None:
        hit = self.test(time, message)
        if self.state:
            if not hit:
                self._close(time)
            elif self.since is None:
                self.since = time
            self.settled = time
        else:
            if not hit and self.last is not None:
                self._close(self.last)
            if hit:
                self._open(time)
            self.settled = time
        self.last = time

    def advance(self, now: int) -> None:
        if self.state and self.last is not None:
            self.settled = max(self.settled, now)

    def source(self, topic: str, time: int, stamp: int) -> None:
        self.test.source(topic, time, stamp)

    def finish(self, end: int) -> None:
        self._close(end if self.state else (self.last if self.last is not None else end))
        self.settled = end


class _Gap(_Node):
    def __init__(self, gap: Gap, start: int) -> None:
        super().__init__()
        self.gap = gap
        self.compare = OPERATORS[gap.op]
        self.start = start
        self.last: int | None = None
        self.growing = gap.op in (">", ">=")  # a silence long enough is known while it lasts

    def push(self, time: int, message: Message) -> None:
        if self.last is not None:
            if self.compare(time - self.last, self.gap.ns):
                self._open(self.last)
            else:
                self._close(self.last)
        self.last = time
        self.settled = max(self.settled, time - 1)

    def advance(self, now: int) -> None:
        if self.last is not None and self.growing and self.compare(now - self.last, self.gap.ns):
            self._open(self.last)
            self.settled = max(self.settled, now)

    def finish(self, end: int) -> None:
        if self.last is None:
            if self.growing and self.compare(end - self.start, self.gap.ns):
                self.closed.append((self.start, end))
        elif self.growing and self.compare(end - self.last, self.gap.ns):
            self._open(self.last)
            self._close(end)
        else:
            self._close(self.last)
        self.settled = end


class _Unchanged(_Node):
    def __init__(self, node: Unchanged) -> None:
        super().__init__()
        self.path = node.path
        self.last: int | None = None
        self.previous: np.ndarray | None = None

    def push(self, time: int, message: Message) -> None:
        values = message.values(self.path)
        previous = self.previous
        same = (
            previous is not None
            and previous.shape == values.shape  # a sequence's length changed: not frozen
            and bool(((values == previous) | (np.isnan(values) & np.isnan(previous))).all())
        )
        if same:
            assert self.last is not None
            self._open(self.last)
        elif self.last is not None:
            self._close(self.last)
        self.settled = max(self.settled, time if same else time - 1)
        self.last, self.previous = time, values

    def finish(self, end: int) -> None:
        if self.last is not None:
            self._close(self.last)
        self.settled = end


class _Rate(_Node):
    """The windows ``[t - W, t]`` whose count satisfies the rate (see ``temporal``)."""

    def __init__(self, rate: Rate, start: int) -> None:
        super().__init__()
        self.compare = OPERATORS[rate.op]
        self.window = rate.window_ns
        self.threshold = rate.hz * rate.window_ns / 1e9
        self.first = start + rate.window_ns  # whole windows only
        # Counts above the threshold compare alike: keep no more log times than it takes.
        self.times: collections.deque[int] = collections.deque(
            maxlen=int(min(self.threshold, 2**31)) + 2
        )
        self.point = NEVER  # where the current count began
        self.reach: int | None = None  # the end of the windows in `since`

    def push(self, time: int, message: Message) -> None:
        self._exits(time)
        self._point(time)
        self.times.append(time)

    def advance(self, now: int) -> None:
        self._exits(now)
        self._segment(self.point, now - 1)  # the count holds until the next change at least
        self._settle(now - self.window - 1)

    def finish(self, end: int) -> None:
        self._exits(end)
        self._segment(self.point, end)
        if self.since is not None:
            assert self.reach is not None
            self._close(self.reach)
        self.settled = end

    def _exits(self, until: int) -> None:
        while self.times and self.times[0] + self.window <= until:
            self._point(self.times[0] + self.window, exit_=True)

    def _point(self, point: int, *, exit_: bool = False) -> None:
        if point > self.point:
            self._segment(self.point, point - 1)
            self.point = point
            self._settle(point - self.window - 1)
        if exit_:
            self.times.popleft()

    def _segment(self, first: int, last: int) -> None:
        first = max(first, self.first)
        if first > last or not self.compare(len(self.times), self.threshold):
            return
        start = first - self.window
        if self.since is not None and self.reach is not None and start <= self.reach + 1:
            self.reach = max(self.reach, last)
            return
        if self.since is not None and self.reach is not None:
            self._close(self.reach)
        self.since, self.reach = start, last

    def _settle(self, settled: int) -> None:
        if self.since is not None and self.reach is not None and self.reach < settled:
            self._close(self.reach)
        self.settled = max(self.settled, settled)


class _Parent(_Node):
    """A node over other nodes: what happens goes to them."""

    items: list[_Node]

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
    def __init__(self, item: _Node, ns: int) -> None:
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

    def __init__(self, kind: str, items: list[_Node], start: int) -> None:
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


def _build(node: Expression, start: int, state: bool) -> _Node:
    if is_per_message(node):
        return _Runs(node, state)
    if isinstance(node, For):
        return _For(_build(node.item, start, state), node.ns)
    if isinstance(node, Gap):
        return _Gap(node, start)
    if isinstance(node, Rate):
        return _Rate(node, start)
    if isinstance(node, Unchanged):
        return _Unchanged(node)
    assert isinstance(node, Node)
    return _Combine(node.kind, [_build(item, start, state) for item in node.items], start)
