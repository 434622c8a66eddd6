"""Where a broken assertion can be looked at: commands that replay or cut it, a Foxglove link.

The commands are those ``bagkit play`` and ``bagkit filter`` accept as printed (tests run
them). The Foxglove link needs to know where the bags are served over HTTP(S): the base URL
under which a bag's path, as given to ``check``, is found (``--bags-url`` or the
``BAGKIT_BAGS_URL`` environment variable); without one there is no link.
"""

from __future__ import annotations

import datetime as dt
import os
from collections.abc import Sequence
from pathlib import Path
from urllib.parse import quote, urlencode

from bagkit.bag.storage_files import STORAGE_SUFFIXES
from bagkit.storage.urls import is_url, path_part

BAGS_URL_ENV = "BAGKIT_BAGS_URL"
CONTEXT_S = 5
"""Seconds of context before and after a broken span in the commands."""
FOXGLOVE_APP = "https://app.foxglove.dev/~/view"


def play_command(bag: str, start_ns: int, bag_start_ns: int) -> str:
    """``bagkit play`` from CONTEXT_S before ``start_ns``."""
    import shlex  # here: a healthy bag's check starts without it

    offset = max(start_ns - bag_start_ns - CONTEXT_S * 1_000_000_000, 0) / 1e9
    return f"bagkit play {shlex.quote(bag)} --start-offset {offset:.3f}"


def filter_command(bag: str, topic: str, condition: str) -> str:
    """``bagkit filter --around`` the episodes of ``TOPIC: CONDITION``, with context."""
    import shlex  # here: a healthy bag's check starts without it

    around = shlex.quote(f"{topic}: {condition}")
    name = Path(path_part(bag)).name
    if name.endswith((*STORAGE_SUFFIXES, ".bag")):  # a bag file: planted.mcap -> planted_cuts
        name = Path(name).stem
    out = shlex.quote(f"{name}_cuts")
    return (
        f"bagkit filter {shlex.quote(bag)} -o {out} --around {around} "
        f"--before {CONTEXT_S} --after {CONTEXT_S}"
    )


def bags_url(given: str | None = None) -> str | None:
    """Where bags are served: ``given``, else ``$BAGKIT_BAGS_URL``, else None."""
    return given or os.environ.get(BAGS_URL_ENV) or None


def foxglove_link(
    base_url: str, bag: str, time_ns: int, files: Sequence[tuple[int, str]] = ()
) -> str:
    """Foxglove opening ``bag``'s MCAP file (served under ``base_url``) that holds ``time_ns``:
    of ``files`` (each file's first log time and name, in time order) the last starting at or
    before it; without them, the bag's first. A bag in storage (``s3://bucket/key``) is found
    under ``base_url`` by its bucket (or host) and key."""
    url_bag = is_url(bag)
    path = Path(path_part(bag).partition("://")[2] if url_bag else bag)
    if files and path.name not in (name for _, name in files):  # a bag directory
        holding = [name for start, name in files if start <= time_ns]
        path = path / (holding[-1] if holding else files[0][1])
    elif not url_bag and path.is_dir():
        found = sorted(path.glob("*.mcap"))
        path = found[0] if found else path
    relative = path.as_posix().lstrip("/")
    url = f"{base_url.rstrip('/')}/{quote(relative)}"
    stamp = dt.datetime.fromtimestamp(time_ns // 1_000_000_000, tz=dt.timezone.utc)
    when = stamp.strftime("%Y-%m-%dT%H:%M:%S") + f".{time_ns % 1_000_000_000:09d}Z"
    return f"{FOXGLOVE_APP}?{urlencode({'ds': 'remote-file', 'ds.url': url, 'time': when})}"
