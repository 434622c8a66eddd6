"""``read_arrow`` and ``read_dataframe``: one topic of a bag as a table, for notebooks."""

from __future__ import annotations

import warnings
from collections.abc import Sequence
from pathlib import Path
from typing import TYPE_CHECKING

import pyarrow as pa

from bagkit.bag import BagReader
from bagkit.data.errors import DataError, DataLossWarning, UndecodableTopicError
from bagkit.data.scan import plan_scan
from bagkit.data.table import ColumnTable
from bagkit.selection.errors import EmptyWindowWarning
from bagkit.selection.query import Query, resolve_names
from bagkit.selection.times import TimeLike

if TYPE_CHECKING:
    import pandas as pd


def read_arrow(
    bag: str | Path,
    topic: str,
    fields: Sequence[str] | None = None,
    start: TimeLike | None = None,
    end: TimeLike | None = None,
    *,
    bulk: bool = True,
    query: Query | None = None,
) -> pa.Table:
    """The messages of ``topic`` as a ``pyarrow.Table``, in log-time order.

    Args:
        bag: a bag directory or a single ``.mcap``/``.db3`` file.
        topic: the topic name.
        fields: dotted paths or globs (``linear_acceleration.*``, ``header``); all leaves when
            None.
        start, end: the window ``start <= log_time < end``: seconds from the bag's first
            message, or absolute (epoch seconds >= 1e9, datetime, ISO 8601 string).
        bulk: decode fixed-layout messages in bulk (False: one by one, to cross-check).
        query: fields, times and a condition (:class:`~bagkit.selection.query.Query`), in
            place of ``fields``, ``start`` and ``end``; ``topic`` is the topic read.

    Columns: ``log_time`` and ``publish_time`` (int64 ns), then one per leaf field by its path
    (fixed arrays one column per element, variable-length sequences as lists).
    What could not be read is reported as a :class:`DataLossWarning`.

    Raises:
        BagError: the bag cannot be opened. UnknownTopicError, UnknownFieldError,
        UndecodableTopicError.
    """
    table, schema = _read(bag, topic_query(topic, fields, start, end, query), bulk=bulk)
    return table.to_arrow(schema)


def topic_query(
    topic: str,
    fields: Sequence[str] | None,
    start: TimeLike | None,
    end: TimeLike | None,
    query: Query | None,
) -> Query:
    """The query of a call that reads one topic: its keywords, or ``query`` for ``topic``.

    Raises:
        TypeError: both ``query`` and keywords are given.
        SelectionError: a time does not parse.
    """
    if query is None:
        return Query.create(topic, fields, start, end)
    if fields is not None or start is not None or end is not None:
        raise TypeError("give fields, start and end in the query or as keywords, not both")
    return query.with_topics(topic)


def _read(bag: str | Path, query: Query, *, bulk: bool) -> tuple[ColumnTable, pa.Schema]:
    with BagReader(bag, allow_empty=True) as reader:
        topics = resolve_names(query.topics, {n: i.type for n, i in reader.topics.items()})
        if len(topics) != 1:
            raise DataError(f"{', '.join(query.topics)} is several topics: {', '.join(topics)}")
        (topic,) = topics
        scan = plan_scan(reader, query, label=str(bag), bulk=bulk)
        if scan.outside is not None:
            warnings.warn(scan.outside, EmptyWindowWarning, stacklevel=3)
        if topic in scan.skipped:
            raise UndecodableTopicError(f"{topic} cannot be decoded: {scan.skipped[topic]}")
        table = scan.table(topic)
        for problem in scan.problems:
            warnings.warn(f"{bag}: {problem}", DataLossWarning, stacklevel=3)
    return table, scan.topics[topic].schema


def read_dataframe(
    bag: str | Path,
    topic: str,
    fields: Sequence[str] | None = None,
    start: TimeLike | None = None,
    end: TimeLike | None = None,
    *,
    bulk: bool = True,
    query: Query | None = None,
) -> pd.DataFrame:
    """The messages of ``topic`` as a ``pandas.DataFrame`` indexed by log time.

    The columns of :func:`read_arrow`; the index (named ``time``) is the log time as
    ``datetime64[ns]`` (UTC). Strings are pandas strings, list columns hold numpy arrays.

    Example:
        >>> imu = bagkit.read_dataframe("flight1", "/imu/data", ["linear_acceleration.*"])
        >>> imu["linear_acceleration.z"].resample("1s").mean()
    """
    table, schema = _read(bag, topic_query(topic, fields, start, end, query), bulk=bulk)
    return table.to_pandas(schema)
