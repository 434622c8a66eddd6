"""``bagkit stats summary`` over many bags: per-bag partial statistics merged exactly.

A worker runs the summary's own accumulation over one bag and returns its accumulators: counts,
first/last log times and, per field, the running moments (count, NaN and infinity counts,
min/max, shifted mean and sum of squared deviations). The driver merges them in the order of
the bags: counts, min and max exactly, mean and M2 with Chan et al.'s parallel formula
(:meth:`bagkit.stats.moments.Moments.merge`), which agrees with one pass over all the bags to
rounding. A bag that cannot be read is reported in ``problems``; the others are summarized.
"""

from __future__ import annotations

import contextlib
import functools
from collections.abc import Iterable, Sequence
from dataclasses import dataclass, field
from pathlib import Path
from typing import TYPE_CHECKING

from bagkit.bag import BagError, BagReader
from bagkit.errors import not_read
from bagkit.fleet.errors import FleetError
from bagkit.fleet.execute import ItemDone, run_each
from bagkit.selection.errors import UnknownTopicError
from bagkit.selection.query import Query, resolve_names
from bagkit.stats import StatsError, Summary
from bagkit.stats.accumulate import TopicAccumulator
from bagkit.stats.run import SummaryRun
from bagkit.stats.summary import check_topics, finish_summary
from bagkit.storage.errors import StorageError
from bagkit.storage.urls import location, shown_as

if TYPE_CHECKING:
    from distributed import Client


@dataclass(slots=True)
class BagPartial:
    """What one bag contributes to a summary (sent from a worker to the driver).

    Attributes:
        bag: the bag as given.
        topics: every topic of the bag and its type (to resolve the query's names against all
            the bags).
        accumulators: the running figures per summarized topic.
        skipped: topic -> why its messages could not be decoded.
        problems: what could not be read in the bag.
        error: why the bag could not be read at all (then nothing else is filled in).
    """

    bag: str
    topics: dict[str, str] = field(default_factory=dict)
    accumulators: dict[str, TopicAccumulator] = field(default_factory=dict)
    skipped: dict[str, str] = field(default_factory=dict)
    problems: list[str] = field(default_factory=list)
    error: str | None = None


def summarize_bag(
    bag: str,
    query: Query | None = None,
    *,
    bulk: bool = True,
    check_crc: bool = True,
) -> BagPartial:
    """The partial summary of one bag (what a worker computes); arguments as ``summarize``.

    The query's names that this bag has are summarized (a service's or action's name resolved
    as ``echo`` resolves it); :func:`merge_partials` checks each is in one of the bags.
    """
    query = query or Query()
    run = SummaryRun.of(query, bulk=bulk, prefetch=False)
    path, bag = bag, shown_as(bag)  # opened in full, named without a URL's secrets
    try:
        with BagReader(path, allow_empty=True, check_crc=check_crc) as reader:
            types = {name: info.type for name, info in reader.topics.items()}
            run.read(reader, _present(query.topics, types), bag)
    except (BagError, StorageError) as exc:
        return BagPartial(bag, error=str(exc))
    return BagPartial(bag, types, run.accumulators, run.skipped, run.problems)


def _present(names: Sequence[str], topic_types: dict[str, str]) -> list[str] | None:
    """The topics of ``names`` that a bag has (None: all, when no name is given)."""
    if not names:
        return None
    found: list[str] = []
    for name in names:
        with contextlib.suppress(UnknownTopicError):
            found += resolve_names([name], topic_types)
    return found


def _merge_topic(into: TopicAccumulator, other: TopicAccumulator, bag: str) -> None:
    if into.type_name != other.type_name:
        raise StatsError(
            f"topic {into.topic} has type {into.type_name} in one bag "
            f"and {other.type_name} in another"
        )
    if into.signature != other.signature:
        raise StatsError(
            f"{into.type_name} of topic {into.topic} is defined differently in {bag} than in "
            "the bags before it: summarize them separately"
        )
    into.count += other.count
    other.end_bag()
    into.intervals += other.intervals
    into.span_ns += other.span_ns
    if other.first_ns is not None and other.last_ns is not None:
        into.first_ns = (
            other.first_ns if into.first_ns is None else min(into.first_ns, other.first_ns)
        )
        into.last_ns = other.last_ns if into.last_ns is None else max(into.last_ns, other.last_ns)
    into.scalars.merge(other.scalars)
    for path, moments in into.pooled.items():
        moments.merge(other.pooled[path])
    into.failures += other.failures
    into.first_failure = into.first_failure or other.first_failure


def _merge(run: SummaryRun, part: BagPartial) -> None:
    """Add one bag's partial to ``run``, as the in-process summary would have read the bag."""
    for topic, accumulator in part.accumulators.items():
        existing = run.accumulators.get(topic)
        if existing is not None:
            _merge_topic(existing, accumulator, part.bag)
        elif topic not in run.skipped:  # a topic skipped in an earlier bag stays skipped
            run.accumulators[topic] = accumulator
    for topic, reason in part.skipped.items():
        if topic in run.accumulators:
            run.problems.append(f"{part.bag}: messages on {topic} not read: {reason}")
        else:
            run.skipped.setdefault(topic, reason)
    run.problems.extend(part.problems)


def merge_partials(parts: Sequence[BagPartial], query: Query | None = None) -> Summary:
    """The summary of the bags of ``parts`` (in their order), as ``summarize`` would give it.

    Raises:
        FleetError: no bag could be read.
        UnknownTopicError, NothingToSummarizeError, StatsError: as ``summarize``.
    """
    readable = [part for part in parts if part.error is None]
    if not readable:
        raise FleetError(f"no bag could be read ({parts[0].error if parts else 'no bag given'})")
    query = query or Query()
    known = {name: kind for part in readable for name, kind in part.topics.items()}
    check_topics(known, list(query.topics) or None, len(parts))
    run = SummaryRun.of(query, prefetch=False)
    for part in parts:
        if part.error is not None:
            run.problems.append(not_read(part.bag, part.error))
            run.unread.append(part.bag)
        else:
            _merge(run, part)
    return finish_summary(run, [part.bag for part in parts])


def summarize_fleet(
    bags: Iterable[str | Path],
    *,
    client: Client | None,
    query: Query | None = None,
    bulk: bool = True,
    check_crc: bool = True,
    done: ItemDone | None = None,
) -> Summary:
    """``bagkit.stats.summarize`` of ``bags``, on ``client``'s workers (here when None).

    Args:
        done: called with the index of each bag once it is summarized.

    Raises:
        As :func:`merge_partials`.
    """
    paths = [location(bag) for bag in bags]
    query = query or Query()
    task = functools.partial(summarize_bag, query=query, bulk=bulk, check_crc=check_crc)
    parts = run_each(task, paths, client, done)
    return merge_partials(parts, query)
