"""``read_arrow`` and ``read_dataframe``: one topic of a bag as a table, for notebooks."""

from __future__ import annotations

import warnings
from collections.abc import Sequence
from pathlib import Path
from typing import TYPE_CHECKING

import pyarrow as pa

from bagkit.bag import BagReader
from bagkit.data.errors import UndecodableTopicError
from bagkit.data.scan import plan_scan
from bagkit.data.table import ColumnTable
from bagkit.selection.errors import EmptyWindowWarning
from bagkit.selection.times import TimeLike
from bagkit.selection.topics import require_topics
from bagkit.selection.windows import TimeRange

if TYPE_CHECKING:
    import pandas as pd


class DataLossWarning(UserWarning):
    """Part of the bag could not be read (a salvaged file, messages that do not decode)."""


def read_arrow(
    bag: str | Path,
    topic: str,
    fields: Sequence[str] | None = None,
    start: TimeLike | None = None,
    end: TimeLike | None = None,
    *,
    bulk: bool = True,
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

    Columns: ``log_time`` and ``publish_time`` (int64 ns), then one per leaf field by its path
    (fixed arrays one column per element, variable-length sequences as lists).
    What could not be read is reported as a :class:`DataLossWarning`.

    Raises:
        BagError: the bag cannot be opened. UnknownTopicError, UnknownFieldError,
        UndecodableTopicError.
    """
    table, schema = _read(bag, topic, fields, start, end, bulk=bulk)
    return table.to_arrow(schema)


def _read(
    bag: str | Path,
    topic: str,
    fields: Sequence[str] | None,
    start: TimeLike | None,
    end: TimeLike | None,
    *,
    bulk: bool,
) -> tuple[ColumnTable, pa.Schema]:
    span = TimeRange.parse(start, end)
    with BagReader(bag, allow_empty=True) as reader:
        (topic,) = require_topics([topic], reader.topics)
        scan = plan_scan(reader, [topic], fields, span, label=str(bag), bulk=bulk)
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
) -> pd.DataFrame:
    """The messages of ``topic`` as a ``pandas.DataFrame`` indexed by log time.

    The columns of :func:`read_arrow`; the index (named ``time``) is the log time as
    ``datetime64[ns]`` (UTC). Strings are pandas strings, list columns hold numpy arrays.

    Example:
        >>> imu = bagkit.read_dataframe("flight1", "/imu/data", ["linear_acceleration.*"])
        >>> imu["linear_acceleration.z"].resample("1s").mean()
    """
    table, schema = _read(bag, topic, fields, start, end, bulk=bulk)
    return table.to_pandas(schema)
