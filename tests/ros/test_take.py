"""bagkit.ros.record.take against rclpy's own take, on real subscriptions of one real publisher."""

from __future__ import annotations

from collections.abc import Iterator
from dataclasses import dataclass
from typing import Any

import pytest
import rclpy
from rclpy.context import Context
from rclpy.duration import Duration
from rclpy.node import Node
from rclpy.qos import HistoryPolicy, QoSProfile, ReliabilityPolicy
from rclpy.signals import SignalHandlerOptions
from rclpy.subscription import Subscription
from sensor_msgs.msg import Image, Imu
from waiting import wait_matched

from bagkit.recording.handoff import TakenMessages
from bagkit.ros.record.take import take_serialized

KEEP_ALL = QoSProfile(history=HistoryPolicy.KEEP_ALL, reliability=ReliabilityPolicy.RELIABLE)


@dataclass
class Pair:
    """A publisher and two subscriptions that receive the same messages."""

    node: Node
    publisher: Any
    ours: Subscription
    reference: Subscription
    message_type: Any

    def publish_and_wait(self, messages: list[Any]) -> None:
        for message in messages:
            self.publisher.publish(message)
        # Keep-all reliable: a message is acknowledged once each reader's history holds it.
        assert self.publisher.wait_for_all_acked(Duration(seconds=10))

    def reference_take(self) -> list[tuple[bytes, dict[str, int]]]:
        taken = []
        while (one := self.reference.handle.take_message(self.message_type, True)) is not None:
            taken.append(one)
        return taken


@pytest.fixture
def context() -> Iterator[Context]:
    context = Context()
    rclpy.init(context=context, signal_handler_options=SignalHandlerOptions.NO)
    try:
        yield context
    finally:
        context.try_shutdown()


def make_pair(context: Context, message_type: Any, topic: str) -> Pair:
    node = Node("bagkit_test_take", context=context, start_parameter_services=False)
    publisher = node.create_publisher(message_type, topic, KEEP_ALL)
    ours = node.create_subscription(message_type, topic, lambda _m: None, KEEP_ALL, raw=True)
    reference = node.create_subscription(message_type, topic, lambda _m: None, KEEP_ALL, raw=True)
    wait_matched(publisher, count=2)
    return Pair(node, publisher, ours, reference, message_type)


def imu_messages(count: int) -> list[Imu]:
    messages = []
    for i in range(count):
        message = Imu()
        message.header.frame_id = "imu" * (i % 7)  # payloads of different lengths
        message.header.stamp.sec = i
        message.linear_acceleration.x = i * 0.5
        messages.append(message)
    return messages


def take_all(pair: Pair, *, max_count: int, max_bytes: int) -> list[TakenMessages]:
    batches = []
    while (taken := take_serialized(pair.ours, max_count=max_count, max_bytes=max_bytes)).payloads:
        batches.append(taken)
    return batches


def test_columns_equal_what_rclpy_takes(context: Context) -> None:
    pair = make_pair(context, Imu, "/bagkit_test/take/imu")
    sent = imu_messages(300)
    pair.publish_and_wait(sent)

    batches = take_all(pair, max_count=64, max_bytes=1 << 20)
    reference = pair.reference_take()

    assert [len(b) for b in batches] == [64, 64, 64, 64, 44]
    payloads = [p for b in batches for p in b.payloads]
    assert len(reference) == 300
    assert payloads == [data for data, _info in reference]
    assert [s for b in batches for s in b.sequences] == [
        info["publication_sequence_number"] for _data, info in reference
    ]
    assert [s for b in batches for s in b.sources] == [
        info["source_timestamp"] for _data, info in reference
    ]
    # Each subscription stamps its own receive time: after the publisher's stamp, soon after.
    for taken in batches:
        for received, source in zip(taken.received, taken.sources, strict=True):
            assert 0 <= received - source < 5_000_000_000
    assert all(b.nbytes == sum(map(len, b.payloads)) for b in batches)
    # The sequence numbers are the publisher's, consecutive.
    sequences = [s for b in batches for s in b.sequences]
    assert sequences == list(range(sequences[0], sequences[0] + 300))


def test_byte_budget_stops_after_the_message_that_crosses_it(context: Context) -> None:
    pair = make_pair(context, Image, "/bagkit_test/take/image")
    sent = []
    for size in (100_000, 300_000, 50_000, 10, 200_000):
        image = Image()
        image.data = bytes([size % 251]) * size
        sent.append(image)
    pair.publish_and_wait(sent)

    batches = take_all(pair, max_count=100, max_bytes=350_000)

    # 100k + 300k crosses 350k: the first batch ends there; then 50k + 10 + 200k crosses too.
    assert [len(b) for b in batches] == [2, 3]
    assert [p for b in batches for p in b.payloads] == [d for d, _i in pair.reference_take()]


def test_nothing_waiting_is_an_empty_batch(context: Context) -> None:
    pair = make_pair(context, Imu, "/bagkit_test/take/empty")
    taken = take_serialized(pair.ours, max_count=10, max_bytes=1 << 20)
    assert (taken.payloads, taken.received, taken.sources, taken.sequences, taken.nbytes) == (
        [],
        [],
        [],
        [],
        0,
    )
