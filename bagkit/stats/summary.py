"""``summarize``: per-topic counts and rates, per-numeric-field exact statistics, over bags.

One pass over each bag, one decompressed chunk at a time (memory does not grow with the bag).
Each topic's :class:`~bagkit.stats.accumulate.TopicAccumulator` gets the payload spans of each
chunk: topics whose type has a CDR layout are decoded in bulk with numpy
(:mod:`bagkit.decode.bulk`), every other message by the general path
(:meth:`~bagkit.decode.MessageTypes.value_reader`); both feed the same moments.
"""

from __future__ import annotations

from collections.abc import Callable, Iterable, Mapping, Sequence
from contextlib import closing
from dataclasses import dataclass, field
from pathlib import Path
from typing import TYPE_CHECKING

from bagkit.bag import BagChunk, BagError, BagReader
from bagkit.decode import DecodeError, MessageTypes, leaf_fields
from bagkit.decode.layout import CdrLayout
from bagkit.errors import not_read
from bagkit.prefetch import prefetch
from bagkit.selection.errors import UnknownFieldError
from bagkit.selection.fields import FieldSelection, unknown_field_message
from bagkit.selection.query import Query, resolve_names
from bagkit.selection.topics import absolute_topic_name, did_you_mean
from bagkit.selection.windows import TimeRange, Window, outside_warning
from bagkit.stats.accumulate import TopicAccumulator
from bagkit.stats.errors import NothingToSummarizeError, StatsError
from bagkit.stats.result import Summary

if TYPE_CHECKING:
    from bagkit.decode.matcher import PayloadMatcher
    from bagkit.selection.conditions import Condition
from bagkit.storage.urls import location, shown_as
from bagkit.words import counted

ProgressCallback = Callable[[int, int], None]
"""Called with (messages done, messages in total) as the summary advances."""
# From this much chunk data on, glibc keeps freed buffers (bagkit.native): below it the
# ctypes import costs more than the page faults it saves.
KEEP_FREED_FROM_BYTES = 64 << 20


@dataclass(slots=True)
class SummaryRun:
    """The state of one summary across its bags: what :func:`summarize` runs in this process,
    and a fleet worker on its bag (:mod:`bagkit.fleet.stats`).

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


def summarize(
    bags: Iterable[str | Path],
    query: Query | None = None,
    *,
    progress: ProgressCallback | None = None,
    bulk: bool = True,
    check_crc: bool = True,
) -> Summary:
    """Count, rate and exact statistics of every numeric field, pooled over ``bags``.

    Args:
        bags: bag directories or single ``.mcap``/``.db3`` files.
        query: only its topics (all when it names none; a service by its name), the fields
            its patterns select (:mod:`bagkit.selection.fields`: globs with ``*`` and ``?``,
            brackets literal, ``TOPIC_GLOB:FIELD_GLOB``), the messages of its window
            (``10`` and ``-5`` count from each bag's own first and last message) satisfying
            its condition (topics whose type lacks the condition's fields are left out, unless
            one topic is asked for: then UnknownFieldError).
        progress: called with (messages done, messages in total).
        bulk: decode fixed-layout messages in bulk with numpy; False decodes every message
            with the general decoder (slower; to cross-check the bulk path).
        check_crc: check each chunk's CRC as it is read (a damaged chunk is a problem).

    Raises:
        BagError: the bag cannot be opened, or none of several (see ``bagkit.bag``); one of
            several that cannot is in the summary's problems, the others summarized.
        UnknownTopicError: a topic of ``query`` is in none of the bags.
        UnknownFieldError: ``fields`` select no numeric field (with the closest ones).
        NothingToSummarizeError: no message in the selection, or no topic can be decoded.
        StatsError: a topic has different types in different bags.
    """
    paths = [location(bag) for bag in bags]  # opened in full (a presigned URL's query)
    names = [shown_as(path) for path in paths]
    if not paths:
        raise StatsError("no bag given")
    query = query or Query()
    run = SummaryRun.of(query, bulk=bulk, progress=progress)
    readers: list[BagReader] = []
    read_names: list[str] = []  # of the bags opened
    try:
        for path, name in zip(paths, names, strict=True):
            try:
                readers.append(BagReader(path, allow_empty=True, check_crc=check_crc).open())
            except BagError as exc:
                # Among others, a bag that cannot be read is reported and the rest summarized,
                # as on a cluster (bagkit.fleet.stats); alone, or when none can be, it fails.
                if len(paths) == 1 or (path == paths[-1] and not readers):
                    raise
                run.problems.append(not_read(name, str(exc)))
                run.unread.append(name)
                continue
            read_names.append(name)
        known = {name: info.type for reader in readers for name, info in reader.topics.items()}
        topics = check_topics(known, list(query.topics) or None, len(paths))
        run.total = sum(
            count
            for reader in readers
            for topic, count in reader.topic_counts.items()
            if topics is None or topic in topics
        )
        # A local db3 has no chunks: its file's size instead.
        read = sum(r.uncompressed_size or (0 if r.in_storage else r.size_bytes) for r in readers)
        if read >= KEEP_FREED_FROM_BYTES:
            # Each chunk's buffers and columns are freed and allocated again for the next:
            # kept by glibc, not paid for in page faults chunk after chunk (180k -> 11k, a
            # quarter of the CPU of 1M Imu: benchmarks/README.md, issue 36 item 3).
            from bagkit.native import keep_freed_memory

            keep_freed_memory()
        for name, reader in zip(read_names, readers, strict=True):
            run.read(reader, topics, name)
    finally:
        for reader in readers:
            reader.close()
    if progress is not None:
        progress(run.total, run.total)
    return finish_summary(run, names)


def check_topics(
    topic_types: Mapping[str, str], topics: Sequence[str] | None, bags: int
) -> list[str] | None:
    """``topics`` as the bags (``topic_types``: every topic of any of them -> its type) store
    them, a service's or action's name resolved as ``echo`` resolves it (None: all topics).

    Raises:
        UnknownTopicError: a name is in none of the bags; the message names the closest ones.
    """
    if not topics:
        return None
    return list(resolve_names(topics, topic_types, "the bag" if bags == 1 else "any of the bags"))


def _no_field_message(run: SummaryRun) -> str:
    """``/imu/data has no numeric field x (did you mean y? it has ...)``: the fields of the
    summarized topics, named as the patterns name them."""
    numeric = {
        topic: [leaf.path for leaf in accumulator.signature if leaf.numeric]
        for topic, accumulator in sorted(run.accumulators.items())
    }
    patterns = list(run.fields.patterns)
    if len(numeric) == 1:
        ((topic, paths),) = numeric.items()
        return unknown_field_message(topic, patterns, paths).replace(
            " field ", " numeric field ", 1
        )
    qualified = [f"{topic}:{path}" for topic, paths in numeric.items() for path in paths]
    bare = [path for paths in numeric.values() for path in paths]
    guess = did_you_mean(patterns[0], qualified if ":" in patterns[0] else bare).rstrip()
    listing = f"{counted(len(numeric), 'topic')}, {counted(len(bare), 'numeric field')}"
    return f"no topic has a numeric field {', '.join(patterns)} ({guess or listing})"


def finish_summary(run: SummaryRun, paths: list[str]) -> Summary:
    """The :class:`Summary` of a run over ``paths``: results per topic, problems reported."""
    results = []
    for topic in sorted(run.accumulators):
        accumulator = run.accumulators[topic]
        if accumulator.failures:
            run.problems.append(
                f"{topic}: {counted(accumulator.failures, 'message')} could not be decoded "
                f"({accumulator.first_failure})"
            )
        if run.fields and not accumulator.leaves:
            continue
        results.append(accumulator.result())
    seen = [a for a in run.accumulators.values() if a.first_ns is not None]
    if not seen:
        bags = ", ".join(paths)
        if run.skipped and not run.accumulators:
            reasons = "; ".join(f"{t}: {why}" for t, why in sorted(run.skipped.items()))
            raise NothingToSummarizeError(f"no topic of {bags} can be decoded ({reasons})")
        if run.where is not None:  # nothing matched: said once, an empty summary
            run.problems.append(f"no message satisfies {run.where.text!r} in {bags}")
        if run.span.bounded or run.where is not None:  # the window missed: said once per bag
            return Summary(
                tuple(paths),
                None,
                None,
                (),
                dict(run.skipped),
                tuple(run.problems),
                tuple(run.unread),
            )
        lost = f" ({'; '.join(run.problems)})" if run.problems else ""  # what was lost
        raise NothingToSummarizeError(f"no messages to summarize in {bags}{lost}")
    if run.fields and not results:
        raise UnknownFieldError(_no_field_message(run))
    return Summary(
        bags=tuple(paths),
        start_ns=min(a.first_ns for a in seen if a.first_ns is not None),
        end_ns=max(a.last_ns for a in seen if a.last_ns is not None),
        topics=tuple(results),
        skipped=dict(sorted(run.skipped.items())),
        problems=tuple(run.problems),
        unread=tuple(run.unread),
    )


def _count_failures(matcher: PayloadMatcher, accumulator: TopicAccumulator, before: int) -> None:
    """Count the messages the matcher could not decode since it had ``before`` failures."""
    if matcher.undecodable > before:
        accumulator.fail(DecodeError(matcher.first_failure), matcher.undecodable - before)


def _named(label: str, problem: str) -> str:
    """``problem`` naming the bag as the user gave it, unless it names that file already."""
    return problem if problem.startswith(f"{Path(label).name}:") else f"{label}: {problem}"
