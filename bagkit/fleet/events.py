"""Named events in a catalogue: ``--events NAME='TOPIC: CONDITION'`` and their episodes.

Beside ``catalog.parquet``, ``catalog.events.parquet`` holds one row per episode of each named
event in each bag (:mod:`bagkit.fleet.find`), and one row with ``count`` 0 for a bag searched
without finding one, so that an update searches only the bags that changed, and every bag
again when an event's condition changes. ``catalog query --event NAME`` asks which bags had it.
"""

from __future__ import annotations

import re
from collections.abc import Sequence
from pathlib import Path
from typing import TYPE_CHECKING

import numpy as np
import pandas as pd

from bagkit.fleet.catalog import NAT_NS, CatalogPlan, absolute_window, write_catalog
from bagkit.fleet.errors import CatalogError
from bagkit.fleet.execute import ItemDone, run_each
from bagkit.fleet.find import BagEpisodes, episodes_in_bag
from bagkit.selection.conditions import parse_topic_condition
from bagkit.selection.errors import SelectionError
from bagkit.selection.query import Query

if TYPE_CHECKING:
    from distributed import Client

EVENT_COLUMNS = ("event", "when", "path", "topic", "start", "end", "count")
_NAME = re.compile(r"[A-Za-z_][A-Za-z0-9_.-]*")


def events_path(catalog: str | Path) -> Path:
    """``flights.events.parquet`` beside ``flights.parquet``."""
    catalog = Path(catalog)
    return catalog.with_name(f"{catalog.stem}.events.parquet")


def parse_events(specs: Sequence[str]) -> dict[str, str]:
    """``NAME='TOPIC: CONDITION'`` options -> {name: condition text}, each checked.

    Raises:
        SelectionError: no ``NAME=``, a name given twice (these name the ``events`` field),
            or a condition that does not parse.
    """
    events: dict[str, str] = {}
    for spec in specs:
        name, sep, when = spec.partition("=")
        name = name.strip()
        if not sep or not _NAME.fullmatch(name):
            raise SelectionError(f"{spec!r}: expected NAME='TOPIC: CONDITION'", "events")
        if name in events:
            raise SelectionError(f"names {name!r} twice", "events")
        events[name] = parse_topic_condition(when).text
    return events


def read_events(path: str | Path) -> pd.DataFrame:
    """The events file beside a catalogue (empty when there is none).

    Raises:
        CatalogError: the file is not readable.
    """
    if not Path(path).exists():
        return _frame([])
    try:
        return pd.read_parquet(path)
    except (OSError, ValueError) as exc:
        raise CatalogError(f"{path}: not a readable events file ({exc})") from None


def update_events(
    plan: CatalogPlan,
    events: dict[str, str],
    catalog: Path,
    client: Client | None,
    done: ItemDone | None = None,
) -> pd.DataFrame:
    """Search the bags of ``plan`` for ``events`` and write the events file beside ``catalog``.

    A bag unchanged since it was searched for the same condition is not searched again.
    """
    path = events_path(catalog)
    old = read_events(path)
    rows: list[dict[str, object]] = []
    kept = [_frame([])]
    jobs: list[tuple[str, str, str]] = []
    for name, when in events.items():
        known = old[(old["event"] == name) & (old["when"] == when)]
        unchanged = set(known["path"]) - set(plan.to_open)
        kept.append(known[known["path"].isin(unchanged) & known["path"].isin(plan.bags)])
        jobs += [(name, when, bag) for bag in plan.bags if bag not in unchanged]
    found = run_each(_search, jobs, client, done)
    for (name, when, bag), part in zip(jobs, found, strict=True):
        rows += _rows(name, when, bag, part)
    frame = pd.concat([*kept, _frame(rows)], ignore_index=True)
    order = {bag: i for i, bag in enumerate(plan.bags)}
    frame = frame.sort_values(
        ["event", "path", "start"], key=lambda c: c.map(order) if c.name == "path" else c
    ).reset_index(drop=True)
    write_catalog(frame, path)
    return frame


def _search(job: tuple[str, str, str]) -> BagEpisodes:
    """One task: one bag searched for one event (name, condition, bag)."""
    _, when, bag = job
    return episodes_in_bag(bag, when=when)


def _rows(name: str, when: str, bag: str, part: BagEpisodes) -> list[dict[str, object]]:
    topic = parse_topic_condition(when).topic
    if not len(part.spans):  # searched, nothing found (or not readable): count 0
        return [dict(event=name, when=when, path=bag, topic=topic, start=None, end=None, count=0)]
    return [
        dict(
            event=name,
            when=when,
            path=bag,
            topic=topic,
            start=start,
            end=end,
            count=count,
        )
        for start, end, count in part.spans.tolist()
    ]


def _frame(rows: list[dict[str, object]]) -> pd.DataFrame:
    columns = {name: [row[name] for row in rows] for name in EVENT_COLUMNS}
    data: dict[str, pd.Series] = {}
    for name, values in columns.items():
        if name in ("start", "end"):
            ns = np.array([NAT_NS if v is None else v for v in values], dtype=np.int64)
            data[name] = pd.Series(ns.view("datetime64[ns]")).dt.tz_localize("UTC")
        else:
            data[name] = pd.Series(values, dtype="int64" if name == "count" else "string")
    return pd.DataFrame(data, columns=list(EVENT_COLUMNS))


def query_events(frame: pd.DataFrame, event: str, selection: Query | None = None) -> pd.DataFrame:
    """The episodes of ``event`` overlapping ``selection``'s time range (absolute times; either
    side may be open), in bag order.

    Raises:
        CatalogError: the catalogue holds no event of that name. SelectionError: a time that
        is not absolute.
    """
    if not (frame["event"] == event).any():
        names = ", ".join(sorted(set(frame["event"]))) or "none"
        raise CatalogError(f"no event {event!r} in the catalogue (it has: {names})")
    keep = (frame["event"] == event) & (frame["count"] > 0)
    low, high = absolute_window((selection or Query()).span)
    if low is not None:
        keep &= frame["end"] >= low
    if high is not None:
        keep &= frame["start"] <= high
    return frame[keep].reset_index(drop=True)
