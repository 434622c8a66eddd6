"""``bagkit find``: the episodes where ``TOPIC: CONDITION`` holds, over many bags on Dask.

Each bag is searched by :func:`bagkit.data.episodes.find_episodes` (the same code in this
process and on a worker), so the Dask path gives what the in-process one gives; results come
back in the order of the bags. A bag without the topic has no episode; a bag that cannot be
read is reported and the others are searched.
"""

from __future__ import annotations

import functools
from collections.abc import Iterable
from dataclasses import asdict, dataclass, field
from pathlib import Path
from typing import TYPE_CHECKING, Any

import numpy as np

from bagkit.bag import BagError, BagReader
from bagkit.data.episodes import NO_SPANS, find_episodes
from bagkit.data.errors import could_have_lost
from bagkit.errors import not_read
from bagkit.fleet.errors import FleetError
from bagkit.fleet.execute import ItemDone, run_each
from bagkit.selection.conditions import parse_topic_condition
from bagkit.selection.errors import UnknownTopicError
from bagkit.selection.query import Query
from bagkit.selection.topics import absolute_topic_name, require_topics
from bagkit.storage.errors import StorageError
from bagkit.storage.urls import location, shown_as

if TYPE_CHECKING:
    import pyarrow as pa
    from distributed import Client

COLUMNS = ("bag", "topic", "start_ns", "end_ns", "count", "start_offset_s", "end_offset_s")
_NS_PER_MS = 1_000_000


def episode_offsets(start_ns: int, end_ns: int, bag_start_ns: int) -> tuple[float, float]:
    """An episode as seconds from its bag's start, in ms, widened to hold it: the start
    rounded down, the end (exclusive, after the last match) up. ``--start``/``--end`` of
    filter and golden add, and play's ``--start-offset``, take them as printed."""
    first = (start_ns - bag_start_ns) // _NS_PER_MS
    last = -(-(end_ns + 1 - bag_start_ns) // _NS_PER_MS)
    return first / 1000, last / 1000


@dataclass(frozen=True, slots=True)
class FoundEpisode:
    """One episode of one bag: first and last matching log time (ns), matches in it, and
    the log time of the bag's first message (for the offsets)."""

    bag: str
    topic: str
    start_ns: int
    end_ns: int
    count: int
    bag_start_ns: int = 0

    @property
    def offsets(self) -> tuple[float, float]:
        """Seconds from the bag's start, ms precision: :func:`episode_offsets`."""
        return episode_offsets(self.start_ns, self.end_ns, self.bag_start_ns)

    def to_dict(self) -> dict[str, Any]:
        found = asdict(self)
        del found["bag_start_ns"]
        found["start_offset_s"], found["end_offset_s"] = self.offsets
        return found


@dataclass(slots=True)
class BagEpisodes:
    """What one bag gave (sent from a worker): its episodes, or why it could not be read.

    ``spans``: one row ``(start_ns, end_ns, count)`` per episode
    (:func:`~bagkit.data.episodes.episode_spans`).
    """

    bag: str
    spans: np.ndarray = field(default_factory=NO_SPANS.copy)
    has_topic: bool = True
    topics: list[str] = field(default_factory=list)
    """The bag's topics, kept when it lacks the trigger's (for the did-you-mean)."""
    problems: list[str] = field(default_factory=list)
    error: str | None = None
    start_ns: int = 0
    """The log time of the bag's first message."""
    messages: int = 0
    """The topic's messages looked at (in the window)."""
    undecodable: int = 0
    """Those of them that did not decode (never matched)."""
    lost: list[str] = field(default_factory=list)
    """The parts of the bag that could not be read and could have held messages of the
    topic (:func:`~bagkit.data.errors.could_have_lost`; in ``problems`` too)."""


@dataclass(slots=True)
class FindResult:
    """The episodes of every bag, in bag order then time order, and what could not be read.

    Held as arrays (bags with episodes, and their :attr:`BagEpisodes.spans`): a fleet finds
    hundreds of thousands of episodes, most of which are written to Parquet, never looked at
    one by one.
    """

    topic: str
    parts: list[BagEpisodes]
    """The bags that have episodes, in bag order."""
    problems: list[str]
    unread: int = 0
    """Bags that could not be read at all."""
    messages: int = 0
    """The topic's messages looked at in every bag (in the window)."""
    undecodable: int = 0
    """Those of them that did not decode (never matched)."""
    lost: list[str] = field(default_factory=list)
    """The parts of the bags that could not be read (damaged chunks)."""

    @property
    def none_decoded(self) -> bool:
        """The topic had messages and none of them decoded, in any bag."""
        return 0 < self.messages == self.undecodable

    @property
    def nothing_read(self) -> bool:
        """No message of the topic was read in any bag, and parts of a bag were lost: "0
        episodes" would pass for "the condition never held"."""
        return not self.messages and bool(self.lost)

    @property
    def count(self) -> int:
        """How many episodes."""
        return sum(len(part.spans) for part in self.parts)

    @property
    def episodes(self) -> list[FoundEpisode]:
        """Every episode as an object (made on each call)."""
        return [
            FoundEpisode(part.bag, self.topic, start, end, count, part.start_ns)
            for part in self.parts
            for start, end, count in part.spans.tolist()
        ]

    def to_arrow(self) -> pa.Table:
        """One row per episode: ``bag``, ``topic``, ``start_ns``, ``end_ns``, ``count``,
        ``start_offset_s``, ``end_offset_s``."""
        import pyarrow as pa

        spans = np.concatenate([NO_SPANS, *(part.spans for part in self.parts)])
        repeats = [len(part.spans) for part in self.parts]
        bags = np.repeat(np.array([part.bag for part in self.parts], dtype=object), repeats)
        starts = np.repeat(np.array([p.start_ns for p in self.parts], dtype=np.int64), repeats)
        first = (spans[:, 0] - starts) // _NS_PER_MS
        last = -(-(spans[:, 1] + 1 - starts) // _NS_PER_MS)
        columns = [
            bags,
            np.full(len(spans), self.topic, dtype=object),
            *spans.T,
            first / 1000,
            last / 1000,
        ]
        types = [pa.string(), pa.string(), pa.int64(), pa.int64(), pa.int64()]
        types += [pa.float64(), pa.float64()]
        return pa.table(
            [pa.array(values, type=kind) for values, kind in zip(columns, types, strict=True)],
            names=list(COLUMNS),
        )


def episodes_in_bag(
    bag: str,
    *,
    when: str,
    gap_ns: int = 0,
    query: Query | None = None,
    state_topics: tuple[str, ...] = (),
) -> BagEpisodes:
    """The episodes of ``when`` (``TOPIC: CONDITION``) in one bag (what a worker runs), in
    ``query``'s window of it (the whole bag when None).

    Raises:
        UnknownFieldError, SelectionError: the condition does not fit the topic's type.
    """
    trigger = parse_topic_condition(when)
    path, bag = bag, shown_as(bag)  # opened in full, named without a URL's secrets
    try:
        with BagReader(path, allow_empty=True) as reader:
            resolved = (query or Query()).resolve(reader, label=bag)
            outside = resolved.outside
            try:
                found = find_episodes(reader, trigger, gap_ns, resolved.window, state_topics)
            except UnknownTopicError:
                return BagEpisodes(bag, has_topic=False, topics=list(reader.topics))
            lost = _labelled(bag, reader.problems) if could_have_lost(reader, trigger.topic) else []
    except (BagError, StorageError) as exc:
        return BagEpisodes(bag, error=str(exc))
    problems = _labelled(bag, found.problems)
    if outside is not None:
        problems.insert(0, outside)
    return BagEpisodes(
        bag,
        found.spans,
        problems=problems,
        start_ns=reader.start_ns,
        messages=found.messages,
        undecodable=found.undecodable,
        lost=lost,
    )


def _labelled(bag: str, problems: list[str]) -> list[str]:
    """``problems`` each naming ``bag`` (once)."""
    return [p if p.startswith(bag) else f"{bag}: {p}" for p in problems]


def find_fleet(
    bags: Iterable[str | Path],
    *,
    when: str,
    gap_ns: int = 0,
    query: Query | None = None,
    state_topics: tuple[str, ...] = (),
    client: Client | None = None,
    done: ItemDone | None = None,
) -> FindResult:
    """The episodes of ``when`` in every bag, on ``client``'s workers (here when None).

    Args:
        when: ``'TOPIC: CONDITION'`` (:func:`~bagkit.selection.conditions.parse_topic_condition`).
        gap_ns: matches less than this apart merge into one episode
            (:func:`~bagkit.data.episodes.episode_spans`).
        query: only messages in its window of each bag (seconds from its own start ...).
        state_topics: topics whose messages hold until the next one (besides transient-local
            ones, :func:`~bagkit.data.episodes.find_episodes`).
        done: called with the index of each bag once it is searched.

    Raises:
        SelectionError: ``when`` does not parse (before any bag is read), or its condition
            does not fit the topic's type; FleetError: no bag could be read, or none has
            the topic.
    """
    trigger = parse_topic_condition(when)
    paths = [location(bag) for bag in bags]
    state_topics = tuple(absolute_topic_name(t) for t in state_topics)
    task = functools.partial(
        episodes_in_bag, when=when, gap_ns=gap_ns, query=query, state_topics=state_topics
    )
    parts: list[BagEpisodes] = run_each(task, paths, client, done)
    readable = [part for part in parts if part.error is None]
    if not readable:
        raise FleetError(f"no bag could be read ({parts[0].error if parts else 'no bag given'})")
    if not any(part.has_topic for part in readable):
        known = {name for part in readable for name in part.topics}
        require_topics([trigger.topic], known, "the bag" if len(parts) == 1 else "any of the bags")
    problems: list[str] = []
    for part in parts:
        if part.error is not None:
            problems.append(not_read(part.bag, part.error))
        problems.extend(part.problems)
    found = [part for part in readable if len(part.spans)]
    return FindResult(
        trigger.topic,
        found,
        problems,
        len(parts) - len(readable),
        sum(part.messages for part in readable),
        sum(part.undecodable for part in readable),
        [problem for part in readable for problem in part.lost],
    )
