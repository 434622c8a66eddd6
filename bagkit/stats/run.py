"""A summary's run: its state across the bags, each bag's messages read into the topics'
:class:`~bagkit.stats.accumulate.TopicAccumulator` one chunk at a time (in this process for
:func:`~bagkit.stats.summary.summarize`, on a fleet worker for :mod:`bagkit.fleet.stats`)."""

from __future__ import annotations

from collections.abc import Callable, Sequence
from contextlib import closing
from dataclasses import dataclass, field
from pathlib import Path
from typing import TYPE_CHECKING

from bagkit.bag import BagChunk, BagReader
from bagkit.decode import DecodeError, MessageTypes, leaf_fields
from bagkit.decode.layout import CdrLayout
from bagkit.prefetch import prefetch
from bagkit.selection.errors import UnknownFieldError
from bagkit.selection.fields import FieldSelection
from bagkit.selection.query import Query
from bagkit.selection.topics import absolute_topic_name
from bagkit.selection.windows import TimeRange, Window, outside_warning
from bagkit.stats.accumulate import TopicAccumulator
from bagkit.stats.errors import StatsError

if TYPE_CHECKING:
    from bagkit.decode.matcher import PayloadMatcher
    from bagkit.selection.conditions import Condition

ProgressCallback = Callable[[int, int], None]
"""Called with (messages done, messages in total) as the summary advances."""


@dataclass(slots=True)
class SummaryRun:
    """The state of one summary across its bags: what :func:`~bagkit.stats.summary.summarize`
    runs in this process, and a fleet worker on its bag (:mod:`bagkit.fleet.stats`).

    ``prefetch`` reads and decompresses the next chunk in a thread beside the numpy work on
    the current one: a second core for one process; a worker of a cluster, whose cores are the
    other workers', runs without it.
    """

    types: MessageTypes
    fields: FieldSelection
    span: TimeRange
    bulk: bool
    progress: ProgressCallback | None
    prefetch: bool = True
    where: Condition | None = None
    """Only messages satisfying it; topics whose type lacks its fields are left out (an
    error when the one topic asked for lacks them)."""

    @classmethod
    def of(
        cls,
        query: Query,
        *,
        bulk: bool = True,
        progress: ProgressCallback | None = None,
        prefetch: bool = True,
    ) -> SummaryRun:
        """A run of ``query``'s fields, times and condition (its topics are the caller's)."""
        return cls(
            MessageTypes(),
            query.field_selection,
            query.span,
            bulk,
            progress,
            prefetch=prefetch,
            where=query.where,
        )

    matchers: dict[str, PayloadMatcher] = field(default_factory=dict)
    window: Window = field(default_factory=Window)
    done: int = 0
    total: int = 0
    accumulators: dict[str, TopicAccumulator] = field(default_factory=dict)
    skipped: dict[str, str] = field(default_factory=dict)
    problems: list[str] = field(default_factory=list)
    unread: list[str] = field(default_factory=list)
    """Bags that could not be read (the others are summarized)."""

    def accumulator(
        self, topic: str, type_name: str, encoding: str, bag: str
    ) -> TopicAccumulator | None:
        """The accumulator of ``topic``, or None when ``bag``'s messages on it cannot be decoded.

        Raises:
            StatsError: the topic has another type, or another definition of its type, in a
                bag summarized before ``bag``.
        """
        existing = self.accumulators.get(topic)
        types = self.types.for_topic(topic)
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
                canonical = types.resolve(type_name)
            except DecodeError as exc:
                self.problems.append(f"{bag}: messages on {topic} not read: {exc}")
                return None
            if tuple(leaf_fields(types.typestore, canonical)) != existing.signature:
                raise StatsError(
                    f"{type_name} of topic {topic} is defined differently in {bag} than in "
                    "the bags before it: summarize them separately"
                )
            existing.use_types(types)
            return existing
        if topic in self.skipped:
            return None
        if encoding != "cdr":
            self.skipped[topic] = f"serialization format {encoding!r} is not CDR"
            return None
        try:
            canonical = types.resolve(type_name)
        except DecodeError as exc:
            self.skipped[topic] = str(exc)
            return None
        signature = tuple(leaf_fields(types.typestore, canonical))
        selected = self.fields.for_topic(topic)
        leaves = [leaf for leaf in signature if leaf.numeric and selected(leaf.path)]
        layout = CdrLayout.of(types.typestore, canonical) if self.bulk else None
        accumulator = TopicAccumulator(
            topic, type_name, leaves, layout=layout, types=types, signature=signature
        )
        self.accumulators[topic] = accumulator
        return accumulator

    def read(self, reader: BagReader, topics: Sequence[str] | None, label: str) -> None:
        """Add the messages of ``reader`` on ``topics`` (all when None); ``label`` names the bag
        in problems as the user gave it."""
        # Each bag is decoded with its own definitions (pooled bags must agree on them).
        self.types = MessageTypes.for_bag(reader)
        # Times from the start or end count from this bag's own first or last message.
        self.window = self.span.resolve(reader.start_ns, reader.end_ns)
        if reader.message_count:
            outside = outside_warning(label, self.window, reader.start_ns, reader.end_ns)
            if outside is not None:
                self.problems.append(outside)
        wanted: dict[str, TopicAccumulator] = {}
        named = None if topics is None else {absolute_topic_name(t) for t in topics}
        self.matchers = {}
        for name, info in reader.topics.items():
            if named is not None and absolute_topic_name(name) not in named:
                continue
            accumulator = self.accumulator(name, info.type, info.serialization_format, label)
            if accumulator is not None and self.where is not None:
                accumulator = self._filtered(accumulator, len(named or ()) == 1)
            if accumulator is not None:
                wanted[name] = accumulator
            else:  # skipped: its messages are not read
                self.total -= reader.topic_counts.get(name, 0)
        if wanted:
            # closing(): the reading thread stops before the reader is closed, also on error.
            chunks = reader.chunks(wanted, self.window.start_ns, self.window.end_ns)
            ahead = prefetch(chunks, depth=2 if self.prefetch else 0)
            with closing(ahead) as chunks:
                for chunk in chunks:
                    self.advance(self.add_chunk(chunk, wanted))
        for accumulator in wanted.values():
            accumulator.end_bag()
        self.problems.extend(_named(label, problem) for problem in reader.problems)

    def _filtered(self, accumulator: TopicAccumulator, single: bool) -> TopicAccumulator | None:
        """``accumulator`` with the matcher of ``where`` for this bag, or None when the topic's
        type lacks the condition's fields (left out, unless it is the one topic asked for)."""
        # The condition's matcher (and language) only with --where: a summary starts without.
        from bagkit.decode.matcher import PayloadMatcher

        assert self.where is not None
        topic = accumulator.topic
        try:
            matcher = PayloadMatcher(
                self.types, topic, accumulator.type_name, self.where, bulk=self.bulk
            )
        except UnknownFieldError:
            if single:
                raise
            if not accumulator.count:
                del self.accumulators[topic]
            return None
        self.matchers[topic] = matcher
        return accumulator

    def advance(self, messages: int, every: int = 1) -> None:
        """Count ``messages`` as done; report progress (each time ``done`` passes a multiple
        of ``every``)."""
        before, self.done = self.done, self.done + messages
        if self.progress is not None and self.done // every != before // every:
            self.progress(self.done, self.total)

    def add_chunk(self, chunk: BagChunk, accumulators: dict[str, TopicAccumulator]) -> int:
        """Add the messages of ``chunk`` on the accumulated topics; return how many were seen."""
        seen = 0
        for topic, index in chunk.message_index.items():
            accumulator = accumulators.get(topic)
            if accumulator is None:
                continue
            seen += len(index)
            # A db3 or ROS 1 chunk's payloads where they are (its records are not laid out).
            buffer, log_times, starts, lengths = chunk.payload_view(topic)
            if self.window.bounded:
                keep = self.window.mask(log_times)
                log_times, starts, lengths = log_times[keep], starts[keep], lengths[keep]
            matcher = self.matchers.get(topic)
            if matcher is not None:
                failures = matcher.undecodable
                keep = matcher.mask_records(buffer, starts, lengths)
                _count_failures(matcher, accumulator, failures)
                log_times, starts, lengths = log_times[keep], starts[keep], lengths[keep]
            accumulator.add_times(log_times)
            if not len(starts) or not accumulator.leaves:  # counted; no field to decode
                continue
            accumulator.add_spans(buffer, starts, lengths)
        return seen


def _count_failures(matcher: PayloadMatcher, accumulator: TopicAccumulator, before: int) -> None:
    """Count the messages the matcher could not decode since it had ``before`` failures."""
    if matcher.undecodable > before:
        accumulator.fail(DecodeError(matcher.first_failure), matcher.undecodable - before)


def _named(label: str, problem: str) -> str:
    """``problem`` naming the bag as the user gave it, unless it names that file already."""
    return problem if problem.startswith(f"{Path(label).name}:") else f"{label}: {problem}"
