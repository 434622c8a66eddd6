"""``summarize``: per-topic counts and rates, per-numeric-field exact statistics, over bags.

One pass over each bag, one decompressed chunk at a time (memory does not grow with the bag).
Each topic's :class:`~bagkit.stats.accumulate.TopicAccumulator` gets the payload spans of each
chunk: topics whose type has a CDR layout are decoded in bulk with numpy
(:mod:`bagkit.decode.bulk`), every other message by the general path
(:meth:`~bagkit.decode.MessageTypes.value_reader`); both feed the same moments.
"""

from __future__ import annotations

from collections.abc import Iterable, Mapping, Sequence
from pathlib import Path

from bagkit.bag import BagError, BagReader
from bagkit.errors import not_read
from bagkit.selection.errors import UnknownFieldError
from bagkit.selection.fields import unknown_field_message
from bagkit.selection.query import Query, resolve_names
from bagkit.selection.topics import did_you_mean
from bagkit.stats.errors import NothingToSummarizeError, StatsError
from bagkit.stats.result import Summary
from bagkit.stats.run import ProgressCallback, SummaryRun
from bagkit.storage.urls import location, shown_as
from bagkit.words import counted

# From this much chunk data on, glibc keeps freed buffers (bagkit.native): below it the
# ctypes import costs more than the page faults it saves.
KEEP_FREED_FROM_BYTES = 64 << 20


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
