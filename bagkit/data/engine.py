"""The decoding engine this package stands on, imported in this one module.

Three ideas live elsewhere in bagkit and are only re-exported here, so that moving them (the
bulk decoder into ``bagkit.decode``, the field-glob matcher into its own module, payload spans
into ``BagChunk``) is a change of this file alone:

- :func:`payload_spans`: where each message of a topic is in a decompressed chunk;
- :func:`decode_bulk`: fixed-layout payloads decoded at once into numpy structured arrays;
- :func:`field_matcher`: the glob language of ``--fields`` (``*``, ``?``, brackets literal).
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from bagkit.bag.mcap import MESSAGE_DATA_OFFSET, MESSAGE_PREFIX
from bagkit.stats.bulk import BulkGroup, decode_bulk, gather, read_u32, read_u64
from bagkit.stats.summary import field_matcher

__all__ = [
    "BulkGroup",
    "Spans",
    "decode_bulk",
    "field_matcher",
    "gather",
    "payload_spans",
    "read_u32",
]

# In an MCAP Message record the payload directly follows publish_time (u64).
_PUBLISH_TIME_BEFORE_DATA = 8


@dataclass(frozen=True, slots=True)
class Spans:
    """The messages of one topic in one chunk, in log-time order (ties in storage order).

    Attributes:
        log_times, publish_times: ns (int64).
        starts, lengths: payload offsets and sizes in the chunk's records (int64).
        dropped: index entries that point outside the chunk (a corrupt index), left out.
    """

    log_times: np.ndarray
    publish_times: np.ndarray
    starts: np.ndarray
    lengths: np.ndarray
    dropped: int = 0


def payload_spans(
    buf: np.ndarray, index: np.ndarray, start_ns: int | None, end_ns: int | None
) -> Spans:
    """Spans of the messages of ``index`` (a chunk's message-index entries of one topic).

    Args:
        buf: the chunk's decompressed records as ``uint8``.
        index: ``log_time``/``offset`` entries.
        start_ns, end_ns: keep ``start_ns <= log_time < end_ns`` (None: unbounded).
    """
    log_times = index["log_time"].astype(np.int64)
    keep = np.ones(len(index), dtype=bool)
    if start_ns is not None:
        keep &= log_times >= start_ns
    if end_ns is not None:
        keep &= log_times < end_ns
    offsets = index["offset"].astype(np.int64)[keep]
    log_times = log_times[keep]
    # An index is read from the file: entries must lie inside the records they index.
    inside = (offsets >= 0) & (offsets + MESSAGE_DATA_OFFSET <= len(buf))
    starts = offsets[inside] + MESSAGE_DATA_OFFSET
    lengths = read_u64(buf, offsets[inside] + 1).astype(np.int64) - MESSAGE_PREFIX.size
    whole = (lengths >= 0) & (starts + lengths <= len(buf))
    dropped = int((~inside).sum() + (~whole).sum())
    starts, lengths, log_times = starts[whole], lengths[whole], log_times[inside][whole]
    publish_times = read_u64(buf, starts - _PUBLISH_TIME_BEFORE_DATA).astype(np.int64)
    order = np.argsort(log_times, kind="stable")
    if (np.diff(order) != 1).any():
        starts, lengths = starts[order], lengths[order]
        log_times, publish_times = log_times[order], publish_times[order]
    return Spans(log_times, publish_times, starts, lengths, dropped)
