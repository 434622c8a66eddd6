"""A health contract evaluated live, on the messages the recorder writes (``record --health``).

Each assertion over time of a :class:`~bagkit.health.spec.HealthSpec` is fed to a
:class:`~bagkit.selection.streaming.StreamingCondition` (the evaluator of ``--trigger``), from
its topic's first message on; an episode of it beginning is a check that *broke*, its end a
check that *cleared*. ``rate`` and ``gap`` need the log times alone; a per-message condition
(value bounds, ``isnan``) reads only its fields, straight from the bytes
(:func:`bagkit.decode.direct.value_reader`), over the whole batch at once
(:meth:`~bagkit.selection.conditions.Condition.mask`), and its evaluator is told only where
the result changes; other conditions that read fields get rosbags' decoded messages (from the
definition the recorder stores).
``present`` is decided at the end, ``type`` when the topic is added, ``forbidden`` at its first
message. :class:`LiveHealth` is the recorder's :class:`~bagkit.recording.health_watch.HealthWatch`.
"""

from __future__ import annotations

import time
from collections.abc import Callable, Sequence
from dataclasses import dataclass, field
from typing import Any

import numpy as np

from bagkit.bag import TopicInfo
from bagkit.bag.definitions import canonical_type_name
from bagkit.bag.latched import is_transient_local
from bagkit.decode import DecodeError, MessageTypes, leaf_fields
from bagkit.decode.direct import ValueReader
from bagkit.errors import OptionError
from bagkit.health.spec import HealthSpec, SpecError, TopicContract
from bagkit.recording.health_watch import HealthCount, HealthEvent
from bagkit.selection.condition_terms import (
    Check,
    Comparison,
    Expression,
    For,
    Gap,
    Latency,
    Node,
    Path,
    Rate,
    is_stateless,
    walk,
)
from bagkit.selection.conditions import Condition, message_numbers
from bagkit.selection.errors import SelectionError
from bagkit.selection.message_tests import DecodedMessage
from bagkit.selection.streaming import StreamingCondition


@dataclass(slots=True)
class _Check:
    count: HealthCount
    condition: Condition
    stream: StreamingCondition | None = None
    open: int | None = None  # the start of the episode told of as broken
    # A per-message condition over fixed fields: the columns each of its comparisons reads.
    reads: dict[Comparison | Check, list[str]] | None = None


class _Known:
    """A message whose per-message condition is already decided (over the batch's columns)."""

    def __init__(self, hit: bool) -> None:
        self.hit = hit

    def holds(self, node: Expression) -> bool:
        return self.hit

    def values(self, path: Path | None) -> np.ndarray:
        raise AssertionError("a decided message has no values")


_HIT, _MISS = _Known(True), _Known(False)


@dataclass(slots=True)
class _Topic:
    name: str
    contract: TopicContract | None
    checks: list[_Check]
    present: HealthCount | None = None
    type_count: HealthCount | None = None
    decode: Callable[[bytes], Any] | None = None
    read_values: ValueReader | None = None
    columns: list[str] = field(default_factory=list)
    state: bool = False
    last_ns: int | None = None  # the log time of its last message
    # Latency checks whose source this topic is, with the stamp path they read.
    sources: list[tuple[_Check, Path]] = field(default_factory=list)

    @property
    def reads_fields(self) -> bool:
        return bool(self.sources) or any(_reads_fields(c.condition) for c in self.checks)

    @property
    def decodes(self) -> bool:
        """Whether a check reads decoded messages (not only log times or columns)."""
        return bool(self.sources) or any(
            c.reads is None and _reads_fields(c.condition) for c in self.checks
        )


class LiveHealth:
    """A contract checked on a recording as it is written.

    Args:
        spec: the contract.
        trigger: a check that breaks triggers a snapshot (the recorder must be in snapshot
            mode).
        stop_after_ns: stop once a check has been broken this long (None: never).
        on_event: called with each check that breaks or clears (from the writer thread).

    Raises:
        OptionError: ``stop_after_ns`` is not positive (the error names the field).
    """

    def __init__(
        self,
        spec: HealthSpec,
        *,
        trigger: bool = False,
        stop_after_ns: int | None = None,
        on_event: Callable[[HealthEvent], None] | None = None,
    ) -> None:
        self.spec = spec
        self.trigger = trigger
        if stop_after_ns is not None and stop_after_ns <= 0:
            raise OptionError(f"must be positive, got {stop_after_ns}", "stop_after_ns")
        self.stop_after_ns = stop_after_ns
        self._on_event = on_event
        self._forbidden = {topic: HealthCount(topic, "forbidden") for topic in spec.forbidden}
        self._topics: dict[str, _Topic] = {}
        self._counts: list[HealthCount] = list(self._forbidden.values())
        for contract in spec.topics:
            entry = _Topic(
                contract.topic, contract, [], present=HealthCount(contract.topic, "present")
            )
            self._counts.append(entry.present)  # type: ignore[arg-type]
            if contract.type is not None:
                entry.type_count = HealthCount(contract.topic, f"type {contract.type}")
                self._counts.append(entry.type_count)
            for text, condition in contract.never:
                check = _Check(HealthCount(contract.topic, text), condition)
                entry.checks.append(check)
                self._counts.append(check.count)
                for node in walk(condition.tree):
                    if isinstance(node, Latency):
                        source = self._topics.setdefault(node.source, _Topic(node.source, None, []))
                        source.sources.append((check, node.path))
            existing = self._topics.get(contract.topic)
            if existing is not None:  # a latency source named before its own contract
                entry.sources = existing.sources
            self._topics[contract.topic] = entry

    @property
    def counts(self) -> list[HealthCount]:
        """Per assertion, in the contract's order (forbidden topics first)."""
        return list(self._counts)

    def add_topic(self, info: TopicInfo, definition: str) -> list[HealthEvent]:
        """Check ``info``'s type and the fields its assertions read; prepare its decoder.

        Raises:
            SpecError: an assertion names a field the type lacks, or the type cannot be read.
        """
        entry = self._topics.get(info.name)
        if entry is None:
            return []
        entry.state = is_transient_local(info.offered_qos_profiles)
        events = []
        wanted = entry.contract.type if entry.contract is not None else None
        count = entry.type_count
        if count is not None and wanted is not None and not _same_type(info.type, wanted):
            events.append(self._break(count, time.time_ns()))
        if entry.reads_fields:
            self._readers(entry, info, definition)
        return self._tell(events)

    def _readers(self, entry: _Topic, info: TopicInfo, definition: str) -> None:
        """Check the fields the assertions read; prepare the column reader and the decoder."""
        try:
            types = MessageTypes.from_definitions({info.type: definition})
            canonical = types.resolve(info.type)
            leaves = [leaf.path for leaf in leaf_fields(types.typestore, canonical)]
            for check in entry.checks:
                try:
                    check.condition.check_fields(info.name, leaves)
                except SelectionError as exc:
                    where = f"{self.spec.source}: {check.count.assertion}"
                    raise SpecError(f"{where}: {exc}") from None
                if is_stateless(check.condition.tree):
                    check.reads = check.condition.bulk_columns(leaves)
            entry.columns = sorted(
                {name for c in entry.checks for names in (c.reads or {}).values() for name in names}
            )
            if entry.columns:
                entry.read_values = types.value_reader(info.type, entry.columns)
            if entry.decodes:
                entry.decode = types.decoder(info.type)
        except DecodeError as exc:
            raise SpecError(f"{self.spec.source}: {info.name} cannot be decoded: {exc}") from None

    def observe(
        self, topic: str, payloads: Sequence[bytes], log_times: Sequence[int]
    ) -> list[HealthEvent]:
        """Messages of ``topic`` were written (log times ascending)."""
        events: list[HealthEvent] = []
        forbidden = self._forbidden.get(topic)
        if forbidden is not None and forbidden.breaks == 0 and log_times:
            events.append(self._break(forbidden, log_times[0]))
        entry = self._topics.get(topic)
        if entry is None or not log_times:
            return self._tell(events)
        entry.last_ns = log_times[-1]
        try:
            self._push_columns(entry, payloads, log_times)
            self._push_messages(entry, payloads, log_times)
        except SelectionError as exc:  # a text compared with a number
            raise SpecError(f"{self.spec.source}: {topic}: {exc}") from None
        for check in entry.checks:
            events.extend(self._episodes(check))
        return self._tell(events)

    def _push_columns(
        self, entry: _Topic, payloads: Sequence[bytes], log_times: Sequence[int]
    ) -> None:
        """The checks over columns: decided for the batch at once, pushed where they change."""
        if entry.read_values is None:
            return
        rows, times = [], []
        for data, time_ns in zip(payloads, log_times, strict=True):
            try:
                rows.append(entry.read_values(data))
            except DecodeError:  # never matched, as check skips it; the recording goes on
                continue
            times.append(time_ns)
        if not rows:
            return
        log_times = times
        columns = {name: np.array([row[i] for row in rows]) for i, name in enumerate(entry.columns)}
        last = len(log_times) - 1
        for check in entry.checks:
            if check.reads is None:
                continue
            hits = check.condition.mask(columns, check.reads)
            changes = np.flatnonzero(hits[1:] != hits[:-1]) + 1
            # A run's last message and the first after it: where the evaluator's runs end.
            pushed = sorted({0, last, *changes.tolist(), *(changes - 1).tolist()})
            stream = self._stream(check, log_times[0], entry.state)
            for index in pushed:
                stream.push(log_times[index], _HIT if hits[index] else _MISS)

    def _push_messages(
        self, entry: _Topic, payloads: Sequence[bytes], log_times: Sequence[int]
    ) -> None:
        """The other checks, message by message (decoded where they read fields)."""
        checks = [c for c in entry.checks if c.reads is None]
        if not checks and not entry.sources:
            return
        decode = entry.decode
        for data, time_ns in zip(payloads, log_times, strict=True):
            try:
                message = None if decode is None else decode(data)
            except DecodeError:  # skipped where fields are read, as check skips it
                for check in checks:
                    if not _reads_fields(check.condition):  # times alone: it arrived
                        self._stream(check, time_ns, entry.state).push(time_ns, _MISS)
                continue
            for check, path in entry.sources:
                stream = self._stream(check, time_ns, entry.state)
                sec, nanosec = message_numbers(message, path)[:2]
                stream.source(entry.name, time_ns, int(sec) * 1_000_000_000 + int(nanosec))
            for check in checks:
                # No message decoded: the check reads the log times only.
                read = _MISS if message is None else DecodedMessage(check.condition, message)
                self._stream(check, time_ns, entry.state).push(time_ns, read)

    def advance(self, now_ns: int) -> list[HealthEvent]:
        """Time has come to ``now_ns``: silences long enough break their checks now."""
        events: list[HealthEvent] = []
        for entry in self._topics.values():
            for check in entry.checks:
                if check.stream is not None:
                    check.stream.advance(now_ns)
                    events.extend(self._episodes(check))
        return self._tell(events)

    def finish(self, end_ns: int) -> list[HealthEvent]:
        """The recording ended: topics never seen break ``present``; what is broken stays so."""
        events: list[HealthEvent] = []
        for entry in self._topics.values():
            if entry.present is not None and entry.last_ns is None:
                events.append(self._break(entry.present, end_ns))
            for check in entry.checks:
                if check.stream is None:
                    continue
                check.stream.finish(end_ns)
                for start, stop in check.stream.episodes:
                    if start != check.open:  # an episode only the end showed (a final gap)
                        events.append(self._break(check.count, start))
                    # Over before the end, known only now (a rate window); a run of bad
                    # messages that ends at the topic's last message is going on still.
                    if stop < end_ns and stop != entry.last_ns:
                        events.append(self._clear(check.count, stop))
                    check.open = None
                check.stream.episodes.clear()
        return self._tell(events)

    def overdue(self, now_ns: int) -> HealthCount | None:
        """The first assertion broken for ``stop_after_ns`` or longer at ``now_ns``."""
        if self.stop_after_ns is None:
            return None
        for count in self._counts:
            since = count.broken_since_ns
            if since is not None and now_ns - since >= self.stop_after_ns:
                return count
        return None

    def _stream(self, check: _Check, time_ns: int, state: bool) -> StreamingCondition:
        if check.stream is None:
            check.stream = StreamingCondition(check.condition.tree, time_ns, state=state)
        return check.stream

    def _episodes(self, check: _Check) -> list[HealthEvent]:
        """The breaks and clears of ``check``'s stream since it was last looked at."""
        stream = check.stream
        assert stream is not None
        events = []
        for start, end in stream.episodes:
            if start != check.open:
                events.append(self._break(check.count, start))
            events.append(self._clear(check.count, end))
            check.open = None
        stream.episodes.clear()
        if stream.since != check.open:
            if check.open is not None:  # the episode told of is no longer the one going on
                events.append(self._clear(check.count, stream.root.settled))
            if stream.since is not None:
                events.append(self._break(check.count, stream.since))
            check.open = stream.since
        return events

    @staticmethod
    def _break(count: HealthCount, at_ns: int) -> HealthEvent:
        count.breaks += 1
        count.broken_since_ns = at_ns
        return HealthEvent(True, count.topic, count.assertion, at_ns, at_ns)

    @staticmethod
    def _clear(count: HealthCount, at_ns: int) -> HealthEvent:
        count.clears += 1
        since = count.broken_since_ns if count.broken_since_ns is not None else at_ns
        count.broken_since_ns = None
        return HealthEvent(False, count.topic, count.assertion, at_ns, since)

    def _tell(self, events: list[HealthEvent]) -> list[HealthEvent]:
        if self._on_event is not None:
            for event in events:
                self._on_event(event)
        return events


def _same_type(actual: str, wanted: str) -> bool:
    return canonical_type_name(actual) == canonical_type_name(wanted)


def _reads_fields(condition: Condition) -> bool:
    """Whether ``condition`` reads the messages, not only their log times."""
    return any(not isinstance(node, Gap | Rate | For | Node) for node in walk(condition.tree))
