"""A topic the recorder subscribed to, as the take and writer threads pass it between them."""

from __future__ import annotations

from dataclasses import dataclass, field
from typing import Any

from rclpy.qos import QoSProfile
from rclpy.subscription import Subscription

from bagkit.recording.loss import SequenceTracker
from bagkit.recording.report import TopicRecord


@dataclass(slots=True)
class RecordedTopic:
    """A subscribed topic: its subscription, what re-subscribing needs (type, QoS), its counts."""

    record: TopicRecord
    subscription: Subscription
    message_type: Any
    qos: QoSProfile
    tracker: SequenceTracker = field(default_factory=SequenceTracker)

    def count_gaps(self, sequences: list[int]) -> None:
        """Count the sequence gaps up to the messages just taken (``sequences``)."""
        record = self.record
        record.gaps += self.tracker.observe_many(
            sequences, self.subscription.handle.get_publisher_count
        )
        record.publishers = self.tracker.publishers
