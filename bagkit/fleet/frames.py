"""``bagkit.fleet.dataframe``: one topic of many bags as a lazy Dask DataFrame.

One partition per bag, read on the workers by ``bagkit.read_dataframe`` (the same decoder as
``bagkit stats``) with one :class:`~bagkit.selection.query.Query`, parsed once on the driver.
The columns and dtypes (Dask's ``meta``) are those of the first bag's frame that has the
topic; a bag without it is an empty partition.
"""

from __future__ import annotations

from collections.abc import Iterable, Sequence
from pathlib import Path
from typing import TYPE_CHECKING

from bagkit.extras import FLEET, require
from bagkit.fleet.inputs import expand_bags
from bagkit.storage.urls import location

if TYPE_CHECKING:
    import dask.dataframe as dd
    import pandas as pd

    from bagkit.selection.query import Query
    from bagkit.selection.times import TimeLike


def read_partition(bag: str, query: Query, empty: pd.DataFrame | None = None) -> pd.DataFrame:
    """One bag's frame of the query's one topic (what each task computes); ``empty`` (the
    frame's meta) for a bag without the topic, as every fleet command skips it."""
    from bagkit.data import read_dataframe
    from bagkit.selection.errors import UnknownTopicError

    (topic,) = query.topics
    try:
        return read_dataframe(bag, topic, query=query)
    except UnknownTopicError:
        if empty is None:
            raise
        return empty


def _meta(paths: list[str], query: Query) -> pd.DataFrame:
    """The columns and dtypes of the first bag that has the topic (its error if none has)."""
    from bagkit.selection.errors import UnknownTopicError

    first: UnknownTopicError | None = None
    for path in paths:
        try:
            return read_partition(path, query).iloc[:0]
        except UnknownTopicError as exc:
            first = first or exc
    assert first is not None  # expand_bags names a bag at least
    raise first


def dataframe(
    bags: Iterable[str | Path],
    topic: str,
    fields: Sequence[str] | None = None,
    start: TimeLike | None = None,
    end: TimeLike | None = None,
    *,
    query: Query | None = None,
) -> dd.DataFrame:
    """A lazy Dask DataFrame of ``topic`` over ``bags``, one partition per bag.

    Args:
        bags: bags, directories searched for bags, globs or listings (as ``bagkit`` takes).
        topic: the topic read from every bag.
        fields, start, end, query: as ``bagkit.read_dataframe`` takes them (all fields and
            times when none is given); a window outside a bag warns for that bag.

    ``compute()`` runs on the active ``distributed.Client`` when there is one. Example::

        df = bagkit.fleet.dataframe(["flights/"], "/imu/data", ["linear_acceleration.z"])
        df["linear_acceleration.z"].max().compute()

    Raises:
        NoBagsError: ``bags`` names no bag.
        SelectionError: a time or the query's condition does not parse.
        UnknownTopicError: no bag has ``topic``.
        BagError and the errors of ``read_dataframe``: the first bag cannot be read.
        MissingExtraError: Dask (the fleet extra) is not installed.
    """
    require(FLEET, "bagkit.fleet.dataframe")
    import dask.dataframe as dd

    from bagkit.data.frames import topic_query

    asked = topic_query(topic, fields, start, end, query)
    paths = [location(bag) for bag in expand_bags(bags)]
    meta = _meta(paths, asked)
    return dd.from_map(
        read_partition, paths, query=asked, empty=meta, meta=meta, label="bagkit-read-topic"
    )
