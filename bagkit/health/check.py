"""A health contract evaluated on bags: one :class:`~bagkit.health.verdicts.Assertion` per
line of the contract.

Every assertion over time is a condition that must never hold
(:class:`~bagkit.health.spec.TopicContract`); a topic's conditions are evaluated together by
:func:`bagkit.data.streams.intervals_of_each`, the columns they read decoded in one bulk pass
(``gap`` and ``rate`` alone: from the MCAP indexes, nothing decoded). A topic the bag lacks,
or has no message of, breaks its contract; a field the topic's type lacks is a bad spec
(:class:`SpecError`). Many bags run on Dask through :func:`bagkit.fleet.execute.run_each`; a
bag that cannot be read is reported among the others.
"""

from __future__ import annotations

import functools
from collections.abc import Iterable
from dataclasses import replace
from pathlib import Path
from typing import TYPE_CHECKING

from bagkit.bag import BagError, BagReader
from bagkit.bag.definitions import canonical_type_name
from bagkit.bag.latched import is_state_topic
from bagkit.data.episodes import interval_spans
from bagkit.data.streams import intervals_of_each
from bagkit.fleet.execute import ItemDone, run_each
from bagkit.health import links
from bagkit.health.spec import HealthSpec, SpecError, TopicContract
from bagkit.health.verdicts import Assertion, CheckResult, HealthReport
from bagkit.selection.condition_terms import Latency, walk
from bagkit.selection.conditions import Condition
from bagkit.selection.errors import SelectionError
from bagkit.selection.query import Query
from bagkit.selection.topics import absolute_topic_name, did_you_mean, require_topics
from bagkit.selection.windows import Window, outside_warning
from bagkit.storage.errors import StorageError
from bagkit.storage.urls import location, shown_as
from bagkit.words import counted

if TYPE_CHECKING:
    from distributed import Client


def check_bag(bag: str | Path, spec: HealthSpec, query: Query | None = None) -> HealthReport:
    """Evaluate ``spec`` on ``bag``; with a ``query``, only the contracts of its topics (see
    :func:`restrict`) over the messages of its window (a window outside the bag is a problem).

    Raises:
        BagError: the bag cannot be read; SpecError: a condition names a field the topic's
            type lacks (or compares text with a number).
    """
    found: list[Assertion] = []
    with BagReader(location(bag), allow_empty=True) as reader:
        problems = list(reader.problems)
        window = Window()
        if query is not None:
            spec = restrict(spec, query)
            window = query.span.resolve(reader.start_ns, reader.end_ns)
            if reader.message_count:
                label = shown_as(location(bag))  # a URL named without its secrets
                outside = outside_warning(label, window, reader.start_ns, reader.end_ns)
                problems += [outside] if outside else []
        # The spec's names are absolute; bags of other tools may store relative ones.
        stored = {absolute_topic_name(name): name for name in reader.topics}
        named = [*spec.forbidden, *(c.topic for c in spec.topics)]
        counts = _counts(reader, [stored.get(t, t) for t in named], window)
        for topic in spec.forbidden:
            count = counts.get(stored.get(topic, topic), 0)
            reason = counted(count, "message") if count else ""
            found.append(Assertion(topic, "forbidden", not count, reason=reason))
        for contract in spec.topics:
            topic = stored.get(contract.topic, contract.topic)
            if not counts.get(topic, 0):
                reason = "no message" if not window.bounded else "no message in the window"
                if topic not in reader.topics:  # a misspelling reads as a broken contract
                    guess = did_you_mean(topic, reader.topics).rstrip()
                    reason = f"not in the bag{'; ' + guess if guess else ''}"
                found.append(Assertion(contract.topic, "present", False, reason=reason))
                continue
            found.append(Assertion(contract.topic, "present", True))
            if contract.type is not None:
                actual = canonical_type_name(reader.topics[topic].type)
                same = actual == canonical_type_name(contract.type)
                found.append(
                    Assertion(
                        contract.topic, f"type {contract.type}", same, reason="" if same else actual
                    )
                )
            # A latency whose source topic the bag lacks is broken in this bag, not bad input.
            absent = {text: _absent_sources(c, stored) for text, c in contract.never}
            never = [(text, c) for text, c in contract.never if not absent[text]]
            try:
                broken, times, read_problems = intervals_of_each(
                    reader, topic, [c for _, c in never], window, is_state_topic(reader, topic)
                )
            except SelectionError as exc:
                raise _field_error(reader, topic, spec, contract, exc) from None
            problems.extend(p for p in read_problems if p not in problems)
            spans = {
                t: interval_spans(w, o) for (t, _), w, o in zip(never, broken, times, strict=True)
            }
            for text, _ in contract.never:
                if absent[text]:
                    reason = f"{', '.join(absent[text])} not in the bag"
                    found.append(Assertion(contract.topic, text, False, reason=reason))
                else:
                    found.append(Assertion(contract.topic, text, not len(spans[text]), spans[text]))
        files = sorted(
            (f.start_ns, f.path.name)
            for f in reader.storage_files
            if f.storage_identifier == "mcap"
        )
        return HealthReport(shown_as(location(bag)), reader.start_ns, found, problems, files=files)


def restrict(spec: HealthSpec, query: Query) -> HealthSpec:
    """The contracts of ``spec`` on the query's topics (all when it names none).

    Raises:
        UnknownTopicError: a topic is not in the contract; the message names the closest.
    """
    if not query.topics:
        return spec
    named = [c.topic for c in spec.topics] + list(spec.forbidden)
    wanted = set(require_topics(query.topics, named, f"the contract {spec.source}".rstrip()))
    return replace(
        spec,
        topics=tuple(c for c in spec.topics if c.topic in wanted),
        forbidden=tuple(t for t in spec.forbidden if t in wanted),
    )


def _counts(reader: BagReader, topics: list[str], window: Window) -> dict[str, int]:
    """Each topic's messages in ``window`` (from the indexes where they tell)."""
    if not window.bounded:
        return reader.topic_counts
    counts = {}
    for topic in topics:
        if topic not in reader.topics:
            continue
        times = reader.index_log_times(topic, window.start_ns, window.end_ns)
        counts[topic] = (
            len(times)
            if times is not None
            else sum(1 for _ in reader.messages([topic], window.start_ns, window.end_ns))
        )
    return counts


def _absent_sources(condition: Condition, stored: dict[str, str]) -> list[str]:
    """The latency sources of ``condition`` that the bag (its topics by absolute name) lacks."""
    sources = {
        absolute_topic_name(n.source) for n in walk(condition.tree) if isinstance(n, Latency)
    }
    return sorted(sources - set(stored))


def _field_error(
    reader: BagReader, topic: str, spec: HealthSpec, contract: TopicContract, error: SelectionError
) -> SpecError:
    """The error of a condition that does not fit the type of ``topic`` (the contract's topic
    as the bag stores it), naming its spec line (each condition read alone to find which)."""
    for index, (text, condition) in enumerate(contract.never):
        if _absent_sources(condition, {absolute_topic_name(n): n for n in reader.topics}):
            continue  # its assertion is broken, not the error
        try:
            intervals_of_each(reader, topic, [condition], Window())
        except SelectionError as exc:
            lines = contract.lines
            line = lines[index] if index < len(lines) and lines[index] else None
            where = f"{spec.source}:{line}" if line else spec.source
            # The error names the comparison that failed; the whole condition only when it is
            # more than that one comparison.
            failed = str(exc)
            named = failed if failed.startswith(text) else f"{text}: {failed}"
            return SpecError(f"{where}: {contract.topic}: {named}")
    return SpecError(f"{spec.source}: {contract.topic}: {error}")


def _check_one(
    bag: str, *, spec: HealthSpec, url: str | None, query: Query | None = None
) -> HealthReport:
    """What a worker runs: the report of one bag, or why it could not be read."""
    try:
        report = check_bag(bag, spec, query)
    except (BagError, StorageError) as exc:
        return HealthReport(shown_as(bag), 0, [], error=str(exc))
    report.bags_url = url
    return report


def check_bags(
    bags: Iterable[str | Path] | str | Path,
    spec: HealthSpec | str | Path,
    *,
    client: Client | None = None,
    done: ItemDone | None = None,
    bags_url: str | None = None,
    query: Query | None = None,
) -> CheckResult:
    """Evaluate a health contract on bags, on ``client``'s Dask workers (here when None).

    Args:
        bags: a bag, or bags (directories or ``.mcap`` files).
        spec: the contract, or the path of its YAML file.
        query: only the contracts of its topics, over its window (as :func:`check_bag`).
        done: called with the index of each bag once it is checked.
        bags_url: where the bags are served over HTTP(S) (default ``$BAGKIT_BAGS_URL``): each
            failure then gets a Foxglove link to its moment.

    Raises:
        SpecError: the spec cannot be used (before any bag is read), or a condition names a
            field the topic's type lacks.
        UnknownTopicError: a topic of ``query`` is not in the contract (before any bag is
            read).
    """
    if not isinstance(spec, HealthSpec):
        spec = HealthSpec.load(spec)
    if query is not None:
        restrict(spec, query)  # an unknown topic is one error before any bag is read
    paths = _paths(bags)
    task = functools.partial(_check_one, spec=spec, url=links.bags_url(bags_url), query=query)
    return CheckResult(run_each(task, paths, client, done))


def check(
    bags: Iterable[str | Path] | str | Path,
    spec: HealthSpec | str | Path,
    *,
    workers: int | None = 0,
    scheduler: str | None = None,
    bags_url: str | None = None,
    query: Query | None = None,
) -> CheckResult:
    """``bagkit.check``: evaluate a health contract on bags, here or on Dask.

    Args:
        bags, spec, bags_url, query: as :func:`check_bags`.
        workers: local Dask worker processes (0: in this process; None: a local cluster
            where the bags are enough work to pay for its start).
        scheduler: the address of a ``dask.distributed`` scheduler to run on.

    Raises:
        SpecError: as :func:`check_bags`; SchedulerError, FleetError: as
            :func:`bagkit.fleet.fleet_client`.
    """
    from bagkit.fleet.cluster import CHECK_RATE, fleet_client
    from bagkit.fleet.progress import bag_size

    if not isinstance(spec, HealthSpec):
        spec = HealthSpec.load(spec)  # before any cluster starts
    if query is not None:
        restrict(spec, query)  # an unknown topic too
    paths = _paths(bags)
    with fleet_client(
        workers=workers,
        scheduler=scheduler,
        bags=len(paths),
        size_bytes=sum(bag_size(path) for path in paths),
        rate=CHECK_RATE,
    ) as client:
        return check_bags(paths, spec, client=client, bags_url=bags_url, query=query)


def _paths(bags: Iterable[str | Path] | str | Path) -> list[str]:
    return [location(bags)] if isinstance(bags, str | Path) else [location(bag) for bag in bags]
