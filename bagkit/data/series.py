"""Time series to plot: ``TOPIC:FIELD`` specs read from one or more bags, on a common axis."""

from __future__ import annotations

import itertools
import warnings
from collections import Counter
from collections.abc import Sequence
from dataclasses import dataclass, field, replace
from pathlib import Path

import numpy as np

from bagkit.bag import BagReader
from bagkit.bag.storage_files import bag_path
from bagkit.data.errors import (
    DataError,
    UndecodableTopicError,
    could_have_lost,
    unread_topics,
)
from bagkit.data.scan import plan_scan
from bagkit.data.units import field_unit
from bagkit.decode import MessageTypes
from bagkit.decode.flatten import STRING_TYPES
from bagkit.selection.errors import EmptyWindowWarning
from bagkit.selection.query import Query
from bagkit.selection.topics import require_topics


@dataclass(frozen=True, slots=True)
class Series:
    """One field of one topic of one bag over time.

    Attributes:
        bag: the bag's label (its name, or its path when names repeat).
        topic, field: what is plotted; ``unit`` is ``""`` where nothing says.
        times: seconds from the bag's start, or absolute ``datetime64[ns]`` (UTC).
        values: float64.
    """

    bag: str
    topic: str
    field: str
    unit: str
    times: np.ndarray
    values: np.ndarray

    @property
    def key(self) -> str:
        """``topic:field``: the panel the series goes in (bags overlaid)."""
        return f"{self.topic}:{self.field}"


def parse_spec(spec: str) -> tuple[str, str]:
    """``/imu/data:linear_acceleration.z`` -> (topic, field glob).

    Raises:
        DataError: no ``:`` or an empty part.
    """
    topic, sep, field = spec.partition(":")
    if not sep or not topic or not field:
        raise DataError(f"{spec!r} is not TOPIC:FIELD (e.g. /imu/data:linear_acceleration.z)")
    return topic, field


def bag_labels(bags: Sequence[Path]) -> list[str]:
    """Each bag's name, or its path where two bags share a name."""
    names = [bag.name for bag in bags]
    return [str(bag) if names.count(bag.name) > 1 else bag.name for bag in bags]


@dataclass(slots=True)
class SeriesReading:
    """What :func:`read_series` found: the series, what could not be read, and how many
    messages of each (bag label, topic) were read and did not decode."""

    series: list[Series] = field(default_factory=list)
    problems: list[str] = field(default_factory=list)
    """One line each, the bag's label first; each said once."""
    messages: dict[tuple[str, str], int] = field(default_factory=dict)
    """(bag label, topic) -> its messages read (in the window, before the condition)."""
    undecodable: dict[tuple[str, str], int] = field(default_factory=dict)
    """(bag label, topic) -> those of them that did not decode (not in the series)."""
    lost: list[str] = field(default_factory=list)
    """The parts of the bags that could not be read (damaged chunks; in ``problems`` too)."""
    losing: set[str] = field(default_factory=set)
    """The topics whose messages may be among them (:func:`could_have_lost`)."""

    def nothing_read(self) -> list[str]:
        """The topics no message of which was read in any bag, when a bag lost parts that
        could have held some (:func:`~bagkit.data.errors.nothing_read`)."""
        counts = ((topic, count) for (_, topic), count in self.messages.items())
        return unread_topics(counts, self.losing)

    def none_decoded(self) -> dict[str, int]:
        """Topic -> its messages, for the topics that had messages in the bags and decoded
        none of them in any."""
        messages: Counter[str] = Counter()
        undecodable: Counter[str] = Counter()
        for (_, topic), count in self.messages.items():
            messages[topic] += count
        for (_, topic), count in self.undecodable.items():
            undecodable[topic] += count
        return {t: n for t, n in messages.items() if 0 < n == undecodable[t]}


def load_series(
    bags: Sequence[str | Path],
    specs: Sequence[str],
    *,
    absolute: bool = False,
    query: Query | None = None,
) -> list[Series]:
    """The series of :func:`read_series` (messages that do not decode left out)."""
    return read_series(bags, specs, absolute=absolute, query=query).series


def read_series(
    bags: Sequence[str | Path],
    specs: Sequence[str],
    *,
    absolute: bool = False,
    query: Query | None = None,
) -> SeriesReading:
    """Every numeric field that ``specs`` name, from every bag, in spec order, bag order;
    ``query``'s times resolved against each bag and its condition keeping the messages that
    satisfy it (each spec's topic must have its fields); the specs name topics and fields. A
    topic none of whose messages decode in a bag gives no series there.

    Raises:
        BagError, UnknownTopicError, UnknownFieldError, UndecodableTopicError; DataError for
        a field that is not a number (a string, a variable-length sequence); SelectionError
        for a bad condition.
    """
    wanted = [parse_spec(spec) for spec in specs]
    query = query or Query()
    paths = [bag_path(bag) for bag in bags]
    per_spec: list[list[Series]] = [[] for _ in wanted]
    reading = SeriesReading()
    for label, path in zip(bag_labels(paths), paths, strict=True):
        with BagReader(path, allow_empty=True) as reader:
            types = MessageTypes.for_bag(reader)
            for found, (topic, field_glob) in zip(per_spec, wanted, strict=True):
                found.extend(
                    _topic_series(
                        reader,
                        types,
                        (label, str(path)),
                        (topic, field_glob),
                        query,
                        absolute,
                        reading,
                    )
                )
            reading.lost.extend(f"{label}: {problem}" for problem in reader.problems)
    reading.series = [s for found in per_spec for s in found]
    reading.problems = list(dict.fromkeys(reading.problems))
    return reading


def _topic_series(  # noqa: PLR0917 (private, called once)
    reader: BagReader,
    types: MessageTypes,
    labels: tuple[str, str],
    spec: tuple[str, str],
    query: Query,
    absolute: bool,
    reading: SeriesReading,
) -> list[Series]:
    """The series of one spec in one bag; its counts and problems go into ``reading``."""
    (topic,), field_glob = require_topics([spec[0]], reader.topics), spec[1]
    label, given = labels  # the legend's short name; the path as given, for warnings
    scan = plan_scan(reader, replace(query, topics=(topic,), fields=(field_glob,)), label=given)
    if scan.outside is not None:
        warnings.warn(scan.outside, EmptyWindowWarning, stacklevel=3)
    if topic in scan.skipped:
        raise UndecodableTopicError(f"{topic} cannot be decoded: {scan.skipped[topic]}")
    columns = scan.topics[topic]
    for leaf in columns.leaves:
        if leaf.pooled or leaf.base in STRING_TYPES:
            kind = "a variable-length sequence" if leaf.pooled else "a string"
            raise DataError(f"{topic}:{leaf.path} is {kind}, not a number over time")
    batches = [batch for _, batch in scan.batches() if batch.num_rows]
    if could_have_lost(reader, topic):
        reading.losing.add(topic)
    key = (label, topic)
    reading.messages[key] = columns.messages
    # Another spec of the topic read other fields: the topic decoded something if one did.
    reading.undecodable[key] = min(
        reading.undecodable.get(key, columns.undecodable), columns.undecodable
    )
    reading.problems.extend(p if p.startswith(label) else f"{label}: {p}" for p in scan.problems)
    if not batches:
        return []
    log_times = np.concatenate([b.column("log_time").to_numpy() for b in batches])
    order = np.argsort(log_times, kind="stable")
    times = (
        log_times[order].astype("datetime64[ns]")
        if absolute
        else (log_times[order] - reader.start_ns) / 1e9
    )
    types = types.for_topic(topic)
    canonical = types.resolve(columns.type_name)
    definitions = dict(reader.definitions)  # the units' comments: the topic's own text
    if topic in reader.topic_definitions:
        definitions[columns.type_name] = reader.topic_definitions[topic]
    return [
        Series(
            label,
            topic,
            leaf.path,
            field_unit(types.typestore, canonical, leaf.path, definitions),
            times,
            np.concatenate(
                [b.column(leaf.path).to_numpy(zero_copy_only=False) for b in batches]
            ).astype(np.float64)[order],
        )
        for leaf in columns.leaves
    ]


def decimate(times: np.ndarray, values: np.ndarray, points: int) -> tuple[np.ndarray, np.ndarray]:
    """At most about ``points`` points that keep every bucket's minimum and maximum (spikes
    stay visible, as in PlotJuggler), in time order."""
    n = len(values)
    if n <= points:
        return times, values
    buckets = max(points // 2, 1)
    edges = np.linspace(0, n, buckets + 1).astype(np.int64)
    keep = []
    for low, high in itertools.pairwise(edges):
        if high <= low:
            continue
        part = values[low:high]
        if np.isnan(part).all():
            keep.append(low)
            continue
        keep.extend(sorted({low + int(np.nanargmin(part)), low + int(np.nanargmax(part))}))
    index = np.array(keep, dtype=np.int64)
    return times[index], values[index]


def axis_label(series: Series) -> str:
    """``linear_acceleration.z [m/s²]``."""
    return f"{series.field} [{series.unit}]" if series.unit else series.field
