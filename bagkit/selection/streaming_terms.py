"""The terms of a streaming condition (:mod:`~bagkit.selection.streaming`) that watch one
topic's messages: each a small state machine that knows its truth up to a time (``settled``),
final intervals before it (``closed``) and, maybe, one still going on (``since``): runs of a
per-message test, ``gap``, ``unchanged`` and ``rate``."""

from __future__ import annotations

import collections

import numpy as np

from bagkit.selection.condition_terms import (
    Expression,
    Gap,
    Rate,
    Unchanged,
)
from bagkit.selection.message_tests import Message, MessageTest
from bagkit.selection.temporal import OPERATORS

NEVER = -(2**62)


class StreamNode:
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


class RunsTerm(StreamNode):
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


class GapTerm(StreamNode):
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


class UnchangedTerm(StreamNode):
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


class RateTerm(StreamNode):
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
