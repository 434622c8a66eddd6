"""Episodes: where a condition holds over a topic's messages, as (start, end, count) spans.

An episode is a run of consecutive messages of the topic that match (log-time order); runs
separated by less than ``gap_ns`` (from the last match of one to the first of the next) merge
into one, whatever did not match between them. ``start_ns``/``end_ns`` are the log times of
the first and last matching message, ``count`` the matches in it. On a state topic (latched,
or named) a run lasts until the next message, which changes the state (or the end). A condition
over time (``gap > 1s``) has the episodes of :mod:`bagkit.selection.temporal`, ``count`` the
topic's messages in each. ``bagkit find`` lists them, ``bagkit filter --around`` cuts a bag
around each.
"""

from __future__ import annotations

from collections.abc import Collection, Sequence
from dataclasses import dataclass, field

import numpy as np

from bagkit.bag import BagReader
from bagkit.bag.latched import is_state_topic
from bagkit.data.matching import match_topic
from bagkit.selection import intervals
from bagkit.selection.conditions import TopicCondition
from bagkit.selection.windows import Window


@dataclass(frozen=True, slots=True)
class Episode:
    """Where a condition held: first and last matching log time (ns), matches in between."""

    start_ns: int
    end_ns: int
    count: int


NO_SPANS = np.zeros((0, 3), dtype=np.int64)
"""No episode, as :func:`episode_spans` gives it (copy before changing)."""


@dataclass
class Episodes:
    """The episodes of one topic condition in one bag, and what could not be matched.

    Attributes:
        topic: the topic.
        spans: one row per episode in time order: first and last matching log time (ns),
            matches (int64, shape (n, 3); see :func:`episode_spans`).
        messages: messages of the topic looked at.
        undecodable: those that did not decode (counted, never matched).
        problems: what could not be read, one line each.
    """

    topic: str
    spans: np.ndarray
    messages: int = 0
    undecodable: int = 0
    problems: list[str] = field(default_factory=list)

    @property
    def episodes(self) -> list[Episode]:
        """The episodes in time order."""
        return as_episodes(self.spans)


def episode_spans(log_times: np.ndarray, matched: np.ndarray, gap_ns: int = 0) -> np.ndarray:
    """The episodes of a topic's messages as rows ``(start_ns, end_ns, count)`` (pure).

    Arrays, not objects: a fleet task sends its bag's thousands of episodes back to the
    driver, and unpickling one dataclass per episode took CPU the workers needed
    (benchmarks/README.md, find on 2 workers).

    Args:
        log_times: every message's log time (ns), ascending.
        matched: whether each matched (bool, same length).
        gap_ns: runs of matches less than this apart (last of one to first of the next)
            merge into one episode; 0 keeps every run apart.

    Returns:
        int64, shape (episodes, 3), in time order.
    """
    flags = np.concatenate(([False], np.asarray(matched, dtype=bool), [False]))
    edges = np.diff(flags.astype(np.int8))
    firsts = np.flatnonzero(edges == 1)  # index of each run's first message
    lasts = np.flatnonzero(edges == -1) - 1  # and of its last
    if not len(firsts):
        return NO_SPANS.copy()
    times = np.asarray(log_times, dtype=np.int64)
    # A run opens a new episode unless it starts within gap_ns of the previous run's end.
    apart = times[firsts[1:]] - times[lasts[:-1]] >= gap_ns
    opens = np.concatenate(([0], np.flatnonzero(apart) + 1))
    closes = np.concatenate((opens[1:] - 1, [len(firsts) - 1]))
    before = np.concatenate(([0], np.cumsum(lasts - firsts + 1)))
    return np.stack(
        [times[firsts[opens]], times[lasts[closes]], before[closes + 1] - before[opens]], axis=1
    ).astype(np.int64, copy=False)


def interval_spans(
    found: np.ndarray, log_times: np.ndarray, counted: np.ndarray | None = None, gap_ns: int = 0
) -> np.ndarray:
    """Intervals (:mod:`~bagkit.selection.intervals`) as rows ``(start_ns, end_ns, count)``:
    those less than ``gap_ns`` apart merged, ``count`` the messages in each (those of
    ``counted`` only, when given)."""
    if not len(found):
        return NO_SPANS.copy()
    apart = found[1:, 0] - found[:-1, 1] >= gap_ns
    opens = np.concatenate(([0], np.flatnonzero(apart) + 1))
    closes = np.concatenate((opens[1:] - 1, [len(found) - 1]))
    starts, ends = found[opens, 0], found[closes, 1]
    weights = np.ones(len(log_times), np.int64) if counted is None else counted.astype(np.int64)
    before = np.concatenate(([0], np.cumsum(weights)))
    counts = (
        before[np.searchsorted(log_times, ends, side="right")]
        - before[np.searchsorted(log_times, starts, side="left")]
    )
    return np.stack([starts, ends, counts], axis=1).astype(np.int64, copy=False)


def as_episodes(spans: np.ndarray) -> list[Episode]:
    """The rows of :func:`episode_spans` as Episodes."""
    return [Episode(start, end, count) for start, end, count in spans.tolist()]


def find_episodes(
    reader: BagReader,
    trigger: TopicCondition,
    gap_ns: int = 0,
    window: Window | None = None,
    state_topics: Collection[str] = (),
) -> Episodes:
    """The episodes of ``trigger`` (``TOPIC: CONDITION``) in an open bag.

    Fixed-layout topics are matched in bulk with numpy, others message by message
    (:mod:`bagkit.data.matching`).

    Args:
        reader: the open bag.
        trigger: the topic and the condition on its messages.
        gap_ns: see :func:`episode_spans`.
        window: only messages in it (the whole bag when None).
        state_topics: topics whose messages hold until the next one (besides latched ones).

    Raises:
        UnknownTopicError, UnknownFieldError, UndecodableTopicError; SelectionError when a
        value cannot be compared with its field.
    """
    window = window or Window()
    if trigger.condition.temporal:
        # Bulk columns (pyarrow): only for a condition over time, not at every find's start.
        from bagkit.data.streams import temporal_intervals

        held = temporal_intervals(
            reader,
            trigger.topic,
            trigger.condition,
            window,
            trigger.topic in reader.topics and is_state_topic(reader, trigger.topic, state_topics),
        )
        return Episodes(
            trigger.topic,
            interval_spans(held.found, held.log_times, None, gap_ns),
            len(held.log_times) + held.undecodable,
            held.undecodable,
            held.problems,
        )
    matches = match_topic(reader, trigger.topic, trigger.condition, window)
    if is_state_topic(reader, matches.topic, state_topics):
        times = matches.log_times
        end = reader.end_ns if window.end_ns is None else min(window.end_ns - 1, reader.end_ns)
        until = np.concatenate((times[1:], [max(end, times[-1])])) if len(times) else times
        found = intervals.runs(times, matches.matched, until)
        return Episodes(
            matches.topic,
            interval_spans(found, times, matches.matched, gap_ns),
            len(times),
            matches.undecodable,
            matches.problems,
        )
    return Episodes(
        matches.topic,
        episode_spans(matches.log_times, matches.matched, gap_ns),
        len(matches.log_times),
        matches.undecodable,
        matches.problems,
    )


def episode_windows(episodes: Sequence[Episode], before_ns: int, after_ns: int) -> list[Window]:
    """The window around each episode: from ``before_ns`` before its first match to
    ``after_ns`` after its last, that one included (``[start - before, end + after + 1)``)."""
    return [Window(max(e.start_ns - before_ns, 0), e.end_ns + after_ns + 1) for e in episodes]
