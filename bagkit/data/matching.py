"""Which messages of a topic satisfy a condition: numpy over columns where it can, decoded
messages otherwise.

A condition whose comparisons all read scalar leaves (``linear_acceleration.z < 0``) is
evaluated on columns (:meth:`Condition.mask`), the columns decoded as ``stats`` does: fixed
layout payloads in bulk with numpy, the others through the general decoder
(:class:`~bagkit.data.columns.TopicColumns`). A condition reading sequences
(``status[*].level >= 2``) is evaluated on each decoded message (:meth:`Condition.matches`).
A message that does not decode is counted, never matched.
"""

from __future__ import annotations

from collections.abc import Callable, Iterable, Sequence
from dataclasses import dataclass, field

import numpy as np

from bagkit.bag import BagReader
from bagkit.data.columns import Rows, TopicColumns
from bagkit.data.engine import Spans, payload_spans
from bagkit.data.errors import UndecodableTopicError, UnknownFieldError
from bagkit.decode import DecodeError, MessageTypes, leaf_fields
from bagkit.selection.conditions import Condition
from bagkit.selection.topics import require_topics
from bagkit.selection.windows import Window

# Messages of chunkless storage (.db3) are matched this many at a time.
MESSAGES_PER_BATCH = 8192


class PayloadMatcher:
    """Matches the serialized messages of one topic against a condition.

    Args:
        types: the bag's message types.
        topic: the topic (for messages naming it).
        type_name: its type as the bag names it.
        condition: the condition, its fields checked against the type here.

    Raises:
        UndecodableTopicError: the type cannot be decoded.
        UnknownFieldError: the condition names a field the type lacks.
    """

    def __init__(
        self, types: MessageTypes, topic: str, type_name: str, condition: Condition
    ) -> None:
        try:
            canonical = types.resolve(type_name)
            self._decode = types.decoder(type_name)
        except DecodeError as exc:
            raise UndecodableTopicError(f"{topic} cannot be decoded: {exc}") from None
        leaves = leaf_fields(types.typestore, canonical)
        condition.check_fields(topic, [leaf.path for leaf in leaves])
        self.topic = topic
        self.condition = condition
        self._reads = condition.bulk_columns([leaf.path for leaf in leaves])
        self._columns: TopicColumns | None = None
        if self._reads is not None:
            needed = {path for paths in self._reads.values() for path in paths}
            read = [leaf for leaf in leaves if leaf.path in needed]
            self._columns = TopicColumns(types, topic, type_name, read)
        self._failures = 0
        self.first_failure = ""

    @property
    def undecodable(self) -> int:
        """Messages that did not decode (never matched)."""
        extra = self._columns.failures if self._columns is not None else 0
        return self._failures + extra

    def mask_spans(self, records: bytes, spans: Spans) -> np.ndarray:
        """Whether each payload at ``spans`` in a chunk's ``records`` matches (bool array)."""
        columns = self._columns
        if columns is not None:
            rows = columns.decode_spans(records, spans, lambda n: Rows.empty(columns.leaves, n))
            return self._rows_mask(rows)
        view = memoryview(records)
        payloads = (
            view[s : s + n]
            for s, n in zip(spans.starts.tolist(), spans.lengths.tolist(), strict=True)
        )
        return self._decoded_mask(payloads, len(spans.starts))

    def mask_records(self, records: bytes, starts: np.ndarray, lengths: np.ndarray) -> np.ndarray:
        """Whether each payload at ``starts``/``lengths`` in a chunk's records matches
        (:class:`bagkit.surgery.select.PayloadFilter`, for ``filter --where``)."""
        times = np.zeros(len(starts), np.int64)  # not needed to match
        return self.mask_spans(records, Spans(times, times, starts, lengths))

    @property
    def problem(self) -> str | None:
        """The line for messages that did not decode (never matched), or None."""
        if not self.undecodable:
            return None
        return (
            f"{self.topic}: {self.undecodable} messages could not be decoded, not matched "
            f"({self.first_failure})"
        )

    def mask_payloads(self, payloads: Sequence[bytes]) -> np.ndarray:
        """Whether each of ``payloads`` (storage without chunks) matches (bool array)."""
        columns = self._columns
        if columns is not None:
            zeros = [0] * len(payloads)  # times are not needed to match
            rows = columns.decode_payloads(
                payloads, zeros, zeros, lambda n: Rows.empty(columns.leaves, n)
            )
            return self._rows_mask(rows)
        return self._decoded_mask(iter(payloads), len(payloads))

    def _rows_mask(self, rows: Rows) -> np.ndarray:
        assert self._reads is not None and self._columns is not None
        if self._columns.first_failure:
            self.first_failure = self.first_failure or self._columns.first_failure
        by_path = {leaf.path: rows.arrays[j] for j, leaf in enumerate(rows.leaves)}
        if not len(rows.ok):
            return np.zeros(0, dtype=bool)
        ok = rows.ok
        if not ok.all():  # failed rows hold garbage: compare decoded rows only
            by_path = {path: array[ok] for path, array in by_path.items()}
        matched = np.zeros(len(ok), dtype=bool)
        matched[ok] = self.condition.mask(by_path, self._reads)
        return matched

    def _decoded_mask(self, payloads: Iterable[bytes | memoryview], n: int) -> np.ndarray:
        matched = np.zeros(n, dtype=bool)
        decode, condition = self._decode, self.condition
        for i, data in enumerate(payloads):
            try:
                message = decode(data)
            except DecodeError as exc:
                self._failures += 1
                self.first_failure = self.first_failure or str(exc)
                continue
            matched[i] = condition.matches(message)
        return matched


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
    types = MessageTypes.from_definitions(reader.definitions)
    matcher = PayloadMatcher(types, topic, reader.topics[topic].type, condition)
    times: list[np.ndarray] = []
    masks: list[np.ndarray] = []
    unindexed = 0  # index entries pointing outside their chunk
    if "sqlite3" in reader.storage.split(","):
        _match_messages(reader, topic, window, matcher, times, masks)
    else:
        for chunk in reader.chunks([topic]):
            spans = payload_spans(
                chunk.records, chunk.message_index[topic], window.start_ns, window.end_ns
            )
            times.append(spans.log_times)
            masks.append(matcher.mask_spans(chunk.records, spans))
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


def _match_messages(  # noqa: PLR0917 (private: the loop's state)
    reader: BagReader,
    topic: str,
    window: Window,
    matcher: PayloadMatcher,
    times: list[np.ndarray],
    masks: list[np.ndarray],
) -> None:
    """Storage without chunks (also a bag mixing .db3 and .mcap files): message by message."""
    payloads: list[bytes] = []
    log_times: list[int] = []

    def flush() -> None:
        times.append(np.array(log_times, dtype=np.int64))
        masks.append(matcher.mask_payloads(payloads))
        payloads.clear()
        log_times.clear()

    for message in reader.messages([topic], window.start_ns, window.end_ns):
        payloads.append(message.data)
        log_times.append(message.log_time)
        if len(payloads) >= MESSAGES_PER_BATCH:
            flush()
    if payloads:
        flush()


def where_filters(
    reader: BagReader, condition: Condition, passes: Callable[[str], bool]
) -> dict[str, PayloadMatcher]:
    """A matcher for each topic of an open bag that ``passes`` and whose type has every field
    ``condition`` reads (``filter --where``: the other topics are kept whole).

    Raises:
        UnknownFieldError: no such topic (the message names the fields of the first one).
    """
    types = MessageTypes.from_definitions(reader.definitions)
    matchers: dict[str, PayloadMatcher] = {}
    first_error: UnknownFieldError | None = None
    for name in sorted(reader.topics):
        if not passes(name) or reader.topics[name].serialization_format != "cdr":
            continue
        try:
            matchers[name] = PayloadMatcher(types, name, reader.topics[name].type, condition)
        except UndecodableTopicError:
            continue
        except UnknownFieldError as exc:
            first_error = first_error or exc
    if not matchers:
        if first_error is not None:
            raise UnknownFieldError(
                f"no selected topic has the fields of the condition: {first_error}"
            )
        raise UnknownFieldError("no selected topic can be decoded to check the condition")
    return matchers
