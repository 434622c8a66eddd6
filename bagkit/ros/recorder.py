"""Record ROS 2 topics into a rosbag2-compatible MCAP bag, counting every lost message.

Two threads do the work: the take thread (:mod:`bagkit.ros.take_loop`) owns the node,
subscribes (:mod:`bagkit.ros.subscriptions`) and takes messages in bursts; the writer thread
(:mod:`bagkit.ros.write_loop`) writes them and accounts for loss. They meet in a queue bounded
in bytes (:mod:`bagkit.ros.handoff`). This module holds the life cycle: options, the bag, the
node, the threads.
"""

from __future__ import annotations

import contextlib
import errno
import threading
import time
from collections.abc import Callable, Mapping
from datetime import datetime
from pathlib import Path
from types import TracebackType

import rclpy
from rclpy.context import Context
from rclpy.guard_condition import GuardCondition
from rclpy.node import Node
from rclpy.qos import QoSProfile, ReliabilityPolicy
from rclpy.signals import SignalHandlerOptions

from bagkit.bag import BagWriteError, BagWriter
from bagkit.bag.errors import BagError
from bagkit.ros.clock import CLOCK_TOPIC
from bagkit.ros.errors import RecorderOptionsError, RecordingFailedError
from bagkit.ros.handoff import HandoffQueue, StopSignal
from bagkit.ros.record_report import RecordProgress, RecordReport
from bagkit.ros.subscriptions import Subscriptions, never_called
from bagkit.ros.take_loop import SimClock, TakeLoop
from bagkit.ros.write_loop import FLUSH_PERIOD_S, WriteLoop
from bagkit.selection.topics import TopicSelection

DISCOVERY_PERIOD_S = 0.1
# Bounds the memory held between taking and writing: absorbs writer hiccups (a slow disk
# write, a chunk to compress); beyond that the middleware holds the messages (see handoff).
DEFAULT_QUEUE_BYTES = 64 << 20
# A bag that cannot be written for these reasons is a failed run (exit 1), not a bad option.
_DISK_FULL = {errno.ENOSPC, errno.EDQUOT, errno.EFBIG}


def default_output_name(now: datetime | None = None) -> str:
    """``rosbag2_YYYY_MM_DD-HH_MM_SS`` in local time, as ``ros2 bag record`` names its bags."""
    return (now or datetime.now()).strftime("rosbag2_%Y_%m_%d-%H_%M_%S")


class Recorder:
    """Record topics into a bag; a context manager (``start`` on enter, ``stop`` on exit).

    Construction only checks the options; ``start`` creates the bag and the node.

    Example::

        with Recorder("run1", all_topics=True) as recorder:
            time.sleep(10)
        print(recorder.report.messages, recorder.report.lost)

    Args:
        output: the bag directory to create (it must not exist).
        topics: topic names to record (hidden or not).
        all_topics: record every topic (hidden ones only with ``include_hidden``).
        regex: also record topics whose name contains a match of this regular expression.
        exclude: do not record topics matching this (named ones included).
        include_hidden: let ``all_topics``/``regex`` select hidden topics.
        topic_types: also record topics of these types (``pkg/msg/Name``).
        exclude_topics: do not record these topics (named ones included).
        exclude_topic_types: do not record topics of these types.
        include_unpublished: also subscribe to selected topics that have no publisher.
        custom_data: key -> value pairs for metadata.yaml's ``custom_data``.
        compression: ``zstd`` (default), ``lz4`` or ``none``.
        max_bag_size: split into a new file at this many bytes (0: never).
        max_bag_duration_s: split when a file spans this many seconds (0: never).
        qos_overrides: topic -> subscription profile, instead of the adapted one.
        use_sim_time: ``log_time`` is the latest ``/clock`` time when the message was taken,
            as ``ros2 bag record --use-sim-time``; messages taken before the first ``/clock``
            are not written (counted in ``TopicRecord.before_clock``).
        context: an initialized rclpy context to use; default: a private one.
        node_name: the recorder node's name.
        queue_bytes: bound of the queue between taking and writing.
        discovery_period_s: how often the graph is polled for new topics and publishers.
        on_warning: called (from the recording threads) with each warning, such as a topic
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
        topic_types: tuple[str, ...] | list[str] = (),
        exclude_topics: tuple[str, ...] | list[str] = (),
        exclude_topic_types: tuple[str, ...] | list[str] = (),
        include_unpublished: bool = False,
        custom_data: Mapping[str, str] | None = None,
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
        self.selection = TopicSelection.create(
            topics,
            all_topics=all_topics,
            regex=regex,
            exclude=exclude,
            include_hidden=include_hidden,
            topic_types=topic_types,
            exclude_topics=exclude_topics,
            exclude_topic_types=exclude_topic_types,
        )
        _check_options(self.path, self.selection, max_bag_size, max_bag_duration_s)
        self.compression = compression
        self.max_bag_size = max_bag_size
        self.max_bag_duration_s = max_bag_duration_s
        self.qos_overrides = dict(qos_overrides or {})
        self.use_sim_time = use_sim_time
        self.include_unpublished = include_unpublished
        self.custom_data = dict(custom_data or {})
        self.discovery_period_s = discovery_period_s
        self.report = RecordReport(self.path)
        self._context = context
        self._node_name = node_name
        self._queue = HandoffQueue(queue_bytes)
        self._stop = StopSignal()
        self._stopped = threading.Event()
        self._own_context: Context | None = None
        self._node: Node | None = None
        self._subscriptions: Subscriptions | None = None
        self._writer: WriteLoop | None = None
        self._threads: list[threading.Thread] = []
        self._started = 0.0
        self._on_warning = on_warning

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

    @property
    def subscribed(self) -> threading.Event:
        """Set once every named topic (none named: the first topic) is subscribed or skipped.

        A recording's duration counts from here; ``report.discovery_s`` is the wait.
        """
        assert self._subscriptions is not None, "start() first"
        return self._subscriptions.complete

    def start(self) -> None:
        """Create the bag and the node, subscribe to the topics found, and start recording.

        A failure of the first discovery stops the recording like any later one: the bag is
        finished and ``report.error`` says why.

        Raises:
            RecorderOptionsError: the output exists or cannot be created, or a bag option is
                invalid.
            RecordingFailedError: the bag cannot be written (a full disk); nothing is left.
        """
        bag = self._create_bag()
        try:
            take_loop = self._start_node()
        except BaseException:
            bag.close()
            self._shutdown_node()
            raise
        assert self._subscriptions is not None
        self._writer = WriteLoop(bag, self._queue, self._stop, self._subscriptions.skip)
        self._started = time.monotonic()
        discovered = threading.Event()
        self._threads = [
            threading.Thread(
                target=take_loop.run, args=(discovered,), name="bagkit-record-take", daemon=True
            ),
            threading.Thread(target=self._write, name="bagkit-record-write", daemon=True),
        ]
        for thread in self._threads:
            thread.start()
        discovered.wait()

    def _create_bag(self) -> BagWriter:
        try:
            bag = BagWriter(
                self.path,
                compression=self.compression,
                max_bag_size=self.max_bag_size,
                max_bag_duration_s=self.max_bag_duration_s,
                chunk_interval_s=FLUSH_PERIOD_S,
            ).open()
            bag.custom_data.update(self.custom_data)
            return bag
        except BagWriteError as exc:
            cause = exc.__cause__
            if isinstance(cause, OSError) and cause.errno in _DISK_FULL:
                _remove_empty_bag(self.path)
                raise RecordingFailedError(str(exc)) from None
            raise RecorderOptionsError(str(exc)) from None
        except BagError as exc:
            raise RecorderOptionsError(str(exc)) from None

    def _start_node(self) -> TakeLoop:
        context = self._context
        if context is None:
            context = Context()
            # No signal handlers: the caller decides what Ctrl-C means (stop and finish the bag).
            rclpy.init(context=context, signal_handler_options=SignalHandlerOptions.NO)
            self._own_context = context
        node = self._node = Node(
            self._node_name,
            context=context,
            start_parameter_services=False,
            enable_rosout=False,
        )
        wake = GuardCondition(None, None, context=context)
        self._stop.wake = wake.trigger
        self._subscriptions = Subscriptions(
            node,
            self.selection,
            qos_overrides=self.qos_overrides,
            queue=self._queue,
            skipped=self.report.skipped,
            on_warning=self._on_warning,
            include_unpublished=self.include_unpublished,
        )
        clock = None
        if self.use_sim_time:
            from rosgraph_msgs.msg import Clock

            best_effort = QoSProfile(depth=10, reliability=ReliabilityPolicy.BEST_EFFORT)
            clock = SimClock(
                node.create_subscription(Clock, CLOCK_TOPIC, never_called, best_effort, raw=True)
            )
        return TakeLoop(
            self._subscriptions,
            self._queue,
            self._stop,
            wake=wake.handle,
            clock=clock,
            discovery_period_s=self.discovery_period_s,
        )

    def _write(self) -> None:
        assert self._writer is not None
        self._writer.run()
        report = self.report
        report.duration_s = time.monotonic() - self._started
        assert self._subscriptions is not None
        if self._subscriptions.complete.is_set():
            report.discovery_s = self._subscriptions.complete_at - self._started
        report.topics = sorted(self._writer.records.values(), key=lambda r: r.topic)
        errors = self._stop.errors
        report.error = errors[0] if errors else None
        if report.error is not None and report.lost:
            report.error += f" ({report.lost} messages lost)"
        self._stopped.set()

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
        self._stop.set()
        for thread in self._threads:
            thread.join()
        self._threads = []
        self._shutdown_node()
        self._stopped.set()
        return self.report

    def progress(self) -> RecordProgress:
        """Counts so far (messages written, bytes, lost), for a progress line."""
        records = [t.record for t in self._subscriptions.snapshot()] if self._subscriptions else []
        return RecordProgress(
            elapsed_s=time.monotonic() - self._started if self._started else 0.0,
            topics=len(records),
            messages=sum(r.messages for r in records),
            bytes=sum(r.bytes for r in records),
            lost=sum(r.lost for r in records),
            before_clock=sum(r.before_clock for r in records),
        )


def _remove_empty_bag(path: Path) -> None:
    """Remove what a bag that could not even start left behind: empty files, the directory."""
    if not path.is_dir():
        return
    for child in path.iterdir():
        if child.is_file() and child.stat().st_size == 0:
            child.unlink()
    with contextlib.suppress(OSError):  # something else is in there: not ours to remove
        path.rmdir()


def _check_options(
    path: Path, selection: TopicSelection, max_bag_size: int, max_bag_duration_s: float
) -> None:
    """Raise RecorderOptionsError before anything starts: nothing selected, an existing bag,
    negative split limits."""
    if selection.empty:
        raise RecorderOptionsError(
            "nothing to record: name topics, or use --all, --regex or --topic-types"
        )
    if path.exists():
        raise RecorderOptionsError(f"{path} already exists (bagkit never overwrites a bag)")
    if max_bag_size < 0 or max_bag_duration_s < 0:
        raise RecorderOptionsError("--max-bag-size and --max-bag-duration must be >= 0")
