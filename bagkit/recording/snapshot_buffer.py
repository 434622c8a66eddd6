"""The snapshot buffer: the newest messages of a recording, bounded in bytes and in seconds.

One buffer (rosbag2 keeps two, so its memory reaches twice ``--max-cache-size``): messages are
appended in batches as the recorder takes them and the oldest are evicted as soon as the bound
is exceeded. A snapshot reads a window of it without copying the payloads. Evicted messages of
latched topics are handed to a :class:`~bagkit.recording.latched.LatchedState`, so that the
state before a snapshot's window can be written at its start. No rclpy import.
"""

from __future__ import annotations

from collections import Counter, deque
from collections.abc import Sequence
from dataclasses import dataclass

from bagkit.bag.messages import BagMessage
from bagkit.recording.latched import LatchedState

# What a buffered message costs beyond its payload: the bytes object's header, four list slots
# and three int objects (measured with tracemalloc: 150 - 165 bytes). Counted in the bound so
# that it bounds memory, not only payload bytes.
MESSAGE_OVERHEAD = 160


@dataclass(slots=True)
class MessageSlice:
    """Messages of one topic, oldest first, one list per field (what a bag writer takes)."""

    topic: str
    payloads: list[bytes]
    log_times: list[int]
    publish_times: list[int]
    sequences: list[int]

    def __len__(self) -> int:
        return len(self.payloads)


@dataclass(slots=True)
class _Block:
    """A batch of one topic as it was added; ``start`` is its oldest message still held."""

    messages: MessageSlice
    nbytes: int
    start: int = 0


class SnapshotBuffer:
    """The newest messages, at most ``max_bytes`` (with overhead) and ``max_duration_ns`` apart.

    Args:
        max_bytes: bound on payload bytes plus ``MESSAGE_OVERHEAD`` per message (0: none).
        max_duration_ns: the oldest message is at most this much log time older than the
            newest (0: none).
        latched: receives the evicted messages of the topics it tracks.

    Raises:
        ValueError: neither bound is given, or one is negative.
    """

    def __init__(
        self, max_bytes: int = 0, max_duration_ns: int = 0, latched: LatchedState | None = None
    ) -> None:
        if max_bytes < 0 or max_duration_ns < 0 or not (max_bytes or max_duration_ns):
            raise ValueError("a snapshot buffer needs a positive byte or duration bound")
        self.max_bytes = max_bytes
        self.max_duration_ns = max_duration_ns
        self.latched = latched if latched is not None else LatchedState()
        self.evicted: Counter[str] = Counter()
        self.held_bytes = 0
        self.held_messages = 0
        self.newest_ns = 0
        self._blocks: deque[_Block] = deque()

    @property
    def oldest_ns(self) -> int | None:
        """Log time of the oldest message held (None when empty)."""
        if not self._blocks:
            return None
        block = self._blocks[0]
        return block.messages.log_times[block.start]

    def add(
        self,
        topic: str,
        payloads: Sequence[bytes],
        log_times: Sequence[int],
        publish_times: Sequence[int],
        sequences: Sequence[int],
    ) -> None:
        """Append messages of one topic (oldest first), then evict down to the bounds."""
        if not payloads:
            return
        messages = MessageSlice(
            topic, list(payloads), list(log_times), list(publish_times), list(sequences)
        )
        nbytes = sum(map(len, payloads)) + MESSAGE_OVERHEAD * len(payloads)
        self._blocks.append(_Block(messages, nbytes))
        self.held_bytes += nbytes
        self.held_messages += len(payloads)
        self.newest_ns = max(self.newest_ns, log_times[-1])
        self._evict()

    def window(self, start_ns: int | None = None, end_ns: int | None = None) -> list[MessageSlice]:
        """The held messages with ``start_ns <= log_time <= end_ns``, in the order added."""
        found = []
        for block in self._blocks:
            messages = block.messages
            times = messages.log_times
            indexes = [
                i
                for i in range(block.start, len(times))
                if (start_ns is None or times[i] >= start_ns)
                and (end_ns is None or times[i] <= end_ns)
            ]
            if indexes:
                first, last = indexes[0], indexes[-1] + 1
                if len(indexes) == last - first:
                    found.append(_slice(messages, first, last))
                else:  # a batch out of log-time order: pick the messages one by one
                    found.append(_pick(messages, indexes))
        return found

    def latched_before(self, start_ns: int) -> list[BagMessage]:
        """The last messages of each latched topic logged before ``start_ns``, evicted or held.

        As many per topic as the latched state keeps for it, oldest first.
        """
        latched = self.latched
        by_topic: dict[str, list[BagMessage]] = {}
        for message in latched.messages(before_ns=start_ns):
            by_topic.setdefault(message.topic, []).append(message)
        for block in self._blocks:
            messages = block.messages
            if not latched.tracks(messages.topic):
                continue
            kept = by_topic.setdefault(messages.topic, [])
            for i in range(block.start, len(messages)):
                if messages.log_times[i] < start_ns:
                    kept.append(_held(messages, i))
        return [
            message
            for topic in sorted(by_topic)
            for message in sorted(by_topic[topic], key=lambda m: m.log_time)[
                -latched.depth(topic) :
            ]
        ]

    def _evict(self) -> None:
        blocks = self._blocks
        while blocks and self._over_bound():
            block = blocks[0]
            size = len(block.messages)
            self._drop(block, size if self._evicts_whole(block) else block.start + 1)
            if block.start == size:
                blocks.popleft()

    def _over_bound(self) -> bool:
        if self.max_bytes and self.held_bytes > self.max_bytes:
            return True
        oldest = self.oldest_ns
        return bool(
            self.max_duration_ns
            and oldest is not None
            and self.newest_ns - oldest > self.max_duration_ns
        )

    def _evicts_whole(self, block: _Block) -> bool:
        """Whether a bound needs the whole oldest block gone (cheaper than message by message)."""
        if self.max_bytes and self.held_bytes - block.nbytes >= self.max_bytes:
            return True
        newest_in_block = block.messages.log_times[-1]
        return bool(self.max_duration_ns) and (
            self.newest_ns - newest_in_block > self.max_duration_ns
        )

    def _drop(self, block: _Block, until: int) -> None:
        """Evict the block's messages from ``block.start`` up to ``until``."""
        messages = block.messages
        topic = messages.topic
        latched = self.latched.tracks(topic)
        freed = 0
        for i in range(block.start, until):
            freed += len(messages.payloads[i]) + MESSAGE_OVERHEAD
            if latched:
                self.latched.observe(_held(messages, i))
            messages.payloads[i] = b""  # the payload's memory goes now, not with the block
        count = until - block.start
        block.start = until
        block.nbytes -= freed
        self.held_bytes -= freed
        self.held_messages -= count
        self.evicted[topic] += count


def _slice(messages: MessageSlice, first: int, last: int) -> MessageSlice:
    return MessageSlice(
        messages.topic,
        messages.payloads[first:last],
        messages.log_times[first:last],
        messages.publish_times[first:last],
        messages.sequences[first:last],
    )


def _pick(messages: MessageSlice, indexes: list[int]) -> MessageSlice:
    return MessageSlice(
        messages.topic,
        [messages.payloads[i] for i in indexes],
        [messages.log_times[i] for i in indexes],
        [messages.publish_times[i] for i in indexes],
        [messages.sequences[i] for i in indexes],
    )


def _held(messages: MessageSlice, index: int) -> BagMessage:
    return BagMessage(
        messages.topic,
        messages.payloads[index],
        messages.log_times[index],
        messages.publish_times[index],
        messages.sequences[index],
    )
