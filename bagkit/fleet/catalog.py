"""``bagkit catalog``: one row per bag and topic, in a Parquet file that is updated in place.

Each bag is described from its summary (MCAP summary section, ``metadata.yaml``), never from
its messages. A bag already in the catalogue whose files have the same total size and latest
modification time as when it was described is not reopened: its rows are carried over.
The catalogue describes exactly the bags found under the roots of the last update.

Columns: path, topic, type, count, start, end (UTC timestamps of the bag's first and last
message), duration (s), size (bytes of the bag's files), compression, problems (``""`` when
none), mtime_ns (with size, what tells an unchanged bag). A bag without topics, or that cannot
be read, has one row whose topic is empty and whose problems say why.
"""

from __future__ import annotations

import os
from collections.abc import Iterable
from dataclasses import dataclass
from pathlib import Path
from typing import TYPE_CHECKING, Any

import numpy as np
import pandas as pd

from bagkit.fleet.describe import COLUMNS, bag_stamp, describe_bag
from bagkit.fleet.errors import CatalogError
from bagkit.fleet.execute import ItemDone, readers_for, run_each
from bagkit.fleet.inputs import bag_paths
from bagkit.selection.errors import SelectionError
from bagkit.selection.fields import name_matches
from bagkit.selection.query import Query
from bagkit.selection.topics import absolute_topic_name, closest_names, meant_by
from bagkit.selection.windows import TimeRange

if TYPE_CHECKING:
    from distributed import Client

NAT_NS = np.iinfo(np.int64).min


def _utc(values: list[Any]) -> pd.Series:
    # Through int64 (NaT is its minimum): a float column would round the nanoseconds away.
    ns = np.array([NAT_NS if v is None else v for v in values], dtype=np.int64)
    return pd.Series(ns.view("datetime64[ns]")).dt.tz_localize("UTC")


def to_frame(rows: Iterable[dict[str, Any]]) -> pd.DataFrame:
    """The catalogue DataFrame of ``rows``, with its column types."""
    rows = list(rows)
    columns = {name: [row[name] for row in rows] for name in COLUMNS}
    types = {
        "path": "string",
        "topic": "string",
        "type": "string",
        "count": "Int64",
        "duration": "float64",
        "size": "int64",
        "compression": "string",
        "problems": "string",
        "mtime_ns": "int64",
    }
    data = {
        name: _utc(values) if name in ("start", "end") else pd.Series(values, dtype=types[name])
        for name, values in columns.items()
    }
    return pd.DataFrame(data, columns=COLUMNS)


def read_catalog(path: str | Path) -> pd.DataFrame:
    """A catalogue written by :func:`write_catalog`.

    Raises:
        CatalogError: the file is not a readable catalogue.
    """
    import pyarrow.parquet as pq

    try:
        # One file: ParquetFile, without pd.read_parquet's dataset machinery, which was much
        # of an unchanged update's time (benchmarks/README.md "fleet"); the frame is the same.
        frame = pq.ParquetFile(path).read().to_pandas()
    except (OSError, ValueError) as exc:
        raise CatalogError(f"{path}: not a readable Parquet catalogue ({exc})") from None
    missing = [c for c in COLUMNS if c not in frame.columns]
    if missing:
        raise CatalogError(f"{path}: not a bagkit catalogue (no column {', '.join(missing)})")
    return frame


def write_catalog(frame: pd.DataFrame, path: str | Path) -> None:
    """Write ``frame`` to ``path`` atomically (a reader never sees half a file)."""
    path = Path(path)
    partial = path.with_name(f".{path.name}.partial")
    try:
        frame.to_parquet(partial, index=False)
        os.replace(partial, path)
    except OSError as exc:
        partial.unlink(missing_ok=True)
        raise CatalogError(f"cannot write {path}: {exc.strerror or exc}") from None


@dataclass(frozen=True, slots=True)
class CatalogPlan:
    """What an update has to do: the bags found, the rows kept, the bags to (re)open."""

    bags: list[str]
    kept: pd.DataFrame
    to_open: list[str]
    removed: int


def plan_update(roots: Iterable[str | Path], output: str | Path) -> CatalogPlan:
    """Find the bags under ``roots`` and those of them the catalogue at ``output`` lacks or
    describes as they were before a change."""
    bags = bag_paths(roots)
    old = read_catalog(output) if Path(output).exists() else to_frame([])
    known: dict[str, tuple[int, int]] = {}
    for path, size, mtime in zip(
        old["path"].tolist(), old["size"].tolist(), old["mtime_ns"].tolist(), strict=True
    ):
        known.setdefault(path, (size, mtime))  # the rows of one bag share its stamp
    unchanged = {bag for bag in bags if known.get(bag) == bag_stamp(bag)}
    kept = old[old["path"].isin(unchanged)]
    to_open = [bag for bag in bags if bag not in unchanged]
    removed = len(set(known) - set(bags))
    return CatalogPlan(bags, kept, to_open, removed)


def complete_update(
    plan: CatalogPlan, client: Client | None, done: ItemDone | None = None
) -> pd.DataFrame:
    """The updated catalogue: ``plan``'s kept rows and those of the bags it opens, in bag order.

    Args:
        done: called with the index (in ``plan.to_open``) of each bag described.
    """
    threads = readers_for(plan.to_open)  # in storage: a few requests each, mostly waiting
    described = run_each(describe_bag, plan.to_open, client, done, threads=threads)
    new = to_frame(row for rows in described for row in rows)
    frame = pd.concat([plan.kept, new], ignore_index=True) if len(plan.kept) else new
    order = {bag: i for i, bag in enumerate(plan.bags)}
    frame = frame.sort_values("path", key=lambda p: p.map(order), kind="stable")
    return frame.reset_index(drop=True)


def unreadable(frame: pd.DataFrame) -> dict[str, str]:
    """Path -> why, for the bags of ``frame`` that could not be read: their one row has no
    compression (a bag that was read has one, ``""`` when it holds no chunk)."""
    rows = frame[frame["compression"].isna()]
    return dict(zip(rows["path"].tolist(), rows["problems"].fillna("").tolist(), strict=True))


def query(frame: pd.DataFrame, selection: Query | None = None) -> pd.DataFrame:
    """Rows of bags holding messages on ``selection``'s topics within its time range.

    A topic is a name (``imu/data`` is ``/imu/data``; a service's or an action's name stands
    for its topics) or a glob (``/gps/*``, as in :mod:`bagkit.selection.fields`); the times
    are absolute (a catalogue spans many bags: no bag start to count from).

    Raises:
        SelectionError: a time that is not absolute.
    """
    selection = selection or Query()
    keep = frame["count"].fillna(0) > 0
    if selection.topics:
        keep &= _named(frame, selection.topics)
    low, high = absolute_window(selection.span)
    if low is not None:
        keep &= frame["end"] >= low
    if high is not None:
        keep &= frame["start"] <= high
    return frame[keep].reset_index(drop=True)


def unknown_topics(frame: pd.DataFrame, selection: Query) -> list[str]:
    """``selection``'s topics that no bag of the catalogue has, each with the closest names."""
    known = sorted(set(frame["topic"].dropna()))
    return [
        f"no bag of the catalogue has {topic} ({closest_names(topic, known)})"
        for topic in selection.topics
        if not _named(frame, [topic]).any()
    ]


def _named(frame: pd.DataFrame, topics: Iterable[str]) -> pd.Series:
    """Rows on one of ``topics`` (globs; a service's or an action's name stands for its
    topics)."""
    patterns = [pattern for topic in topics for pattern in meant_by(topic)]
    names = frame["topic"].fillna("").map(absolute_topic_name)
    return names.map(lambda name: any(name_matches(name, p) for p in patterns))


def absolute_window(span: TimeRange) -> tuple[pd.Timestamp | None, pd.Timestamp | None]:
    """``--start``/``--end`` of a catalogue query as UTC timestamps (an open side None).

    Raises:
        SelectionError: a time that is not absolute.
    """
    sides = []
    for side, point in (("start", span.start), ("end", span.end)):
        if point is not None and not point.absolute:
            raise SelectionError(
                f"bad --{side} '{point.ns / 1e9:g}': a catalogue query takes absolute times "
                "(ISO 8601 or epoch seconds), not seconds from a bag's start or end"
            )
        sides.append(None if point is None else pd.Timestamp(point.ns, unit="ns", tz="UTC"))
    return sides[0], sides[1]
