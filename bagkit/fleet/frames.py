"""``bagkit.fleet.dataframe``: one topic of many bags as a lazy Dask DataFrame.

One partition per bag, read on the workers by ``bagkit.read_dataframe`` (the same decoder as
``bagkit stats``) with one :class:`~bagkit.selection.query.Query`, parsed once on the driver.
The columns and dtypes (Dask's ``meta``) are those of the first bag's frame.
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


def read_partition(bag: str, query: Query) -> pd.DataFrame:
    """One bag's frame of the query's one topic (what each task computes)."""
    from bagkit.data import read_dataframe

    (topic,) = query.topics
    return read_dataframe(bag, topic, query=query)


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
        BagError and the errors of ``read_dataframe``: the first bag cannot be read.
        MissingExtraError: Dask (the fleet extra) is not installed.
    """
    require(FLEET, "bagkit.fleet.dataframe")
    import dask.dataframe as dd

    from bagkit.data.frames import topic_query

    asked = topic_query(topic, fields, start, end, query)
    paths = [location(bag) for bag in expand_bags(bags)]
    meta = read_partition(paths[0], asked).iloc[:0]
    return dd.from_map(read_partition, paths, query=asked, meta=meta, label="bagkit-read-topic")
