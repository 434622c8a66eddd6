"""Which messages of a topic satisfy a condition, over a whole bag (``find``, ``--around``).

The matching itself is :class:`bagkit.decode.matcher.PayloadMatcher` (the one matcher, shared
with ``--where`` on export, plot and stats): the columns a condition reads decoded in bulk with
numpy for fixed layouts, decoded messages otherwise. A message that does not decode is counted,
never matched.
"""

from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np

from bagkit.bag import BagReader
from bagkit.data.engine import payload_spans
from bagkit.data.errors import UndecodableTopicError
from bagkit.decode import DecodeError, MessageTypes
from bagkit.decode.matcher import PayloadMatcher
from bagkit.selection.conditions import Condition
from bagkit.selection.topics import require_topics
from bagkit.selection.windows import Window


@dataclass
class TopicMatches:
    """Every message of one topic in a window, in log-time order, and whether it matched.

    Attributes:
        topic: the topic.
        log_times: int64 ns, ascending (ties in storage order).
        matched: bool, one per message (False for messages that did not decode).
        undecodable: messages that did not decode.
        problems: what could not be read, one line each (the bag's and the decoder's).
    """

    topic: str
    log_times: np.ndarray
    matched: np.ndarray
    undecodable: int = 0
    problems: list[str] = field(default_factory=list)

    @property
    def count(self) -> int:
        """Messages that matched."""
        return int(self.matched.sum())


def match_topic(
    reader: BagReader, topic: str, condition: Condition, window: Window | None = None
) -> TopicMatches:
    """Match every message of ``topic`` in ``window`` (the whole bag when None) of an open bag.

    Raises:
        UnknownTopicError, UnknownFieldError, UndecodableTopicError; SelectionError when a
        value cannot be compared with its field (text with a number).
    """
    (topic,) = require_topics([topic], reader.topics)
    window = window or Window()
    types = MessageTypes.for_bag(reader)
    info = reader.topics[topic]
    try:
        if info.serialization_format != "cdr":  # as echo refuses it
            raise DecodeError(f"serialization format {info.serialization_format!r} is not CDR")
        matcher = PayloadMatcher(types, topic, info.type, condition)
    except DecodeError as exc:
        raise UndecodableTopicError(f"{topic} cannot be decoded: {exc}") from None
    times: list[np.ndarray] = []
    masks: list[np.ndarray] = []
    unindexed = 0  # index entries pointing outside their chunk
    for chunk in reader.chunks([topic], window.start_ns, window.end_ns):
        spans = payload_spans(
            chunk.records, chunk.message_index[topic], window.start_ns, window.end_ns
        )
        times.append(spans.log_times)
        masks.append(matcher.mask_records(chunk.records, spans.starts, spans.lengths))
        unindexed += spans.dropped
    log_times = np.concatenate(times) if times else np.zeros(0, np.int64)
    matched = np.concatenate(masks) if masks else np.zeros(0, bool)
    order = np.argsort(log_times, kind="stable")  # chunks may overlap in time
    problems = list(reader.problems)
    if unindexed:
        problems.append(f"{topic}: {unindexed} index entries point outside their chunk: lost")
    if matcher.problem:
        problems.append(matcher.problem)
    return TopicMatches(topic, log_times[order], matched[order], matcher.undecodable, problems)
