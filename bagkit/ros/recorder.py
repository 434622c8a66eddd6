"""Record ROS 2 topics into a rosbag2-compatible MCAP bag, counting every lost message.

Two threads do the work. The *take* thread owns the node: it polls the graph (every
``discovery_period_s``), subscribes raw with QoS adapted to the publishers' offers, waits on a
wait set and drains every ready subscription with ``take_message(raw=True)``; an executor
callback per message would cost about 200 us, far too slow for a recorder. Batches go to the
*writer* thread through a queue bounded in bytes; when it stays full for a second a batch is
dropped and counted. The writer thread writes the bag and accounts for loss.

Loss per topic, three kinds, all 0 when the system keeps up:
- ``gaps``: holes in the publishers' publication sequence numbers, i.e. messages lost inside
  the middleware (best-effort drops, keep-last queues overwritten before we took them);
- ``overflow``: taken but dropped because the write queue was full;
- ``write_failed``: handed to the bag writer but not in the bag (disk full).
"""

from __future__ import annotations

import contextlib
import ctypes
import ctypes.util
import json
import logging
import struct
import threading
import time
from collections import deque
from collections.abc import Callable, Mapping
from dataclasses import dataclass, field
from datetime import datetime
from pathlib import Path
from types import TracebackType
from typing import Any

import rclpy
from rclpy.context import Context
from rclpy.guard_condition import GuardCondition
from rclpy.impl.implementation_singleton import rclpy_implementation as _rclpy
from rclpy.node import Node
from rclpy.qos import (
    DurabilityPolicy,
    QoSProfile,
    ReliabilityPolicy,
)
from rclpy.signals import SignalHandlerOptions
from rclpy.subscription import Subscription

from bagkit.bag import BagReader, BagWriteError, BagWriter, TopicInfo
from bagkit.bag.errors import BagError
from bagkit.ros.errors import MessageClassNotFoundError, RecorderOptionsError, RecordingFailedError
from bagkit.ros.graph import DiscoveredTopic, TopicFilter, discover_topics
from bagkit.ros.qos import adapt_subscription_qos, dump_offered_qos_profiles
from bagkit.ros.take import TakenMessages, take_serialized
from bagkit.ros.types import import_message_type

_log = logging.getLogger(__name__)

DISCOVERY_PERIOD_S = 0.1
# Bounds the memory held between taking and writing: absorbs writer hiccups (a slow disk
# write, a chunk to compress); beyond that the middleware holds the messages (see _Queue).
DEFAULT_QUEUE_BYTES = 64 << 20
# Messages taken from one subscription before looking at the others, so that a flood on one
# topic does not starve the rest, and before handing a batch to the writer; a topic's burst
# also ends at TAKE_BURST_BYTES (four 1 MB images), so batches stay far below the queue bound.
TAKE_BURST = 256
TAKE_BURST_BYTES = 4 << 20
# How long taken messages may wait before they are handed to the writer.
BATCH_AGE_S = 0.005
# While messages flow, the take thread takes from every subscription in turn instead of waiting
# on the wait set (a wait costs 30 us of CPU here even when data is there, an empty take
# 0.7 us), and after a round that found fewer than PAUSE_BELOW messages it first lets PAUSE_S
# pass: any wake-up costs 30 - 40 us on this kind of machine (a bare 1 ms sleep: 36 us of CPU),
# so a topic at a few kHz is better taken a few messages per wake-up than one. The messages
# wait in the middleware with their receive times already stamped; the best-effort
# subscriptions' keep-last depth (RECORD_DEPTH) holds 2 ms of up to 500k messages/s.
PAUSE_BELOW = 16
PAUSE_S = 0.002
# How long the take thread waits for room in a full write queue before dropping a batch.
QUEUE_WAIT_S = 1.0
# How long a stop (or a re-subscription) keeps taking what the middleware already holds.
DRAIN_S = 1.0
# The writer closes a chunk at least this often, so a killed recorder loses at most this much.
FLUSH_PERIOD_S = 1.0
CLOCK_TOPIC = "/clock"
# mallopt parameters (glibc malloc.h) and the largest mmap threshold glibc accepts on 64 bits.
_M_TRIM_THRESHOLD = -1
_M_MMAP_THRESHOLD = -3
_MMAP_THRESHOLD_MAX = 32 << 20
_PR_SET_NAME = 15  # prctl option (linux/prctl.h)
CUSTOM_DATA_PREFIX = "bagkit.record."


def _libc_function(name: str) -> Any:
    """A C library function through ctypes, or None where there is no such library or function."""
    try:
        return getattr(ctypes.CDLL(ctypes.util.find_library("c") or "libc.so.6"), name)
    except (OSError, AttributeError):
        return None


def name_native_thread(name: str) -> None:
    """Give the calling thread ``name`` (15 bytes at most) in ``top -H``, ``ps -L`` and /proc.

    Python 3.11 names only its own thread objects; without this every thread of the recorder
    shows up as ``python`` beside the middleware's named ones. No-op without glibc.
    """
    prctl = _libc_function("prctl")
    if prctl is not None:
        prctl(_PR_SET_NAME, name.encode()[:15], 0, 0, 0)


def keep_freed_memory() -> None:
    """Let glibc keep freed large buffers for reuse instead of returning them to the kernel.

    Each large message taken is a fresh allocation; glibc serves those with ``mmap`` and unmaps
    them on free, so every 1 MB image costs 256 page faults per copy (measured here: copying
    1 MB 0.8 ms -> 0.08 ms, writing it 2.7 ms -> 0.8 ms). Process-wide, so ``bagkit record``
    calls it for its own process; the :class:`Recorder` does not. No-op without glibc.
    """
    mallopt = _libc_function("mallopt")
    if mallopt is None:
        return
    mallopt(_M_MMAP_THRESHOLD, _MMAP_THRESHOLD_MAX)
    mallopt(_M_TRIM_THRESHOLD, 4 * _MMAP_THRESHOLD_MAX)


def default_output_name(now: datetime | None = None) -> str:
    """``rosbag2_YYYY_MM_DD-HH_MM_SS`` in local time, as ``ros2 bag record`` names its bags."""
    return (now or datetime.now()).strftime("rosbag2_%Y_%m_%d-%H_%M_%S")


# -- loss accounting ----------------------------------------------------------------------------


class SequenceTracker:
    """Count holes in publication sequence numbers of one topic's publishers.

    rclpy does not give the publisher of a message (rmw's ``publisher_gid`` is not in the
    message info), so the messages are attributed to *streams*: a number that continues a
    stream extends it; otherwise, while there are fewer streams than matched publishers, it
    starts a new one (a publisher's first message after matching is not a loss); otherwise the
    stream it skipped ahead from (the highest number below it) counts the hole. A number below
    every stream is a publisher that restarted. Exact with one publisher; with several whose
    numbers run close to each other, a lossy stretch can be attributed to the wrong stream and
    the count be off by a few (an estimate, never a silent zero).
    """

    __slots__ = ("_hot", "_last", "publishers")

    def __init__(self) -> None:
        self._last: list[int] = []
        self._hot = 0  # the stream that advanced last: where the next number most likely goes
        self.publishers = 0

    def observe(self, sequence: int, matched_publishers: Callable[[], int]) -> int:
        """Account for one received ``sequence`` number; return how many messages were skipped.

        ``matched_publishers`` is asked only when the number does not continue a stream.
        """
        last = self._last
        hot = self._hot
        if last and last[hot] + 1 == sequence:
            last[hot] = sequence
            return 0
        for i, previous in enumerate(last):
            if sequence == previous + 1:
                last[i] = sequence
                self._hot = i
                return 0
        if len(last) < max(1, matched_publishers()):
            last.append(sequence)
            self._hot = len(last) - 1
            self.publishers = max(self.publishers, len(last))
            return 0
        below = [(previous, i) for i, previous in enumerate(last) if previous < sequence]
        if not below:
            # Restarted publisher (numbers start again), or a duplicate: nothing lost.
            self._hot = last.index(max(last))
            last[self._hot] = sequence
            return 0
        previous, self._hot = max(below)
        last[self._hot] = sequence
        return sequence - previous - 1

    def observe_many(self, sequences: list[int], matched_publishers: Callable[[], int]) -> int:
        """Account for received ``sequences`` in order (0: unknown, skipped); return the skipped.

        The common case, a run that continues the last stream without a hole, costs one list
        comparison instead of a call per number.
        """
        last = self._last
        if sequences and last:
            expected = last[self._hot] + 1
            if sequences == list(range(expected, expected + len(sequences))):
                last[self._hot] = sequences[-1]
                return 0
        observe = self.observe
        return sum(observe(sequence, matched_publishers) for sequence in sequences if sequence)


# -- results -------------------------------------------------------------------------------------


@dataclass(slots=True)
class TopicRecord:
    """What was recorded on one topic, and what was lost."""

    topic: str
    type: str
    messages: int = 0
    bytes: int = 0
    gaps: int = 0
    overflow: int = 0
    write_failed: int = 0
    publishers: int = 0
    first_ns: int = 0
    last_ns: int = 0

    @property
    def lost(self) -> int:
        """Every message of this topic that is not in the bag."""
        return self.gaps + self.overflow + self.write_failed

    @property
    def rate_hz(self) -> float:
        """Average message rate between the first and the last message (receive time)."""
        span = self.last_ns - self.first_ns
        return (self.messages - 1) / span * 1e9 if self.messages > 1 and span > 0 else 0.0

    def to_dict(self) -> dict[str, Any]:
        """JSON-ready view, with ``lost`` and ``rate_hz``."""
        return {
            "topic": self.topic,
            "type": self.type,
            "messages": self.messages,
            "lost": self.lost,
            "gaps": self.gaps,
            "overflow": self.overflow,
            "write_failed": self.write_failed,
            "publishers": self.publishers,
            "rate_hz": self.rate_hz,
            "bytes": self.bytes,
        }


@dataclass(slots=True)
class RecordReport:
    """The outcome of a recording: per-topic counts, skipped topics, the error that stopped it."""

    path: Path
    duration_s: float = 0.0
    topics: list[TopicRecord] = field(default_factory=list)
    skipped: dict[str, str] = field(default_factory=dict)
    error: str | None = None

    @property
    def messages(self) -> int:
        """Messages in the bag."""
        return sum(t.messages for t in self.topics)

    @property
    def lost(self) -> int:
        """Messages lost on every topic together."""
        return sum(t.lost for t in self.topics)

    @property
    def bytes(self) -> int:
        """Serialized message bytes in the bag."""
        return sum(t.bytes for t in self.topics)

    def topic(self, name: str) -> TopicRecord:
        """The record of topic ``name`` (KeyError if it was not recorded)."""
        for record in self.topics:
            if record.topic == name:
                return record
        raise KeyError(name)

    def to_dict(self) -> dict[str, Any]:
        """JSON-ready view."""
        return {
            "path": str(self.path),
            "duration_s": self.duration_s,
            "messages": self.messages,
            "lost": self.lost,
            "bytes": self.bytes,
            "topics": [t.to_dict() for t in self.topics],
            "skipped": dict(self.skipped),
            "error": self.error,
        }


@dataclass(frozen=True, slots=True)
class RecordProgress:
    """A snapshot of a running recording, for a progress line."""

    elapsed_s: float
    topics: int
    messages: int
    bytes: int
    lost: int


# -- the queue between the threads ---------------------------------------------------------------


@dataclass(slots=True)
class _Topic:
    """A subscribed topic: its subscription, what re-subscribing needs (type, QoS), its counts."""

    record: TopicRecord
    subscription: Subscription
    message_type: Any
    qos: QoSProfile
    tracker: SequenceTracker = field(default_factory=SequenceTracker)


# One drained batch: the messages taken from each ready topic.
_Batch = list[tuple[_Topic, TakenMessages]]


class _Queue:
    """FIFO between the threads, bounded in message bytes.

    ``put_batch`` waits up to ``QUEUE_WAIT_S`` for room, so that a writer hiccup turns into
    back-pressure (reliable topics are subscribed keep-all: the middleware holds the messages
    and slows keep-all publishers) rather than loss; after that the batch is dropped and
    counted. Control items (new topics, dropped-batch markers, the end) are always accepted,
    so that the writer sees them in order with the messages.
    """

    def __init__(self, max_bytes: int) -> None:
        self._items: deque[tuple[str, Any, int]] = deque()
        self._bytes = 0
        self._max_bytes = max_bytes
        self._lock = threading.Lock()
        self._not_empty = threading.Condition(self._lock)
        self._not_full = threading.Condition(self._lock)

    def put_batch(self, sim_time: int | None, batch: _Batch, nbytes: int) -> bool:
        with self._lock:
            # An oversized batch still goes into an empty queue.
            accepted = self._not_full.wait_for(
                lambda: not self._bytes or self._bytes + nbytes <= self._max_bytes,
                QUEUE_WAIT_S,
            )
            if accepted:
                self._items.append(("batch", (sim_time, batch), nbytes))
                self._bytes += nbytes
            else:
                self._items.append(("dropped", batch, 0))
            self._not_empty.notify()
            return accepted

    def put_control(self, kind: str, payload: Any = None) -> None:
        with self._lock:
            self._items.append((kind, payload, 0))
            self._not_empty.notify()

    def get(self, timeout: float) -> tuple[str, Any] | None:
        with self._lock:
            if not self._items and not self._not_empty.wait(timeout):
                return None
            if not self._items:
                return None
            kind, payload, nbytes = self._items.popleft()
            if nbytes:
                self._bytes -= nbytes
                self._not_full.notify()
            return kind, payload


def _clock_ns(data: bytes) -> int:
    """``rosgraph_msgs/msg/Clock`` CDR -> ns (after the 4-byte encapsulation header)."""
    endian = "<" if data[1] & 1 else ">"
    sec, nanosec = struct.unpack_from(f"{endian}iI", data, 4)
    return sec * 1_000_000_000 + nanosec


# -- the recorder --------------------------------------------------------------------------------


class Recorder:
    """Record topics into a bag; a context manager (``start`` on enter, ``stop`` on exit).

    Example::

        with Recorder("run1", all_topics=True) as recorder:
            time.sleep(10)
        print(recorder.report.messages, recorder.report.lost)

    Args:
        output: the bag directory to create (it must not exist).
        topics: topic names to record (always recorded, hidden or not).
        all_topics: record every topic (hidden ones only with ``include_hidden``).
        regex: also record topics whose name contains a match of this regular expression.
        exclude: do not record topics (selected by ``all_topics``/``regex``) matching this.
        include_hidden: let ``all_topics``/``regex`` select hidden topics.
        compression: ``zstd`` (default), ``lz4`` or ``none``.
        max_bag_size: split into a new file at this many bytes (0: never).
        max_bag_duration_s: split when a file spans this many seconds (0: never).
        qos_overrides: topic -> subscription profile, instead of the adapted one.
        use_sim_time: ``log_time`` is the latest ``/clock`` time when the message was taken
            (0 before the first), as ``ros2 bag record --use-sim-time``.
        context: an initialized rclpy context to use; default: a private one.
        node_name: the recorder node's name.
        queue_bytes: bound of the queue between taking and writing.
        discovery_period_s: how often the graph is polled for new topics and publishers.
        on_warning: called (from the recording thread) with each warning, such as a topic
            skipped because its message package is not installed; default: logging.

    Raises:
        RecorderOptionsError: nothing selected, bad regex, or ``output`` exists.
    """

    def __init__(
        self,
        output: str | Path,
        *,
        topics: tuple[str, ...] | list[str] = (),
        all_topics: bool = False,
        regex: str | None = None,
        exclude: str | None = None,
        include_hidden: bool = False,
        compression: str = "zstd",
        max_bag_size: int = 0,
        max_bag_duration_s: float = 0,
        qos_overrides: Mapping[str, QoSProfile] | None = None,
        use_sim_time: bool = False,
        context: Context | None = None,
        node_name: str = "bagkit_recorder",
        queue_bytes: int = DEFAULT_QUEUE_BYTES,
        discovery_period_s: float = DISCOVERY_PERIOD_S,
        on_warning: Callable[[str], None] | None = None,
    ) -> None:
        self.path = Path(output)
        self.filter = TopicFilter.create(
            topics,
            all_topics=all_topics,
            regex=regex,
            exclude=exclude,
            include_hidden=include_hidden,
        )
        if self.path.exists():
            raise RecorderOptionsError(
                f"{self.path} already exists (bagkit never overwrites a bag)"
            )
        if max_bag_size < 0 or max_bag_duration_s < 0:
            raise RecorderOptionsError("--max-bag-size and --max-bag-duration must be >= 0")
        self.compression = compression
        self.max_bag_size = max_bag_size
        self.max_bag_duration_s = max_bag_duration_s
        self.qos_overrides = dict(qos_overrides or {})
        self.use_sim_time = use_sim_time
        self.discovery_period_s = discovery_period_s
        self.report = RecordReport(self.path)
        self._context = context
        self._node_name = node_name
        self._queue = _Queue(queue_bytes)
        self._topics: dict[str, _Topic] = {}
        self._warned: set[str] = set()
        self._stopping = threading.Event()
        self._stopped = threading.Event()
        self._lock = threading.Lock()
        self._own_context: Context | None = None
        self._node: Node | None = None
        self._wake: GuardCondition | None = None
        self._bag: BagWriter | None = None
        self._threads: list[threading.Thread] = []
        self._started = 0.0
        self._clock: Subscription | None = None
        self._sim_time: int = 0
        self._errors: list[str] = []
        # Bumped whenever a subscription is added or replaced: the wait set is rebuilt.
        self._generation = 0
        self._on_warning = on_warning

    # -- lifecycle ------------------------------------------------------------------------------

    def __enter__(self) -> Recorder:
        self.start()
        return self

    def __exit__(
        self,
        exc_type: type[BaseException] | None,
        exc: BaseException | None,
        tb: TracebackType | None,
    ) -> None:
        report = self.stop()
        if exc is None and report.error is not None:
            raise RecordingFailedError(report.error)

    @property
    def stopped(self) -> threading.Event:
        """Set when the bag is finished: after ``stop``, or on an error such as a full disk."""
        return self._stopped

    def start(self) -> None:
        """Create the bag and the node, and start recording.

        Raises:
            RecorderOptionsError: the output exists or cannot be created, or a bag option is
                invalid.
        """
        try:
            self._bag = BagWriter(
                self.path,
                compression=self.compression,
                max_bag_size=self.max_bag_size,
                max_bag_duration_s=self.max_bag_duration_s,
                chunk_interval_s=FLUSH_PERIOD_S,
            ).open()
        except BagError as exc:
            raise RecorderOptionsError(str(exc)) from None
        try:
            self._start_node()
        except BaseException:
            self._bag.close()
            self._shutdown_node()
            raise
        self._started = time.monotonic()
        self._discover()
        self._threads = [
            threading.Thread(target=self._take_loop, name="bagkit-record-take", daemon=True),
            threading.Thread(target=self._write_loop, name="bagkit-record-write", daemon=True),
        ]
        for thread in self._threads:
            thread.start()

    def _start_node(self) -> None:
        context = self._context
        if context is None:
            context = Context()
            # No signal handlers: the caller decides what Ctrl-C means (stop and finish the bag).
            rclpy.init(context=context, signal_handler_options=SignalHandlerOptions.NO)
            self._own_context = context
        self._node = Node(
            self._node_name,
            context=context,
            start_parameter_services=False,
            enable_rosout=False,
        )
        self._wake = GuardCondition(None, None, context=context)
        if self.use_sim_time:
            from rosgraph_msgs.msg import Clock

            self._clock = self._node.create_subscription(
                Clock,
                CLOCK_TOPIC,
                _never_called,
                QoSProfile(depth=10, reliability=ReliabilityPolicy.BEST_EFFORT),
                raw=True,
            )

    def _shutdown_node(self) -> None:
        if self._node is not None:
            self._node.destroy_node()
            self._node = None
        if self._own_context is not None:
            self._own_context.try_shutdown()
            self._own_context = None

    def stop(self) -> RecordReport:
        """Stop taking messages, write what was taken, finish the bag; return the report.

        Safe to call twice. The report's ``error`` says why a recording ended early.
        """
        self._stopping.set()
        if self._wake is not None:
            self._wake.trigger()
        for thread in self._threads:
            thread.join()
        self._threads = []
        self._shutdown_node()
        self._stopped.set()
        return self.report

    def progress(self) -> RecordProgress:
        """Counts so far (messages written, bytes, lost), for a progress line."""
        with self._lock:
            records = [t.record for t in self._topics.values()]
        return RecordProgress(
            elapsed_s=time.monotonic() - self._started if self._started else 0.0,
            topics=len(records),
            messages=sum(r.messages for r in records),
            bytes=sum(r.bytes for r in records),
            lost=sum(r.lost for r in records),
        )

    # -- take thread ----------------------------------------------------------------------------

    def _take_loop(self) -> None:
        name_native_thread("bagkit-take")
        try:
            self._take_until_stopped()
        except Exception as exc:  # any failure must still finish the bag
            self._errors.append(f"recording stopped: {exc}")
            self._stopping.set()
        finally:
            self._queue.put_control("end")

    def _take_until_stopped(self) -> None:
        assert self._node is not None and self._wake is not None
        context_handle = self._node.context.handle
        wake = self._wake.handle
        queue = self._queue
        clock = self._clock
        by_pointer: dict[int, _Topic] = {}
        topics: list[_Topic] = []
        wait_set: Any = None
        generation = -1
        next_poll = time.monotonic() + self.discovery_period_s
        # Messages accumulate over a few rounds before they go to the writer: a hand-over
        # costs a lock, a notification and a thread switch, too much to pay per message when
        # a round finds one. With sim time, each round's messages carry the clock of that
        # moment, so each is handed over at once.
        batch: _Batch = []
        nbytes = count = 0
        batch_deadline = 0.0
        max_age = 0.0 if clock is not None else BATCH_AGE_S
        # With sim time a message's log time is the clock when it is taken: no pause.
        pause = PAUSE_S if clock is None else 0.0
        taken_last_round = 0
        full_last_round = False
        while not self._stopping.is_set():
            if generation != self._generation:
                generation = self._generation
                topics = list(self._topics.values())
                by_pointer = {t.subscription.handle.pointer: t for t in topics}
                handles = [t.subscription.handle for t in topics]
                if clock is not None:
                    handles.append(clock.handle)
                wait_set = _rclpy.WaitSet(len(handles), 1, 0, 0, 0, 0, context_handle)
            if taken_last_round:
                # Messages are flowing: take from every topic without a wait set (an empty
                # take costs 0.7 us, a wait 30 us), after a pause if the last round was small.
                if pause and not full_last_round and taken_last_round < PAUSE_BELOW:
                    time.sleep(pause)
                ready = topics
            else:
                wait_set.clear_entities()
                for handle in handles:
                    wait_set.add_subscription(handle)
                wait_set.add_guard_condition(wake)
                until = min(next_poll, batch_deadline) if batch else next_poll
                wait_set.wait(int(max(0.0, until - time.monotonic()) * 1e9))
                ready = [
                    by_pointer[pointer]
                    for pointer in wait_set.get_ready_entities("subscription")
                    if pointer in by_pointer
                ]
            if clock is not None:
                while (taken := clock.handle.take_message(clock.msg_type, True)) is not None:
                    self._sim_time = _clock_ns(taken[0])
            taken_last_round = 0
            full_last_round = False
            for topic in ready:
                # The rest of a topic's burst waits for the next round.
                taken = take_serialized(
                    topic.subscription, max_count=TAKE_BURST, max_bytes=TAKE_BURST_BYTES
                )
                if taken.payloads:
                    if not batch:
                        batch_deadline = time.monotonic() + max_age
                    batch.append((topic, taken))
                    nbytes += taken.nbytes
                    count += len(taken)
                    taken_last_round += len(taken)
                    full_last_round |= len(taken) == TAKE_BURST or taken.nbytes >= TAKE_BURST_BYTES
            now = time.monotonic()
            if batch and (
                now >= batch_deadline or nbytes >= TAKE_BURST_BYTES or count >= TAKE_BURST
            ):
                queue.put_batch(self._sim_time if clock is not None else None, batch, nbytes)
                batch = []
                nbytes = count = 0
            if now >= next_poll:
                self._discover()
                next_poll = time.monotonic() + self.discovery_period_s
        if batch:
            queue.put_batch(self._sim_time if clock is not None else None, batch, nbytes)
        self._drain_all()

    def _drain_all(self) -> None:
        """Take what the middleware already received when the stop came, so it is in the bag."""
        for topic in self._topics.values():
            self._drain(topic)

    def _drain(self, topic: _Topic) -> None:
        """Queue what waits in ``topic``'s subscription, for ``DRAIN_S`` at most.

        A publisher flooding the topic must not hold up a stop.
        """
        sim_time = self._sim_time if self._clock is not None else None
        deadline = time.monotonic() + DRAIN_S
        while time.monotonic() < deadline:
            taken = take_serialized(
                topic.subscription, max_count=TAKE_BURST, max_bytes=TAKE_BURST_BYTES
            )
            if not taken.payloads:
                return
            self._queue.put_batch(sim_time, [(topic, taken)], taken.nbytes)

    def _discover(self) -> None:
        """Subscribe to newly matching topics; re-subscribe where the offers got weaker."""
        assert self._node is not None
        for found in discover_topics(self._node, self.filter):
            known = self._topics.get(found.name)
            if known is None:
                self._subscribe(found)
            elif found.name not in self.qos_overrides:
                self._adapt(known, found)

    def _skip(self, topic: str, reason: str) -> None:
        if topic not in self._warned:
            self._warned.add(topic)
            self.report.skipped[topic] = reason
            message = f"not recording {topic}: {reason}"
            if self._on_warning is not None:
                self._on_warning(message)
            else:
                _log.warning("%s", message)

    def _subscribe(self, found: DiscoveredTopic) -> None:
        assert self._node is not None
        if len(set(found.types)) > 1:
            self._skip(found.name, f"published with several types: {', '.join(found.types)}")
            return
        type_name = found.types[0]
        try:
            message_type = import_message_type(type_name)
        except MessageClassNotFoundError:
            self._skip(found.name, f"message type {type_name} is not installed")
            return
        qos = self.qos_overrides.get(found.name) or adapt_subscription_qos(found.offered)
        info = TopicInfo(
            found.name,
            type_name,
            offered_qos_profiles=dump_offered_qos_profiles(found.offered),
            type_description_hash=found.type_hash,
        )
        subscription = self._node.create_subscription(
            message_type, found.name, _never_called, qos, raw=True
        )
        topic = _Topic(TopicRecord(found.name, type_name), subscription, message_type, qos)
        # The writer adds the topic to the bag before the first message taken from it.
        self._queue.put_control("topic", (topic, info))
        with self._lock:
            self._topics[found.name] = topic
            self._generation += 1

    def _adapt(self, topic: _Topic, found: DiscoveredTopic) -> None:
        """A new publisher with a weaker offer would not match: subscribe again, matching all."""
        assert self._node is not None
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
        replacement = self._node.create_subscription(
            topic.message_type, topic.record.topic, _never_called, wanted, raw=True
        )
        old = topic.subscription
        self._drain(topic)
        with self._lock:
            topic.subscription = replacement
            topic.qos = wanted
            self._generation += 1
        self._node.destroy_subscription(old)

    # -- writer thread --------------------------------------------------------------------------

    def _write_loop(self) -> None:
        name_native_thread("bagkit-write")
        bag = self._bag
        assert bag is not None
        try:
            failed = self._write_until_end(bag)
        except Exception as exc:  # a bug must not leave the bag unfinished
            self._errors.append(f"recording stopped: {exc!r}")
            self._stopping.set()
            failed = True
        self._finish(bag, failed)
        self._stopped.set()

    def _write_until_end(self, bag: BagWriter) -> bool:
        """Write queued messages until the take thread ends; return whether writing failed."""
        failed = False
        last_flush = time.monotonic()
        while True:
            item = self._queue.get(FLUSH_PERIOD_S / 2)
            now = time.monotonic()
            if item is None or now - last_flush >= FLUSH_PERIOD_S:
                # Idle or slow topics: close the open chunk so a crash loses at most a second.
                if not failed:
                    try:
                        bag.flush()
                    except BagWriteError as exc:
                        failed = self._write_failed(exc)
                last_flush = now
                if item is None:
                    continue
            kind, payload = item
            if kind == "end":
                break
            if kind == "topic":
                topic, info = payload
                try:
                    bag.add_topic(info)
                except BagError as exc:
                    failed = failed or self._write_failed(exc)
                continue
            if kind == "dropped":
                for topic, taken in payload:
                    self._account(topic, taken)
                    topic.record.overflow += len(taken)
                continue
            sim_time, batch = payload
            for topic, taken in batch:
                if failed:
                    self._account(topic, taken)
                    topic.record.write_failed += len(taken)
                else:
                    failed = self._write_messages(bag, topic, taken, sim_time)
        return failed

    def _write_messages(
        self, bag: BagWriter, topic: _Topic, taken: TakenMessages, sim_time: int | None
    ) -> bool:
        """Write one topic's messages of a batch; return whether writing failed.

        After a failure the counts are those of the batch; :meth:`_finish` recounts from the bag.
        """
        record = topic.record
        self._account(topic, taken)
        log_times = taken.received if sim_time is None else [sim_time] * len(taken)
        failed = False
        try:
            bag.write_batch(
                record.topic,
                taken.payloads,
                log_times=log_times,
                publish_times=taken.sources,
                sequences=taken.sequences,
            )
        except BagError as exc:
            failed = self._write_failed(exc)
        if not record.first_ns:
            record.first_ns = log_times[0]
        record.last_ns = log_times[-1]
        record.messages += len(taken)
        record.bytes += taken.nbytes
        return failed

    def _account(self, topic: _Topic, taken: TakenMessages) -> None:
        """Count the sequence gaps up to the messages just taken."""
        topic.record.gaps += topic.tracker.observe_many(
            taken.sequences, topic.subscription.handle.get_publisher_count
        )
        topic.record.publishers = topic.tracker.publishers

    def _write_failed(self, exc: BagError) -> bool:
        self._errors.append(str(exc))
        self._stopping.set()
        if self._wake is not None:
            self._wake.trigger()
        return True

    def _finish(self, bag: BagWriter, failed: bool) -> None:
        report = self.report
        with self._lock:
            records = [t.record for t in self._topics.values()]
        bag.custom_data[CUSTOM_DATA_PREFIX + "lost"] = str(sum(r.lost for r in records))
        bag.custom_data[CUSTOM_DATA_PREFIX + "loss"] = _loss_summary(records)
        try:
            bag.close()
        except BagError as exc:
            failed = True
            self._errors.append(str(exc))
        if failed:
            self._recount_from_bag(records)
        report.duration_s = time.monotonic() - self._started
        report.topics = sorted(records, key=lambda r: r.topic)
        report.error = self._errors[0] if self._errors else None

    def _recount_from_bag(self, records: list[TopicRecord]) -> None:
        """After a write failure, count what really is in the bag (chunks may have been lost)."""
        with contextlib.suppress(BagError, OSError), BagReader(self.path) as reader:
            counts = {name: 0 for name in reader.topics}
            for message in reader.messages():
                counts[message.topic] += 1
            for record in records:
                in_bag = counts.get(record.topic, 0)
                record.write_failed += max(0, record.messages - in_bag)
                record.messages = min(record.messages, in_bag)


def _never_called(_message: object) -> None:
    """Subscriptions are drained from the wait set, never through an executor callback."""


def _loss_summary(records: list[TopicRecord]) -> str:
    """JSON ``{topic: {messages, gaps, overflow, write_failed, publishers}}`` (custom_data is
    string -> string)."""
    return json.dumps(
        {
            r.topic: {
                "messages": r.messages,
                "gaps": r.gaps,
                "overflow": r.overflow,
                "write_failed": r.write_failed,
                "publishers": r.publishers,
            }
            for r in sorted(records, key=lambda r: r.topic)
        },
        sort_keys=True,
    )
