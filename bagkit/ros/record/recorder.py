"""Record ROS 2 topics into a rosbag2-compatible MCAP bag, counting every lost message.

Two threads do the work: the take thread (:mod:`~bagkit.ros.record.take_loop`) owns the node,
subscribes (:mod:`~bagkit.ros.record.subscriptions`) and takes messages in bursts; the writer
thread (:mod:`~bagkit.ros.record.write_loop`) writes them and accounts for loss. They meet in a
queue bounded in bytes (:mod:`~bagkit.ros.record.handoff`). This module holds the life cycle:
the bag, the node, the threads, and the run that stops them.
"""

from __future__ import annotations

import contextlib
import errno
import logging
import threading
import time
from collections.abc import Callable
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
from bagkit.recording.options import RecordOptions, default_output_name
from bagkit.recording.report import RecordProgress, RecordReport, SnapshotRecord
from bagkit.ros.clock import CLOCK_TOPIC
from bagkit.ros.errors import RecorderOptionsError, RecordingFailedError
from bagkit.ros.qos import load_qos_overrides
from bagkit.ros.record.control_services import ControlServices, recorder_actions
from bagkit.ros.record.handoff import HandoffQueue, StopSignal
from bagkit.ros.record.latched_topics import LatchedRepeats
from bagkit.ros.record.pause import PauseGate
from bagkit.ros.record.snapshot import SnapshotSink
from bagkit.ros.record.subscriptions import Subscriptions, never_called
from bagkit.ros.record.take_loop import SimClock, TakeLoop
from bagkit.ros.record.triggers import TriggerError, check_triggers_in_graph
from bagkit.ros.record.write_loop import FLUSH_PERIOD_S, WriteLoop
from bagkit.ros.tuning import process_tuning
from bagkit.selection.topics import absolute_topic_name

# A recording that cannot be written for these reasons is a failed run (exit 1), not a bad option.
_DISK_FULL = {errno.ENOSPC, errno.EDQUOT, errno.EFBIG}
# How often run() looks at its stop conditions before the topics are subscribed (the duration
# counts from there), and at most between two looks afterwards.
_POLL_STARTING_S = 0.05
_POLL_S = 0.5
# How long the start waits for the trigger topics to check their conditions' fields, and how
# long after the start a trigger topic may be absent before a warning says so.
TRIGGER_CHECK_WAIT_S = 1.0
TRIGGER_TOPIC_WAIT_S = 10.0
# What run() may be told to stop by: an event to set, or a function that says when.
StopWhen = threading.Event | Callable[[], bool]


class Recorder:
    """Record topics into a bag, as :class:`~bagkit.recording.options.RecordOptions` say.

    Construction only checks the options; :meth:`run` (or ``start``, then ``stop``; or ``with``)
    does the work: creates the bag and the node, tunes the process as ``bagkit record`` does
    (unless ``options.tune_process`` is False), records, finishes the bag.

    Example::

        stop = threading.Event()  # set it from anywhere to stop
        report = Recorder(RecordOptions(Path("run1"), all_topics=True, duration_s=10)).run(stop)
        print(report.messages, report.lost)

    Args:
        options: what to record, where, how.
        context: an initialized rclpy context to use; default: a private one.
        on_warning: called (from the recording threads) with each warning, such as a topic
            skipped because its message package is not installed; default: logging.

    Raises:
        RecorderOptionsError: the output exists.
    """

    def __init__(
        self,
        options: RecordOptions,
        *,
        context: Context | None = None,
        on_warning: Callable[[str], None] | None = None,
    ) -> None:
        self.options = options
        self.path = options.output or Path(default_output_name())
        if self.path.exists():
            raise RecorderOptionsError(
                f"{self.path} already exists (bagkit never overwrites a bag)"
            )
        self.selection = options.selection
        self.report = RecordReport(self.path)
        self._context = context
        self._on_warning = on_warning
        self._queue = HandoffQueue(options.queue_bytes)
        self._stop = StopSignal()
        self._stopped = threading.Event()
        self._own_context: Context | None = None
        self._node: Node | None = None
        self._subscriptions: Subscriptions | None = None
        self._writer: WriteLoop | None = None
        self._threads: list[threading.Thread] = []
        self._started = 0.0
        self._services: ControlServices | None = None
        self._absent_triggers: threading.Timer | None = None
        self._gate = PauseGate(paused=options.start_paused)
        # Latched state repeated at the start of each split file (snapshots keep their own).
        self._latched = (
            LatchedRepeats(options)
            if LatchedRepeats.wanted(options) and not options.snapshot_mode
            else None
        )

    def run(
        self,
        stop: StopWhen | None = None,
        *,
        on_progress: Callable[[RecordProgress], None] | None = None,
        progress_period_s: float = _POLL_S,
    ) -> RecordReport:
        """Record until ``stop``, ``options.duration_s``, ``options.max_messages`` or a failure.

        The bag is finished in every case, Ctrl-C (KeyboardInterrupt) included.

        Args:
            stop: an event that stops the recording when set, or a function returning True
                when it should stop; None: only the options' limits or a failure stop it.
            on_progress: called right after the recording started, then about every
                ``progress_period_s`` seconds, with the counts so far.
            progress_period_s: seconds between two ``on_progress`` calls.

        Returns:
            The report; its ``error`` says why a recording ended early (a full disk).

        Raises:
            RecorderOptionsError: the output cannot be created, or a bag option is invalid.
            RecordingFailedError: the bag cannot be written (a full disk); nothing is left.
        """
        self.start()
        try:
            self._wait(_should_stop(stop), on_progress, progress_period_s)
        finally:
            report = self.stop()
        return report

    def _wait(
        self,
        should_stop: Callable[[float], bool],
        on_progress: Callable[[RecordProgress], None] | None,
        progress_period_s: float,
    ) -> None:
        """Return when told to stop, at a limit of the options, or when the bag is finished."""
        options = self.options
        next_progress = 0.0
        while not self._stopped.is_set():
            now = time.monotonic()
            if on_progress is not None and now >= next_progress:
                on_progress(self.progress())
                next_progress = now + progress_period_s
            subscribed = self.subscribed.is_set()
            wait = min(_POLL_S, progress_period_s) if subscribed else _POLL_STARTING_S
            if options.duration_s is not None and subscribed:
                assert self._subscriptions is not None
                remaining = self._subscriptions.complete_at + options.duration_s - now
                if remaining <= 0:
                    return
                wait = min(wait, remaining)
            if options.max_messages is not None:
                if self.progress().messages >= options.max_messages:
                    return
                wait = _POLL_STARTING_S
            if should_stop(wait):
                return

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
        overrides = self._qos_overrides()
        bag = self._create_bag()
        try:
            # Fast DDS reads its profile when the participant is created.
            with process_tuning(self.options.tune_process):
                take_loop = self._start_node(overrides)
        except BaseException:
            bag.close()
            self._shutdown_node()
            raise
        assert self._subscriptions is not None
        self._writer = WriteLoop(
            bag,
            self._queue,
            self._stop,
            self._subscriptions.skip,
            latched=self._latched,
            gate=self._gate,
        )
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
        if self.options.snapshot_mode:
            self._start_snapshots()
        assert self._node is not None
        self._services = ControlServices(
            self._node.context, self.options.node_name, recorder_actions(self)
        )

    def _start_snapshots(self) -> None:
        """Check the triggers on the topics found; warn later about absent ones.

        Raises:
            RecorderOptionsError: a trigger names a field its topic's type lacks (the
                recording is stopped and nothing is left).
        """
        assert self._writer is not None and self._subscriptions is not None and self._node
        sink = self._writer.bag
        assert isinstance(sink, SnapshotSink)
        try:
            check_triggers_in_graph(self._node, sink.triggers, TRIGGER_CHECK_WAIT_S)
        except TriggerError as exc:
            self.stop()
            with contextlib.suppress(OSError):  # no snapshot was written: nothing to keep
                self.path.rmdir()
            raise RecorderOptionsError(str(exc)) from None
        self._absent_triggers = threading.Timer(TRIGGER_TOPIC_WAIT_S, self._warn_absent_triggers)
        self._absent_triggers.daemon = True
        self._absent_triggers.start()

    def _warn_absent_triggers(self) -> None:
        sink = self._writer.bag if self._writer is not None else None
        if isinstance(sink, SnapshotSink) and not self._stop.is_set():
            for topic in sink.triggers.unseen():
                self._warn(
                    f"trigger topic {topic} has not appeared after "
                    f"{TRIGGER_TOPIC_WAIT_S:g} s: recording goes on, it triggers once "
                    "it appears"
                )

    def _warn(self, message: str) -> None:
        if self._on_warning is not None:
            self._on_warning(message)
        else:
            logging.getLogger(__name__).warning(message)

    def _qos_overrides(self) -> dict[str, QoSProfile]:
        """The overrides file's profiles by absolute topic name.

        Raises:
            QosProfileError: the file cannot be read.
        """
        path = self.options.qos_overrides
        if path is None:
            return {}
        return {absolute_topic_name(k): v for k, v in load_qos_overrides(path).items()}

    def _create_bag(self) -> BagWriter | SnapshotSink:
        if self.options.snapshot_mode:
            return self._create_snapshot_sink()
        try:
            bag = BagWriter(
                self.path,
                compression=self.options.compression,
                max_bag_size=self.options.max_bag_size,
                max_bag_duration_s=self.options.max_bag_duration_s,
                chunk_interval_s=FLUSH_PERIOD_S,
                file_preamble=self._latched.state.messages if self._latched else None,
                rotation=self.options.rotation,
            ).open()
            bag.custom_data.update(self.options.custom_data)
            return bag
        except BagWriteError as exc:
            cause = exc.__cause__
            if isinstance(cause, OSError) and cause.errno in _DISK_FULL:
                _remove_empty_bag(self.path)
                raise RecordingFailedError(str(exc)) from None
            raise RecorderOptionsError(str(exc)) from None
        except BagError as exc:
            raise RecorderOptionsError(str(exc)) from None

    def _create_snapshot_sink(self) -> SnapshotSink:
        try:
            return SnapshotSink(self.path, self.options, self._stop.fail).open()
        except FileExistsError:
            raise RecorderOptionsError(
                f"{self.path} already exists (bagkit never overwrites a bag)"
            ) from None
        except OSError as exc:
            raise RecorderOptionsError(
                f"cannot create {self.path}: {exc.strerror or exc}"
            ) from None

    @property
    def is_paused(self) -> bool:
        """Whether the recording is paused (messages are taken, counted, not written)."""
        return self._gate.paused

    def pause(self) -> bool:
        """Pause (``~/pause``, the space key); return whether it was recording."""
        return self._gate.set_paused(True)

    def resume(self) -> bool:
        """Resume (``~/resume``); the last latched messages taken meanwhile are written.

        Returns whether it was paused.
        """
        changed = self._gate.set_paused(False)
        self._queue.put_control("wake")  # the writer writes the held latched messages now
        return changed

    def toggle_paused(self) -> None:
        """Pause if recording, resume if paused (the space key)."""
        if not self.pause():
            self.resume()

    def split(self) -> str:
        """Start a new file before the next message (``~/split_bagfile``); return a description.

        Raises:
            RecorderOptionsError: in snapshot mode (each snapshot is a bag of its own).
        """
        bag = self._writer.bag if self._writer is not None else None
        if not isinstance(bag, BagWriter):
            raise RecorderOptionsError("split: no bag file to split (snapshot mode or not started)")
        bag.request_split()
        return f"{self.path}: a new file starts with the next message"

    def snapshot(self, reason: str = "request") -> SnapshotRecord:
        """Trigger a snapshot now, as the ``~/snapshot`` service does (snapshot mode only).

        Returns:
            The snapshot this opened, or the open one it extended (its window grows).

        Raises:
            RecorderOptionsError: not in snapshot mode, or not started.
        """
        sink = self._writer.bag if self._writer is not None else None
        if not isinstance(sink, SnapshotSink):
            raise RecorderOptionsError("snapshots need snapshot mode (--snapshot-mode), started")
        return sink.request(reason)

    def _start_node(self, qos_overrides: dict[str, QoSProfile]) -> TakeLoop:
        context = self._context
        if context is None:
            context = Context()
            # No signal handlers: the caller decides what Ctrl-C means (stop and finish the bag).
            rclpy.init(context=context, signal_handler_options=SignalHandlerOptions.NO)
            self._own_context = context
        node = self._node = Node(
            self.options.node_name,
            context=context,
            start_parameter_services=False,
            enable_rosout=False,
        )
        wake = GuardCondition(None, None, context=context)
        self._stop.wake = wake.trigger
        self._subscriptions = Subscriptions(
            node,
            self.selection,
            qos_overrides=qos_overrides,
            queue=self._queue,
            skipped=self.report.skipped,
            on_warning=self._on_warning,
            include_unpublished=self.options.include_unpublished,
        )
        clock = None
        if self.options.use_sim_time:
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
            discovery_period_s=self.options.discovery_period_s,
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
        if isinstance(self._writer.bag, SnapshotSink):
            report.snapshots = self._writer.bag.snapshots
            report.evicted = self._writer.bag.evicted
        errors = self._stop.errors
        report.error = errors[0] if errors else None
        report.error_exit_code = self._stop.exit_code
        if report.error is not None and report.lost:
            report.error += f" ({report.lost} messages lost)"
        self._stopped.set()

    def _shutdown_node(self) -> None:
        if self._absent_triggers is not None:
            self._absent_triggers.cancel()
        if self._services is not None:
            self._services.close()
            self._services = None
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
            paused=sum(r.paused for r in records),
            is_paused=self._gate.paused,
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


def _never() -> bool:
    return False


def _should_stop(stop: StopWhen | None) -> Callable[[float], bool]:
    """``stop`` as ``wait(seconds)``: wait up to that long, return whether to stop."""
    if isinstance(stop, threading.Event):
        return stop.wait
    condition = stop if stop is not None else _never

    def wait(seconds: float) -> bool:
        if condition():
            return True
        time.sleep(seconds)
        return condition()

    return wait
