"""A plain recursive flattener: the oracle for bagkit's generated one (same path rules)."""

from __future__ import annotations

from typing import Any

import numpy as np
from rosbags.interfaces import Nodetype
from rosbags.typesys.base import normalize_fieldname
from rosbags.typesys.store import Typestore

from bagkit.decode import leaf_fields


def reference_flatten(msg: Any, ts: Typestore, *, numeric_only: bool = False) -> dict[str, Any]:
    typename = msg.__msgtype__
    leaves = leaf_fields(ts, typename)
    out: dict[str, Any] = {leaf.path: [] if leaf.pooled else None for leaf in leaves}
    _struct(out, "", msg, typename, ts, pooled=False)
    if numeric_only:
        return {leaf.path: out[leaf.path] for leaf in leaves if leaf.numeric}
    return out


def _scalar(value: Any) -> Any:
    if isinstance(value, (bool, np.bool_)):
        return int(value)
    if isinstance(value, np.generic):
        return value.item()
    return value


def _struct(
    out: dict[str, Any], prefix: str, msg: Any, typename: str, ts: Typestore, *, pooled: bool
) -> None:
    for name, desc in ts.fielddefs[typename][1]:
        value = getattr(msg, normalize_fieldname(name))
        _value(out, f"{prefix}{name}", value, desc, ts, pooled=pooled)


def _value(
    out: dict[str, Any], path: str, value: Any, desc: Any, ts: Typestore, *, pooled: bool
) -> None:
    kind, rest = desc
    if kind == Nodetype.BASE:
        if pooled:
            out[path].append(_scalar(value))
        else:
            out[path] = _scalar(value)
    elif kind == Nodetype.NAME:
        _struct(out, f"{path}.", value, rest, ts, pooled=pooled)
    elif kind == Nodetype.ARRAY:
        for i, item in enumerate(value):
            _value(out, f"{path}[{i}]", item, rest[0], ts, pooled=pooled)
    else:
        sub = rest[0]
        key = f"{path}[]"
        if sub[0] == Nodetype.BASE and not pooled:
            if isinstance(value, np.ndarray):
                out[key] = value.astype(np.uint8) if value.dtype == np.bool_ else value
            else:
                out[key] = [_scalar(v) for v in value]
            return
        for item in value:
            _value(out, key, item, sub, ts, pooled=True)
