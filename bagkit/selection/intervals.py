"""Sets of closed log-time intervals ``[start, end]`` (int64 ns, shape (n, 2)), and their algebra.

A set is *normal*: sorted, and no two intervals overlap or touch (``next.start > end + 1``).
Log times are integers, so the complement of a closed set is closed again, and ``and``, ``or``
and ``not`` of conditions are :func:`intersect`, :func:`union` and :func:`complement`.
"""

from __future__ import annotations

import numpy as np

NONE = np.zeros((0, 2), dtype=np.int64)
"""The empty set (copy before changing)."""


def normal(spans: np.ndarray) -> np.ndarray:
    """``spans`` (any order, overlapping) as a normal set."""
    spans = np.asarray(spans, dtype=np.int64).reshape(-1, 2)
    if len(spans) < 2:
        return spans.copy()
    spans = spans[np.lexsort((spans[:, 1], spans[:, 0]))]
    reach = np.maximum.accumulate(spans[:, 1])
    # A new interval opens where it starts beyond everything before it (and one past it).
    opens = np.concatenate(([True], spans[1:, 0] > reach[:-1] + 1))
    starts = spans[opens, 0]
    closes = np.concatenate((np.flatnonzero(opens)[1:] - 1, [len(spans) - 1]))
    return np.stack([starts, reach[closes]], axis=1)


def union(*sets: np.ndarray) -> np.ndarray:
    """Where any of ``sets`` holds."""
    return normal(np.concatenate([NONE, *sets]))


def intersect(a: np.ndarray, b: np.ndarray) -> np.ndarray:
    """Where both normal sets hold."""
    if not len(a) or not len(b):
        return NONE.copy()
    # For each interval of a, the intervals of b that can overlap it (b is sorted and disjoint).
    first = np.searchsorted(b[:, 1], a[:, 0], side="left")
    last = np.searchsorted(b[:, 0], a[:, 1], side="right")
    counts = np.maximum(last - first, 0)
    rows = np.repeat(np.arange(len(a)), counts)
    offsets = np.arange(counts.sum()) - np.repeat(np.cumsum(counts) - counts, counts)
    other = np.repeat(first, counts) + offsets
    starts = np.maximum(a[rows, 0], b[other, 0])
    ends = np.minimum(a[rows, 1], b[other, 1])
    keep = starts <= ends
    return np.stack([starts[keep], ends[keep]], axis=1).astype(np.int64, copy=False)


def complement(a: np.ndarray, start: int, end: int) -> np.ndarray:
    """Where the normal set ``a`` does not hold, within ``[start, end]``."""
    bounds = np.concatenate(([start - 1], a.reshape(-1), [end + 1])).reshape(-1, 2)
    spans = np.stack([bounds[:, 0] + 1, bounds[:, 1] - 1], axis=1)
    spans = spans[spans[:, 0] <= spans[:, 1]]
    spans = np.clip(spans, start, end)
    return spans[spans[:, 0] <= spans[:, 1]].astype(np.int64, copy=False)


def lasting(a: np.ndarray, ns: int) -> np.ndarray:
    """The intervals of ``a`` lasting at least ``ns`` (``end - start >= ns``)."""
    return a[a[:, 1] - a[:, 0] >= ns]


def runs(log_times: np.ndarray, mask: np.ndarray, until: np.ndarray | None = None) -> np.ndarray:
    """The runs of consecutive messages where ``mask`` holds, as intervals from the first
    message of a run to its last, or (``until`` given) to ``until`` of its last message (a
    state holds until the next message changes it)."""
    flags = np.concatenate(([False], np.asarray(mask, dtype=bool), [False]))
    edges = np.diff(flags.astype(np.int8))
    firsts = np.flatnonzero(edges == 1)
    lasts = np.flatnonzero(edges == -1) - 1
    ends = log_times[lasts] if until is None else until[lasts]
    return normal(np.stack([log_times[firsts], ends], axis=1))


def contains(spans: np.ndarray, times: np.ndarray) -> np.ndarray:
    """Whether each of ``times`` is inside an interval of the normal set ``spans``."""
    times = np.asarray(times, dtype=np.int64)
    at = np.searchsorted(spans[:, 0], times, side="right") - 1
    inside = at >= 0
    inside[inside] = times[inside] <= spans[at[inside], 1]
    return inside


def holds_at(spans: np.ndarray, time: int) -> bool:
    """Whether ``time`` is inside an interval of the normal set ``spans``."""
    return bool(contains(spans, np.array([time]))[0])
