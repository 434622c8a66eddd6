"""Snapshot triggers on the data: ``--trigger 'TOPIC: CONDITION'`` checked on each message.

The trigger topic's serialized messages are deserialized with rclpy (its C type support, the
fastest decoder here) and the condition of :mod:`bagkit.selection.conditions` is evaluated on
the message objects. A condition over time (``gap > 1s``, ``unchanged(x) for 2s``) is fed to
its :class:`~bagkit.selection.streaming.StreamingCondition`, and :meth:`DataTriggers.tick`
tells it the time between messages, so a silence triggers while it lasts. The condition's
fields are checked against the topic's definition as soon as the topic is known, so that a
misspelt field stops the recording at once.
"""

from __future__ import annotations

import threading
import time
from collections.abc import Callable, Sequence
from dataclasses import dataclass, field
from typing import Any

from rclpy.node import Node
from rosidl_parser.definition import AbstractNestedType, NamespacedType

from bagkit.bag import TopicInfo
from bagkit.errors import BagkitError
from bagkit.recording.errors import TriggerError
from bagkit.recording.options import RecordOptions
from bagkit.ros.message_classes import import_message_type
from bagkit.ros.serialization import deserializer
from bagkit.selection.condition_terms import Latency, walk
from bagkit.selection.conditions import Condition, message_numbers
from bagkit.selection.errors import SelectionError
from bagkit.selection.message_tests import DecodedMessage
from bagkit.selection.streaming import StreamingCondition

# How often the graph is looked at while waiting for the trigger topics at the start.
GRAPH_POLL_S = 0.05
# How long the start waits for the trigger topics to check their conditions' fields, and how
# long after the start a trigger topic may be absent before a warning says so.
TRIGGER_CHECK_WAIT_S = 1.0
TRIGGER_TOPIC_WAIT_S = 10.0


@dataclass(slots=True)
class _Trigger:
    text: str
    condition: Condition
    stream: StreamingCondition | None = None  # a condition over time, once its topic is seen


@dataclass(slots=True)
class _TopicTriggers:
    conditions: list[_Trigger]
    decode: Callable[[bytes], Any] | None = None
    seen: bool = False
    # Latency conditions whose source this topic is, with the stamp they read.
    sources: list[tuple[_Trigger, tuple[str | int, ...]]] = field(default_factory=list)


class DataTriggers:
    """The ``--trigger`` conditions, by topic.

    Args:
        triggers: (text as given, absolute topic, condition) per trigger.
    """

    def __init__(self, triggers: Sequence[tuple[str, str, Condition]]) -> None:
        self._by_topic: dict[str, _TopicTriggers] = {}
        for text, topic, condition in triggers:
            entry = self._by_topic.setdefault(topic, _TopicTriggers([]))
            trigger = _Trigger(text, condition)
            entry.conditions.append(trigger)
            for node in walk(condition.tree):
                if isinstance(node, Latency):
                    source = self._by_topic.setdefault(node.source, _TopicTriggers([]))
                    source.sources.append((trigger, node.path))

    @classmethod
    def of(cls, options: RecordOptions) -> DataTriggers:
        """The triggers of ``options`` (none without snapshot mode)."""
        triggers = options.snapshot.triggers if options.snapshot is not None else ()
        return cls([(t.text, t.condition.topic, t.condition.condition) for t in triggers])

    @property
    def topics(self) -> list[str]:
        """The trigger topics."""
        return sorted(self._by_topic)

    def unseen(self) -> list[str]:
        """Trigger topics that have not appeared (no publisher found yet)."""
        return sorted(t for t, entry in self._by_topic.items() if not entry.seen)

    def add_topic(self, info: TopicInfo) -> None:
        """Check the conditions of ``info``'s topic against its type; prepare its decoder.

        Raises:
            TriggerError: a condition names a field the type lacks, or the type cannot be read.
        """
        entry = self._by_topic.get(info.name)
        if entry is None:
            return
        entry.seen = True
        self.check(info.name, info.type)
        entry.decode = deserializer(info.type)

    def check(self, topic: str, type_name: str) -> None:
        """Raise TriggerError if a condition on ``topic`` names a field ``type_name`` lacks."""
        entry = self._by_topic.get(topic)
        if entry is None:
            return
        try:
            paths = leaf_paths(import_message_type(type_name))
        except BagkitError as exc:
            raise TriggerError(f"trigger on {topic}: {exc}") from None
        for trigger in entry.conditions:
            try:
                trigger.condition.check_fields(topic, paths)
            except SelectionError as exc:
                raise TriggerError(f"trigger {trigger.text!r}: {exc}") from None

    def matching(
        self, topic: str, payloads: Sequence[bytes], log_times: Sequence[int]
    ) -> list[tuple[int, str]]:
        """(index, trigger text) of each message of ``topic`` that satisfies a condition, or
        at which an episode of a condition over time became known.

        Raises:
            TriggerError: a value cannot be compared (text with a number).
        """
        entry = self._by_topic.get(topic)
        if entry is None or entry.decode is None:
            return []
        found = []
        for index, data in enumerate(payloads):
            message = entry.decode(data)
            time_ns = log_times[index]
            for trigger, path in entry.sources:
                self._source(trigger, topic, time_ns, message, path)
            hit_text = None
            for trigger in entry.conditions:
                try:
                    hit = self._hit(trigger, time_ns, message)
                except SelectionError as exc:
                    raise TriggerError(f"trigger {trigger.text!r}: {exc}") from None
                if hit and hit_text is None:
                    hit_text = trigger.text
            if hit_text is not None:
                found.append((index, hit_text))
        return found

    def tick(self, now_ns: int) -> list[str]:
        """Tell the conditions over time that ``now_ns`` has come: the texts of those whose
        episode became known (a silence long enough)."""
        found = []
        for entry in self._by_topic.values():
            for trigger in entry.conditions:
                if trigger.stream is not None:
                    trigger.stream.advance(now_ns)
                    if trigger.stream.take_new():
                        found.append(trigger.text)
        return found

    @staticmethod
    def _hit(trigger: _Trigger, time_ns: int, message: Any) -> bool:
        if not trigger.condition.temporal:
            return trigger.condition.matches(message)
        if trigger.stream is None:
            trigger.stream = StreamingCondition(trigger.condition.tree, time_ns, keep=False)
        trigger.stream.push(time_ns, DecodedMessage(trigger.condition, message))
        return trigger.stream.take_new() > 0

    @staticmethod
    def _source(
        trigger: _Trigger, topic: str, time_ns: int, message: Any, path: tuple[str | int, ...]
    ) -> None:
        if trigger.stream is None:
            trigger.stream = StreamingCondition(trigger.condition.tree, time_ns, keep=False)
        sec, nanosec = message_numbers(message, path)[:2]
        trigger.stream.source(topic, time_ns, int(sec) * 1_000_000_000 + int(nanosec))


def start_trigger_checks(
    node: Node,
    triggers: DataTriggers,
    *,
    stopping: Callable[[], bool],
    warn: Callable[[str], None],
) -> threading.Timer:
    """Check the triggers on the topics found (up to TRIGGER_CHECK_WAIT_S for them to appear);
    return the timer that warns TRIGGER_TOPIC_WAIT_S later about trigger topics still absent
    (unless ``stopping()`` by then). Cancel it when the recording stops.

    Raises:
        TriggerError: a condition names a field its topic's type lacks.
    """
    check_triggers_in_graph(node, triggers, TRIGGER_CHECK_WAIT_S)

    def warn_absent() -> None:
        if stopping():
            return
        for topic in triggers.unseen():
            warn(
                f"trigger topic {topic} has not appeared after {TRIGGER_TOPIC_WAIT_S:g} s: "
                "recording goes on, it triggers once it appears"
            )

    timer = threading.Timer(TRIGGER_TOPIC_WAIT_S, warn_absent)
    timer.daemon = True
    timer.start()
    return timer


def check_triggers_in_graph(node: Node, triggers: DataTriggers, wait_s: float) -> None:
    """Check the triggers of the topics ``node``'s graph shows, waiting ``wait_s`` for them.

    A topic that does not appear in time is checked when it is subscribed.

    Raises:
        TriggerError: a condition names a field its topic's type lacks.
    """
    deadline = time.monotonic() + wait_s
    checked: set[str] = set()
    while True:
        graph = dict(node.get_topic_names_and_types())
        for topic in triggers.topics:
            types = graph.get(topic, [])
            if topic in checked or len(types) != 1:
                continue
            try:
                import_message_type(types[0])
            except BagkitError:
                continue  # not installed: the topic is skipped with a warning of its own
            triggers.check(topic, types[0])
            checked.add(topic)
        if len(checked) == len(triggers.topics) or time.monotonic() >= deadline:
            return
        time.sleep(GRAPH_POLL_S)


def leaf_paths(message_class: Any, prefix: str = "") -> list[str]:
    """The leaf field paths of an rclpy message class (``status[].level``), as
    :mod:`bagkit.selection.fields` writes them (every array as ``[]``)."""
    paths = []
    names = message_class.get_fields_and_field_types()
    for name, slot in zip(names, message_class.SLOT_TYPES, strict=True):
        path = f"{prefix}.{name}" if prefix else name
        element = slot
        if isinstance(slot, AbstractNestedType):
            path += "[]"
            element = slot.value_type
        if isinstance(element, NamespacedType):
            nested = import_message_type("/".join([*element.namespaces, element.name]))
            paths.extend(leaf_paths(nested, path))
        else:
            paths.append(path)
    return paths
