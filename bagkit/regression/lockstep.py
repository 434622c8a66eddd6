"""Lockstep replay: a bag's inputs straight into the processors, in-process, on bag time.

No node, no executor, no DDS: each input message is deserialized with rclpy's type support
(``bagkit.ros.serialization``),
handed to every processor that subscribes to its topic with its log time as the clock, and the
processors' timers tick on bag time (see ``_next_tick_ns``), interleaved with the messages.
What the processors return is serialized and written to a candidate bag with the bag time of
the event that produced it as log and publish time. The same bag and parameters always give
the same bytes.
"""

from __future__ import annotations

import functools
import heapq
import math
import time
from collections.abc import Callable, Mapping, Sequence
from dataclasses import dataclass
from pathlib import Path
from typing import Any

from bagkit.bag import BagMessage, BagReader, BagWriter, TopicInfo, message_definition
from bagkit.decode import MessageTypes
from bagkit.decode.cdr import has_wide_strings
from bagkit.decode.layout import CdrLayout, PaddingZeroer
from bagkit.extras import ROS, require
from bagkit.regression.errors import RegressionError
from bagkit.regression.processor import Processor
from bagkit.regression.services import LockstepServices
from bagkit.words import counted


@dataclass(frozen=True, slots=True)
class LockstepResult:
    """What a lockstep run did."""

    output: Path
    input_messages: int
    output_counts: dict[str, int]
    timer_calls: int
    bag_duration_ns: int
    wall_time_s: float

    @property
    def speedup(self) -> float:
        """Bag time covered per second of wall time (how much faster than real time)."""
        return self.bag_duration_ns / 1e9 / self.wall_time_s if self.wall_time_s > 0 else 0.0


def _next_tick_ns(after_ns: int, period_ns: int) -> int:
    # A node under use_sim_time creates its timer at sim time 0, so its ticks fall on the
    # multiples of the period; and when the clock first jumps to the bag's start, the overdue
    # timer fires at once. Lockstep ticks at the first input, then on those multiples.
    return (after_ns // period_ns + 1) * period_ns


@functools.cache
def _canonicalizer(type_name: str, definition: str) -> Callable[[bytes], bytes]:
    """A function that gives a payload of ``type_name`` its one encoding: zeroed padding.

    rclpy's serializer leaves the CDR alignment padding uninitialized (whatever was in memory),
    so the same message serializes to different bytes from run to run. Types with a fixed
    layout once their length prefixes are read get the padding masked out; the others (with
    sequences of messages) are decoded and re-encoded with rosbags. Built once per process and
    definition: building a type's (de)serializers costs milliseconds.
    """
    codec = MessageTypes.from_definitions({type_name: definition})
    store = codec.typestore
    name = codec.resolve(type_name)
    layout = CdrLayout.of(store, name)
    if layout is not None:
        return PaddingZeroer(layout)
    if has_wide_strings(store, name):
        # No CDR writer knows wstring (rosbags' lacks it): kept as rclpy wrote it; the
        # comparison decodes values, so only byte-identity of such outputs is not promised.
        return bytes

    rosbags = codec.rosbags_typestore()

    def reencode(data: bytes) -> bytes:
        return bytes(rosbags.serialize_cdr(rosbags.deserialize_cdr(data, name), name))

    return reencode


class _OutputBag:
    """The candidate bag: topics added on first use, a sequence number per topic."""

    def __init__(self, writer: BagWriter, known: Mapping[str, TopicInfo]) -> None:
        from bagkit.ros.serialization import message_type_name, serialize

        self._type_name: Callable[[Any], str] = message_type_name
        self._serialize: Callable[[Any], bytes] = serialize
        self.writer = writer
        self.known = known
        self.counts: dict[str, int] = {}
        self.canonicalizers: dict[str, Callable[[bytes], bytes]] = {}

    def add_topic(self, info: TopicInfo, definition: str | None = None) -> None:
        self.writer.add_topic(info, definition=definition)
        self.counts[info.name] = 0
        self.canonicalizers[info.name] = _canonicalizer(
            info.type, definition or message_definition(info.type)
        )

    def write(self, topic: str, msg: Any, now_ns: int) -> None:
        if topic not in self.counts:
            golden = self.known.get(topic)
            msg_type = self._type_name(msg)
            qos = golden.offered_qos_profiles if golden and golden.type == msg_type else ""
            self.add_topic(TopicInfo(topic, msg_type, offered_qos_profiles=qos))
        self.counts[topic] += 1
        self.writer.write(
            topic,
            self.canonicalizers[topic](self._serialize(msg)),
            log_time=now_ns,
            publish_time=now_ns,
            sequence=self.counts[topic],
        )

    def copy(self, message: BagMessage) -> None:
        """Write a message of the golden unchanged."""
        self.writer.write(
            message.topic,
            message.data,
            log_time=message.log_time,
            publish_time=message.publish_time,
            sequence=message.sequence,
        )


class _Timers:
    """The processors' timers on bag time; ties fire in processor order, deterministically."""

    def __init__(self, processors: Sequence[Processor], out: _OutputBag) -> None:
        self.processors = processors
        self.out = out
        self.heap: list[tuple[int, int]] = []
        self.calls = 0

    def start(self, start_ns: int) -> None:
        # Timers start with the first input and stop with the last one, as bag time does.
        self.heap = [(start_ns, i) for i, p in enumerate(self.processors) if p.timer_period_ns]

    def fire_until(self, until_ns: int) -> None:
        """Fire every tick before ``until_ns``."""
        while self.heap and self.heap[0][0] < until_ns:
            tick, index = heapq.heappop(self.heap)
            processor = self.processors[index]
            for topic, msg in processor.on_timer(tick):
                self.out.write(topic, msg, tick)
            _drain(processor)
            self.calls += 1
            period = processor.timer_period_ns
            assert period is not None
            heapq.heappush(self.heap, (_next_tick_ns(tick, period), index))


def _drain(processor: Processor) -> None:
    # Nobody reads a processor's log here; draining keeps its buffer bounded.
    drain = getattr(processor, "drain_log", None)
    if drain is not None:
        drain()


def run_lockstep(
    golden: Path,
    output: Path,
    *,
    processors: Sequence[Processor],
    input_topics: Sequence[str] | None = None,
    output_topics: Sequence[str] = (),
    copy_topics: Sequence[str] = (),
    services: Sequence[str] = (),
) -> LockstepResult:
    """Run ``golden``'s inputs through ``processors`` into the bag ``output``.

    Args:
        golden: the bag to read inputs from.
        output: the candidate bag to write (must not exist).
        processors: the system under test (see ``bagkit.regression.Processor``).
        input_topics: the topics fed to the processors (default: every topic a processor
            subscribes to); each must be in the golden bag.
        output_topics: topics created in the output even if nothing is published on them
            (their type and QoS are taken from the golden bag).
        copy_topics: topics of the golden copied unchanged into the output, inputs or not
            (this is how a golden is rewritten with new expected outputs); the golden's
            metadata.yaml ``custom_data`` is then kept too.
        services: services whose recorded requests the processors answer
            (:mod:`bagkit.regression.services`); their event topics are written to the output.

    Raises:
        RegressionError: an input topic is missing or its type is not installed.
        MissingExtraError: rclpy, whose serialization makes the message objects, is not there.
    """
    require(ROS, "lockstep golden replay (ROS message objects)")
    started = time.perf_counter()
    subscribed = {t for p in processors for t in p.input_topics}
    wanted = list(input_topics) if input_topics is not None else sorted(subscribed)
    with BagReader(golden) as reader:
        decoders = _decoders(golden, reader, wanted)
        routes = {t: [p for p in processors if t in p.input_topics] for t in wanted}
        # Chunks closed by size only (not by wall time) keep the file bytes reproducible.
        with BagWriter(output, chunk_interval_s=math.inf) as writer:
            out = _OutputBag(writer, reader.topics)
            copied = [t for t in copy_topics if t in reader.topics]
            if copied and reader.metadata is not None:  # a golden rewritten: keep what it knew
                writer.custom_data.update(reader.metadata.custom_data)
            for t in [*copied, *output_topics]:
                if t in reader.topics and t not in out.counts:
                    info = reader.topics[t]
                    own = reader.topic_definitions.get(t, reader.definitions.get(info.type))
                    out.add_topic(info, own)
            timers = _Timers(processors, out)
            answered = LockstepServices(reader, processors, services) if services else None
            done, start_ns, end_ns = _feed(reader, decoders, routes, copied, out, timers, answered)
            counts = {t: n for t, n in out.counts.items() if t not in copied}
    return LockstepResult(
        output=output,
        input_messages=done,
        output_counts=counts,
        timer_calls=timers.calls,
        bag_duration_ns=end_ns - start_ns,
        wall_time_s=time.perf_counter() - started,
    )


def _decoders(golden: Path, reader: BagReader, topics: list[str]) -> dict[str, Any]:
    """A deserializer per input topic (through bagkit.ros.serialization: rclpy stays there)."""
    from bagkit.ros.errors import MessageClassNotFoundError
    from bagkit.ros.serialization import deserializer

    missing = [t for t in topics if t not in reader.topics]
    if missing:
        raise RegressionError(
            f"{golden}: {counted(len(missing), 'input topic')} missing: {', '.join(missing)}"
        )
    try:
        return {t: deserializer(reader.topics[t].type) for t in topics}
    except MessageClassNotFoundError as exc:
        raise RegressionError(f"{golden}: {exc}") from exc


def _feed(  # noqa: PLR0917 (the run's parts, passed as they are)
    reader: BagReader,
    decoders: dict[str, Any],
    routes: dict[str, list[Processor]],
    copied: list[str],
    out: _OutputBag,
    timers: _Timers,
    services: LockstepServices | None = None,
) -> tuple[int, int, int]:
    """Feed every input message to its processors in log-time order, timers between them;
    return (messages fed, first and last log time)."""
    start_ns = end_ns = 0
    done = 0
    service_topics = services.topics if services is not None else set()
    for bag_msg in reader.messages(topics=sorted({*decoders, *copied, *service_topics})):
        if bag_msg.topic in copied:
            out.copy(bag_msg)
        if bag_msg.topic in service_topics and services is not None:
            timers.fire_until(bag_msg.log_time + 1)
            services.feed(bag_msg, out.write)
            continue
        if bag_msg.topic not in decoders:
            continue
        if not done:
            start_ns = bag_msg.log_time
            timers.start(start_ns)
        end_ns = bag_msg.log_time
        # A tick at exactly a message's time fires before it, as a node that is spinning
        # would see the timer become ready first.
        timers.fire_until(bag_msg.log_time + 1)
        msg = decoders[bag_msg.topic](bag_msg.data)
        for processor in routes[bag_msg.topic]:
            for topic, reply in processor.on_message(bag_msg.topic, msg, bag_msg.log_time):
                out.write(topic, reply, bag_msg.log_time)
            _drain(processor)
        done += 1
    timers.fire_until(end_ns + 1)
    return done, start_ns, end_ns
