"""The recorder's subscriptions: one per selected topic, QoS adapted to the publishers' offers.

Runs in the take thread (after the first discovery, which ``Recorder.start`` waits for); the
writer thread and ``progress()`` read the topics under ``lock``.
"""

from __future__ import annotations

import logging
import threading
import time
from collections.abc import Callable, Mapping

from rclpy.node import Node
from rclpy.qos import DurabilityPolicy, QoSProfile, ReliabilityPolicy

from bagkit.bag import TopicInfo, message_definition
from bagkit.bag.errors import UnknownMessageTypeError as UnknownDefinitionError
from bagkit.recording.handoff import HandoffQueue, NewTopic
from bagkit.recording.report import TopicRecord
from bagkit.ros.errors import MessageClassNotFoundError
from bagkit.ros.graph import DiscoveredTopic, discover_topics
from bagkit.ros.message_classes import import_message_type
from bagkit.ros.qos import adapt_subscription_qos, dump_offered_qos_profiles
from bagkit.ros.record.recorded_topic import RecordedTopic
from bagkit.selection.topics import TopicSelection

_log = logging.getLogger(__name__)


def never_called(_message: object) -> None:
    """Subscriptions are drained from the wait set, never through an executor callback."""


class Subscriptions:
    """Subscribe to the selected topics as publishers appear; skip those that cannot be recorded.

    Args:
        node: the recorder's node.
        selection: which topics to record.
        qos_overrides: topic -> subscription profile, instead of the adapted one.
        queue: where new topics are announced to the writer.
        skipped: topic -> reason it is not recorded (the report's, filled here).
        on_warning: called with each warning; default: logging.
        include_unpublished: also subscribe to selected topics that have no publisher yet.

    ``complete`` is set after the discovery that subscribed every named topic (skipped ones
    count as done) or, when no topic is named, the first topic; ``complete_at`` is then its
    ``time.monotonic()``: a recording's duration counts from there.
    """

    def __init__(
        self,
        node: Node,
        selection: TopicSelection,
        *,
        qos_overrides: Mapping[str, QoSProfile],
        queue: HandoffQueue,
        skipped: dict[str, str],
        on_warning: Callable[[str], None] | None,
        include_unpublished: bool = False,
    ) -> None:
        self.node = node
        self.include_unpublished = include_unpublished
        self.complete = threading.Event()
        self.complete_at = 0.0
        self.selection = selection
        self.qos_overrides = qos_overrides
        self.topics: dict[str, RecordedTopic] = {}
        # Bumped whenever a subscription is added or replaced: the wait set is rebuilt.
        self.generation = 0
        self.lock = threading.Lock()
        self._queue = queue
        self._skipped = skipped
        self._on_warning = on_warning

    def snapshot(self) -> list[RecordedTopic]:
        """The topics subscribed so far."""
        with self.lock:
            return list(self.topics.values())

    def discover(self, drain: Callable[[RecordedTopic], None]) -> None:
        """Subscribe to newly matching topics; re-subscribe where the offers got weaker.

        ``drain`` queues what an old subscription holds before it is replaced.
        """
        found_topics = discover_topics(
            self.node, self.selection, include_unpublished=self.include_unpublished
        )
        for found in found_topics:
            known = self.topics.get(found.name)
            if known is None:
                self._subscribe(found)
            elif found.name not in self.qos_overrides:
                self._adapt(known, found, drain)
        if not self.complete.is_set() and self._covers_selection():
            self.complete_at = time.monotonic()
            self.complete.set()

    def _covers_selection(self) -> bool:
        """Whether every named topic is subscribed or skipped (any topic, if none is named)."""
        if self.selection.topics:
            return not self.never_appeared()
        with self.lock:
            return bool(self.topics)

    def never_appeared(self) -> list[str]:
        """The named topics neither subscribed nor skipped, sorted."""
        with self.lock:
            done = set(self.topics) | set(self._skipped)
        return sorted(self.selection.topics - done)

    def skip(self, topic: str, reason: str) -> None:
        """Leave ``topic`` out of the recording, with one warning (however often it is seen)."""
        with self.lock:
            if topic in self._skipped:
                return
            self._skipped[topic] = reason
        message = f"not recording {topic}: {reason}"
        if self._on_warning is not None:
            self._on_warning(message)
        else:
            _log.warning("%s", message)

    def _subscribe(self, found: DiscoveredTopic) -> None:
        if found.name in self._skipped:
            return
        if len(set(found.types)) > 1:
            self.skip(found.name, f"published with several types: {', '.join(found.types)}")
            return
        type_name = found.types[0]
        try:
            message_type = import_message_type(type_name)
        except MessageClassNotFoundError:
            self.skip(found.name, f"message type {type_name} is not installed")
            return
        try:
            # Read now rather than by the writer: a type without a definition on disk (a
            # service's bare request published as a topic) is skipped before it is subscribed.
            definition = message_definition(type_name)
        except UnknownDefinitionError as exc:
            self.skip(found.name, f"no message definition for the bag: {exc}")
            return
        qos = self.qos_overrides.get(found.name) or adapt_subscription_qos(found.offered)
        info = TopicInfo(
            found.name,
            type_name,
            offered_qos_profiles=dump_offered_qos_profiles(found.offered),
            type_description_hash=found.type_hash,
        )
        subscription = self.node.create_subscription(
            message_type, found.name, never_called, qos, raw=True
        )
        topic = RecordedTopic(TopicRecord(found.name, type_name), subscription, message_type, qos)
        # The writer adds the topic to the bag before the first message taken from it.
        self._queue.put_control("topic", NewTopic(topic, info, definition))
        with self.lock:
            self.topics[found.name] = topic
            self.generation += 1

    def _adapt(
        self, topic: RecordedTopic, found: DiscoveredTopic, drain: Callable[[RecordedTopic], None]
    ) -> None:
        """A new publisher with a weaker offer would not match: subscribe again, matching all."""
        wanted = adapt_subscription_qos(found.offered)
        current = topic.qos
        weaker = (
            current.reliability == ReliabilityPolicy.RELIABLE
            and wanted.reliability != ReliabilityPolicy.RELIABLE
        ) or (
            current.durability == DurabilityPolicy.TRANSIENT_LOCAL
            and wanted.durability != DurabilityPolicy.TRANSIENT_LOCAL
        )
        if not weaker:
            return
        # Subscribe anew before dropping the old one, so that nothing is missed in between;
        # the old one's queue is drained into the bag first.
        replacement = self.node.create_subscription(
            topic.message_type, topic.record.topic, never_called, wanted, raw=True
        )
        old = topic.subscription
        drain(topic)
        with self.lock:
            topic.subscription = replacement
            topic.qos = wanted
            self.generation += 1
        self.node.destroy_subscription(old)
