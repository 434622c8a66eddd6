"""``bagkit.fleet.dataframe``: one topic of many bags as a lazy Dask DataFrame.

One partition per bag, read on the workers by ``bagkit.read_dataframe`` (the same decoder as
``bagkit stats``). The columns and dtypes (Dask's ``meta``) are those of the first bag's frame.
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


def read_partition(bag: str, topic: str, fields: Sequence[str] | None) -> pd.DataFrame:
    """One bag's frame of ``topic`` (what each task computes)."""
    from bagkit.data import read_dataframe

    return read_dataframe(bag, topic, fields=list(fields) if fields is not None else None)


def dataframe(
    bags: Iterable[str | Path], topic: str, fields: Sequence[str] | None = None
) -> dd.DataFrame:
    """A lazy Dask DataFrame of ``topic`` over ``bags``, one partition per bag.

    Args:
        bags: bags, directories searched for bags, globs or listings (as ``bagkit`` takes).
        topic: the topic read from every bag.
        fields: field paths or globs, as ``bagkit.read_dataframe`` takes them (all when None).

    ``compute()`` runs on the active ``distributed.Client`` when there is one. Example::

        df = bagkit.fleet.dataframe(["flights/"], "/imu/data", ["linear_acceleration.z"])
        df["linear_acceleration.z"].max().compute()

    Raises:
        NoBagsError: ``bags`` names no bag.
        BagError and the errors of ``read_dataframe``: the first bag cannot be read.
        MissingExtraError: Dask (the fleet extra) is not installed.
    """
    require(FLEET, "bagkit.fleet.dataframe")
    import dask.dataframe as dd

    paths = [location(bag) for bag in expand_bags(bags)]
    chosen = tuple(fields) if fields is not None else None
    meta = read_partition(paths[0], topic, chosen).iloc[:0]
    return dd.from_map(
        read_partition, paths, topic=topic, fields=chosen, meta=meta, label="bagkit-read-topic"
    )
