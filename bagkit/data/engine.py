"""The decoding engine this package stands on, imported in this one module.

Two ideas live elsewhere in bagkit and are only re-exported here: where each message's payload
is in a decompressed chunk (``bagkit.bag.mcapio.chunks``, checked against the chunk) and the
bulk decoder of fixed-layout payloads (``bagkit.decode.bulk``). Field globs are
``bagkit.selection.fields``'.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from bagkit.bag.mcapio.chunks import payload_publish_times
from bagkit.bag.mcapio.chunks import payload_spans as chunk_payload_spans
from bagkit.decode.bulk import BulkGroup, decode_bulk, gather, read_u32

__all__ = [
    "BulkGroup",
    "Spans",
    "decode_bulk",
    "gather",
    "payload_spans",
    "read_u32",
]


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

    def take(self, keep: np.ndarray) -> Spans:
        """The spans where ``keep`` (bool, one per span) is true."""
        return Spans(
            self.log_times[keep],
            self.publish_times[keep],
            self.starts[keep],
            self.lengths[keep],
            self.dropped,
        )


def payload_spans(
    records: bytes, index: np.ndarray, start_ns: int | None, end_ns: int | None
) -> Spans:
    """Spans of the messages of ``index`` (a chunk's message-index entries of one topic).

    Args:
        records: the chunk's decompressed records.
        index: ``log_time``/``offset`` entries.
        start_ns, end_ns: keep ``start_ns <= log_time < end_ns`` (None: unbounded).
    """
    log_times, starts, lengths, dropped = chunk_payload_spans(records, index)
    keep = np.ones(len(starts), dtype=bool)
    if start_ns is not None:
        keep &= log_times >= start_ns
    if end_ns is not None:
        keep &= log_times < end_ns
    log_times, starts, lengths = log_times[keep], starts[keep], lengths[keep]
    publish_times = payload_publish_times(records, starts)
    order = np.argsort(log_times, kind="stable")
    if (np.diff(order) != 1).any():
        starts, lengths = starts[order], lengths[order]
        log_times, publish_times = log_times[order], publish_times[order]
    return Spans(log_times, publish_times, starts, lengths, dropped)
