"""Random messages of any rosbags type, and equality of decoded values, for the decode tests."""

from __future__ import annotations

from typing import Any

import numpy as np
from rosbags.interfaces import Nodetype
from rosbags.typesys import Stores, get_typestore
from rosbags.typesys.store import Typestore

JAZZY = get_typestore(Stores.ROS2_JAZZY)
_NUMPY = {
    "bool": np.bool_,
    "byte": np.uint8,
    "char": np.uint8,
    "int8": np.int8,
    "uint8": np.uint8,
    "int16": np.int16,
    "uint16": np.uint16,
    "int32": np.int32,
    "uint32": np.uint32,
    "int64": np.int64,
    "uint64": np.uint64,
    "float32": np.float32,
    "float64": np.float64,
}


def _random_primitives(rng: np.random.Generator, base: str, n: int) -> np.ndarray:
    dtype = np.dtype(_NUMPY[base])
    if dtype.kind == "b":
        return rng.integers(0, 2, n).astype(bool)
    if dtype.kind == "f":
        values = rng.normal(0, 1e3, n).astype(dtype)
        values[rng.random(n) < 0.1] = np.nan
        return values
    info = np.iinfo(dtype)
    return rng.integers(info.min, info.max, n, dtype=dtype, endpoint=True)


def _random_string(rng: np.random.Generator) -> str:
    return "".join(chr(c) for c in rng.integers(97, 123, int(rng.integers(0, 13))))


def _random_value(ts: Typestore, desc: Any, rng: np.random.Generator) -> Any:
    kind, rest = desc
    if kind == Nodetype.BASE:
        if rest[0] == "string":
            return _random_string(rng)
        value = _random_primitives(rng, rest[0], 1)[0]
        return bool(value) if rest[0] == "bool" else value.item()
    if kind == Nodetype.NAME:
        return random_message(ts, rest, rng)
    sub, bound = rest
    n = bound if kind == Nodetype.ARRAY else int(rng.integers(0, (bound or 6) + 1))
    if sub[0] == Nodetype.BASE and sub[1][0] != "string":
        return _random_primitives(rng, sub[1][0], n)
    return [_random_value(ts, sub, rng) for _ in range(n)]


def random_message(ts: Typestore, typename: str, rng: np.random.Generator) -> object:
    """A message of ``typename`` with random values, strings and sequence lengths."""
    fields = {name: _random_value(ts, desc, rng) for name, desc in ts.fielddefs[typename][1]}
    return ts.types[typename](**fields)


def same(a: Any, b: Any) -> bool:
    return bool(
        np.array_equal(np.asarray(a, dtype=float), np.asarray(b, dtype=float), equal_nan=True)
    )


def flat_equal(a: Any, b: Any) -> bool:
    if type(a) is not type(b):
        return False
    if isinstance(a, np.ndarray):
        return a.dtype == b.dtype and bool(np.array_equal(a, b, equal_nan=True))
    if isinstance(a, list):
        return len(a) == len(b) and all(flat_equal(x, y) for x, y in zip(a, b, strict=True))
    if isinstance(a, float):
        return a == b or (np.isnan(a) and np.isnan(b))
    return bool(a == b)
