"""The bags of one replay as one timeline (no rclpy): several bags merged, in a message order.

``bagkit play BAG1 BAG2`` (or ``-i BAG -i BAG``, rosbag2 Kilted's form) replays the bags as one:
their messages merged by log time (``--message-order received``, the default) or by the time
their publisher sent them (``--message-order sent``), one ``/clock``, a topic present in several
bags one topic. A replay of one bag reads it exactly as before (no merge on the way).
"""

from __future__ import annotations

import heapq
from collections.abc import Iterable, Iterator, Sequence
from contextlib import ExitStack
from enum import Enum
from pathlib import Path

from bagkit.bag import BagMessage, BagReader, TopicInfo
from bagkit.bag.latched import last_messages_before
from bagkit.bag.messages import make_message
from bagkit.playback.errors import PlayerError

# Sent order reorders a stream read in log-time order: a message whose send time is more than
# this before its log time (a delivery that slow) may come out after a later-sent one.
SENT_ORDER_WINDOW_NS = 1_000_000_000


class MessageOrder(str, Enum):
    """Which time orders (and times) the replay: rosbag2 Kilted's ``--message-order``."""

    RECEIVED = "received"
    """Log time: when the recorder received each message (rosbag2's default)."""
    SENT = "sent"
    """Publish time: when its publisher sent it (the bag's ``publish_time``)."""


class PlaySource:
    """One or several opened bags, read as one timeline.

    Args:
        readers: the opened bags, in the order given on the command line.
        order: merge (and schedule) by log time or by send time.

    Raises:
        PlayerError: a topic has different types in two bags (both named).
    """

    def __init__(self, readers: Sequence[BagReader], order: MessageOrder) -> None:
        self.readers = list(readers)
        self.order = order
        self.topics: dict[str, TopicInfo] = {}
        self.topic_counts: dict[str, int] = {}
        owner: dict[str, Path] = {}
        for reader in self.readers:
            for name, info in reader.topics.items():
                known = self.topics.get(name)
                if known is not None and known.type != info.type:
                    raise PlayerError(
                        f"topic {name} is {known.type} in {owner[name]} but {info.type} in "
                        f"{reader.path}: one replay publishes a topic under one type"
                    )
                self.topics.setdefault(name, info)
                owner.setdefault(name, reader.path)
                self.topic_counts[name] = self.topic_counts.get(name, 0) + reader.topic_counts.get(
                    name, 0
                )
        with_messages = [r for r in self.readers if r.message_count] or self.readers
        self.start_ns = min(r.start_ns for r in with_messages)
        self.end_ns = max(r.end_ns for r in with_messages)

    @classmethod
    def open(cls, paths: Sequence[Path], order: MessageOrder, stack: ExitStack) -> PlaySource:
        """Open every bag of ``paths`` (closed with ``stack``)."""
        if not paths:
            raise PlayerError("no bag to replay")
        readers = [stack.enter_context(BagReader(path)) for path in paths]
        return cls(readers, order)

    def definition(self, topic: str) -> str | None:
        """The stored definition of ``topic``'s type in the first bag holding it (None: none)."""
        for reader in self.readers:
            info = reader.topics.get(topic)
            if info is not None:
                return reader.topic_definitions.get(topic, reader.definitions.get(info.type))
        return None

    @property
    def name(self) -> str:
        """The bags, for messages: ``drive`` or ``drive + lidar``."""
        return " + ".join(str(reader.path) for reader in self.readers)

    @property
    def message_count(self) -> int:
        """Messages in all the bags."""
        return sum(self.topic_counts.values())

    @property
    def uncompressed_size(self) -> int:
        """Bytes of message data in all the bags (MCAP chunks decompressed)."""
        return sum(reader.uncompressed_size for reader in self.readers)

    @property
    def problems(self) -> list[str]:
        """What the readers could not read, so far."""
        return [problem for reader in self.readers for problem in reader.problems]

    def messages(
        self, topics: Iterable[str] | None, start_ns: int | None, end_ns: int | None
    ) -> Iterator[BagMessage]:
        """Messages of ``topics`` logged in ``[start_ns, end_ns)``, in the replay's order.

        In sent order each message's ``log_time`` is its send time (``publish_time``, or the
        log time where the bag has none): the player schedules and stamps ``/clock`` by it.
        """
        wanted = None if topics is None else list(topics)
        streams = [reader.messages(wanted, start_ns, end_ns) for reader in self.readers]
        if self.order is MessageOrder.SENT:
            streams = [_sent_order(stream) for stream in streams]
        if len(streams) == 1:
            return streams[0]
        return heapq.merge(*streams, key=_log_time)

    def largest_message(self, topics: Iterable[str]) -> int:
        """Payload bytes of the largest message of ``topics`` over the bags, from their indexes
        (:meth:`~bagkit.bag.reader.BagReader.largest_message`).

        What the player sizes its shared-memory segment by; a topic's messages are taken to be
        of one size (images, point clouds of one sensor), without reading the bag.
        """
        wanted = set(topics)
        return max((reader.largest_message(wanted) for reader in self.readers), default=0)

    def latched_before(self, before_ns: int, topics: set[str]) -> list[BagMessage]:
        """The latched state at ``before_ns`` over all the bags, in log-time order.

        The last message before it of each of ``topics`` (the latched ones,
        :func:`bagkit.bag.latched.latched_topics`), found from the storage indexes, the latest
        of any bag.
        """
        latest: dict[str, BagMessage] = {}
        for reader in self.readers:
            found = last_messages_before(reader, topics & set(reader.topics), before_ns)
            for topic, message in found.items():
                if topic not in latest or message.log_time >= latest[topic].log_time:
                    latest[topic] = message
        return sorted(latest.values(), key=lambda m: (m.log_time, m.topic))


def _log_time(message: BagMessage) -> int:
    return message.log_time


def _sent_order(messages: Iterator[BagMessage]) -> Iterator[BagMessage]:
    """Re-time messages by send time and reorder them within ``SENT_ORDER_WINDOW_NS``."""
    pending: list[tuple[int, int, BagMessage]] = []
    for index, message in enumerate(messages):
        sent = message.publish_time or message.log_time
        timed = make_message(message.topic, message.data, sent, sent, message.sequence)
        heapq.heappush(pending, (sent, index, timed))
        horizon = message.log_time - SENT_ORDER_WINDOW_NS
        while pending and pending[0][0] <= horizon:
            yield heapq.heappop(pending)[2]
    while pending:
        yield heapq.heappop(pending)[2]
