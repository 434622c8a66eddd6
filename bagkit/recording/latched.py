"""The latched state of a recording: the last messages of each transient-local topic.

A bag file (a split file, a snapshot) that starts in the middle of a recording lacks the
messages that were published once and latched (``/tf_static``, a map, ``/alerts``); a replay of
that file alone misses them. :class:`LatchedState` keeps the last ``N`` messages of each such
topic, so that they can be written again at the start of the file. No rclpy import.

Which topics are latched is :func:`bagkit.bag.latched.is_transient_local`'s rule (the one
replay, seek and filter use too), plus the topics ``--repeat-transient-local`` names.
"""

from __future__ import annotations

from collections import deque
from collections.abc import Mapping, Sequence

from bagkit.bag.latched import is_transient_local
from bagkit.bag.messages import BagMessage, TopicInfo
from bagkit.recording.errors import RecorderOptionsError
from bagkit.recording.options import RecordOptions
from bagkit.selection.topics import absolute_topic_name

# How many messages of a latched topic are repeated when nothing else is said (rosbag2's too).
DEFAULT_DEPTH = 1


def parse_repeat(values: Sequence[str]) -> dict[str, int]:
    """``TOPIC[=N]`` values (``--repeat-transient-local``) -> {absolute topic: N}.

    Raises:
        RecorderOptionsError: an empty topic, or N that is not a positive integer (field
            ``repeat_transient_local``).
    """
    depths: dict[str, int] = {}
    for value in values:
        topic, sep, count = value.partition("=")
        if not topic.strip():
            raise RecorderOptionsError(f"{value!r}: no topic", "repeat_transient_local")
        depth = DEFAULT_DEPTH
        if sep:
            if not count.isdigit() or int(count) < 1:
                raise RecorderOptionsError(
                    f"{value!r}: N must be a positive integer", "repeat_transient_local"
                )
            depth = int(count)
        depths[absolute_topic_name(topic.strip())] = depth
    return depths


class LatchedState:
    """The last ``depth`` messages of each latched topic, oldest first.

    Args:
        depths: topic -> how many of its last messages to keep.
    """

    def __init__(self, depths: Mapping[str, int] | None = None) -> None:
        self._held: dict[str, deque[BagMessage]] = {
            topic: deque(maxlen=depth) for topic, depth in (depths or {}).items()
        }

    def track(self, topic: str, depth: int) -> None:
        """Keep the last ``depth`` messages of ``topic`` (a topic found latched later)."""
        if topic not in self._held:
            self._held[topic] = deque(maxlen=depth)

    def tracks(self, topic: str) -> bool:
        """Whether ``topic``'s messages are kept."""
        return topic in self._held

    def depth(self, topic: str) -> int:
        """How many of ``topic``'s last messages are kept (0: not latched)."""
        held = self._held.get(topic)
        return 0 if held is None else held.maxlen or 0

    def observe(self, message: BagMessage) -> None:
        """Keep ``message`` if its topic is tracked (the oldest kept one makes room)."""
        held = self._held.get(message.topic)
        if held is not None:
            held.append(message)

    def observe_batch(
        self,
        topic: str,
        payloads: Sequence[bytes],
        log_times: Sequence[int],
        publish_times: Sequence[int],
        sequences: Sequence[int],
    ) -> None:
        """:meth:`observe` for columns of one topic (only the last ``depth`` are looked at)."""
        held = self._held.get(topic)
        if held is None or not payloads:
            return
        first = max(0, len(payloads) - (held.maxlen or 0))
        for index in range(first, len(payloads)):
            held.append(
                BagMessage(
                    topic, payloads[index], log_times[index], publish_times[index], sequences[index]
                )
            )

    def messages(self, before_ns: int | None = None) -> list[BagMessage]:
        """The kept messages (those older than ``before_ns`` if given), by topic, oldest first."""
        return [
            message
            for topic in sorted(self._held)
            for message in self._held[topic]
            if before_ns is None or message.log_time < before_ns
        ]


def latched_depth(topic: TopicInfo, options: RecordOptions) -> int:
    """How many of ``topic``'s last messages start every file (0: none)."""
    named = options.repeat_transient_local.get(topic.name)
    if named is not None:
        return named
    if options.repeats_all_transient_local and is_transient_local(topic.offered_qos_profiles):
        return DEFAULT_DEPTH
    return 0


class LatchedRepeats:
    """The latched state a recording repeats at the start of each split file.

    Args:
        options: the recording's options (which topics, how many messages).
    """

    def __init__(self, options: RecordOptions) -> None:
        self.state = LatchedState()
        self._options = options

    @staticmethod
    def wanted(options: RecordOptions) -> bool:
        """Whether the options ask for repeats at all."""
        return bool(options.repeat_transient_local) or options.repeats_all_transient_local

    def add_topic(self, topic: TopicInfo) -> None:
        """Track ``topic`` if it is latched."""
        depth = latched_depth(topic, self._options)
        if depth:
            self.state.track(topic.name, depth)
