"""Independent oracles: raw messages read with the mcap library / sqlite3, decoded by rosbags,
flattened by a plain recursive walk written here from the documented column rules."""

from __future__ import annotations

import math
import sqlite3
from collections.abc import Iterator
from pathlib import Path
from typing import Any

import numpy as np
from mcap.reader import make_reader
from rosbags.interfaces import Nodetype
from rosbags.typesys.base import normalize_fieldname
from rosbags.typesys.store import Typestore

UNSIGNED_OCTETS = ("byte", "char")


def raw_messages(bag: Path) -> Iterator[tuple[str, int, int, bytes]]:
    """(topic, log_time, publish_time, payload) of every message, in storage order."""
    files = (
        [bag]
        if bag.is_file()
        else sorted(p for p in bag.iterdir() if p.suffix in (".mcap", ".db3"))
    )
    for file in files:
        if file.suffix == ".mcap":
            with open(file, "rb") as f:
                for _, channel, message in make_reader(f).iter_messages(log_time_order=False):
                    yield channel.topic, message.log_time, message.publish_time, message.data
        else:
            db = sqlite3.connect(f"file:{file}?mode=ro&immutable=1", uri=True)
            query = (
                "SELECT t.name, m.timestamp, m.data FROM messages m "
                "JOIN topics t ON m.topic_id = t.id ORDER BY m.id"
            )
            # rosbag2's sqlite3 storage keeps no publish time: it is the log time.
            for name, timestamp, data in db.execute(query):
                yield name, timestamp, timestamp, bytes(data)
            db.close()


def flatten(msg: Any, ts: Typestore, typename: str) -> dict[str, Any]:
    """Leaf path -> value: the columns' rules, from a decoded rosbags message."""
    out: dict[str, Any] = {}
    _struct(out, msg, ts, typename, "", pooled=False)
    return out


def _scalar(value: Any, base: str) -> Any:
    if base == "bool":
        return bool(value)
    if base in UNSIGNED_OCTETS:
        return int(value) & 0xFF  # rosbags reads byte as int8; ROS 2 defines an octet
    if isinstance(value, np.generic):
        return value.item()
    return value


def _struct(
    out: dict[str, Any], msg: Any, ts: Typestore, typename: str, prefix: str, *, pooled: bool
) -> None:
    for name, desc in ts.fielddefs[typename][1]:
        _value(
            out, getattr(msg, normalize_fieldname(name)), desc, ts, f"{prefix}{name}", pooled=pooled
        )


def _value(
    out: dict[str, Any], value: Any, desc: Any, ts: Typestore, path: str, *, pooled: bool
) -> None:
    kind, rest = desc
    if kind == Nodetype.BASE:
        item = _scalar(value, rest[0])
        if pooled:
            out.setdefault(path, []).append(item)
        else:
            out[path] = item
    elif kind == Nodetype.NAME:
        _struct(out, value, ts, rest, f"{path}.", pooled=pooled)
    elif kind == Nodetype.ARRAY:
        for i, item in enumerate(value):
            _value(out, item, rest[0], ts, f"{path}[{i}]", pooled=pooled)
    else:
        key = f"{path}[]"
        out.setdefault(key, []) if rest[0][0] == Nodetype.BASE else None
        for item in value:
            _value(out, item, rest[0], ts, key, pooled=True)


def same(a: Any, b: Any) -> bool:
    """Equal values; NaN equals NaN; lists element-wise."""
    if isinstance(a, (list, tuple, np.ndarray)) or isinstance(b, (list, tuple, np.ndarray)):
        a, b = list(a), list(b)
        return len(a) == len(b) and all(same(x, y) for x, y in zip(a, b, strict=True))
    if isinstance(a, float) and isinstance(b, float) and math.isnan(a) and math.isnan(b):
        return True
    return type(a) is type(b) and a == b
