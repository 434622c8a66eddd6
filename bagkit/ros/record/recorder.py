"""Record ROS 2 topics into a rosbag2-compatible MCAP bag, counting every lost message.

Two threads do the work: the take thread (:mod:`~bagkit.ros.record.take_loop`) owns the node,
subscribes (:mod:`~bagkit.ros.record.subscriptions`) and takes messages in bursts; the writer
thread (:mod:`~bagkit.recording.write_loop`) writes them and accounts for loss. They meet in a
queue bounded in bytes (:mod:`~bagkit.recording.handoff`). This module holds the life cycle:
the output (created by :mod:`~bagkit.recording.output`), the node, the threads, the trigger
checks of snapshot mode (:mod:`~bagkit.ros.record.triggers`) and the run (stopped as
:mod:`~bagkit.recording.run_until` says).
"""

from __future__ import annotations

import contextlib
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
from rclpy.qos import QoSProfile
from rclpy.signals import SignalHandlerOptions

from bagkit.recording.controls import RecordingControls
from bagkit.recording.errors import TriggerError
from bagkit.recording.handoff import HandoffQueue, StopSignal
from bagkit.recording.health_watch import HealthWatch
from bagkit.recording.latched import LatchedRepeats
from bagkit.recording.options import RecordOptions, default_output_name
from bagkit.recording.output import create_output
from bagkit.recording.pause import PauseGate
from bagkit.recording.report import RecordProgress, RecordReport
from bagkit.recording.run_until import POLL_S, StopWhen, wait_until_done
from bagkit.recording.snapshot import SnapshotSink
from bagkit.recording.write_loop import WriteLoop
from bagkit.ros.errors import RecorderOptionsError, RecordingFailedError
from bagkit.ros.qos import load_qos_overrides
from bagkit.ros.record.control_services import ControlServices, recorder_actions
from bagkit.ros.record.subscriptions import Subscriptions
from bagkit.ros.record.take_loop import SimClock, TakeLoop
from bagkit.ros.record.triggers import DataTriggers, start_trigger_checks
from bagkit.ros.tuning import process_tuning
from bagkit.selection.times import NS_PER_S
from bagkit.selection.topics import absolute_topic_name, missing_on_graph
from bagkit.words import counted


class Recorder(RecordingControls):
    """Record topics into a bag, as :class:`~bagkit.recording.options.RecordOptions` say.

    Construction only checks the options; :meth:`run` (or ``start``, then ``stop``; or ``with``)
    does the work: creates the bag and the node, tunes the process as ``bagkit record`` does
    (unless ``options.tune_process`` is False), records, finishes the bag.

    Example::

        stop = threading.Event()  # set it from anywhere to stop
        options = RecordOptions(Path("run1"), all_topics=True, duration_ns=10 * NS_PER_S)
        report = Recorder(options).run(stop)
        print(report.messages, report.lost)

    Args:
        options: what to record, where, how.
        context: an initialized rclpy context to use; default: a private one.
        on_warning: called (from the recording threads) with each warning, such as a topic
            skipped because its message package is not installed; default: logging.
        health: a contract checked on what is written (``--health``):
            :class:`bagkit.health.live.LiveHealth`; its counts go to ``report.health``.

    Raises:
        RecorderOptionsError: the output exists, or the health check triggers snapshots
            outside snapshot mode (the error names ``health.trigger``).
    """

    def __init__(
        self,
        options: RecordOptions,
        *,
        context: Context | None = None,
        on_warning: Callable[[str], None] | None = None,
        health: HealthWatch | None = None,
    ) -> None:
        self.options = options
        if health is not None and health.trigger and not options.snapshot_mode:
            raise RecorderOptionsError("triggers snapshots outside snapshot mode", "health.trigger")
        self.health = health
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
        self._triggers = DataTriggers.of(options) if options.snapshot_mode else None
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
        progress_period_s: float = POLL_S,
    ) -> RecordReport:
        """Record until ``stop``, ``options.duration_ns``, ``options.max_messages`` or a failure.

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
            assert self._subscriptions is not None
            wait_until_done(
                self.options,
                self._subscriptions,
                self._stopped,
                self.progress,
                stop=stop,
                on_progress=on_progress,
                progress_period_s=progress_period_s,
            )
        finally:
            report = self.stop()
        return report

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
        bag = create_output(
            self.path,
            self.options,
            file_preamble=self._latched.state.messages if self._latched else None,
            triggers=self._triggers,
            on_snapshot_error=self._stop.fail,
        )
        try:
            # Fast DDS reads its profile when the participant is created.
            with process_tuning(self.options.tune_process):
                take_loop = self._start_node(overrides)
        except BaseException:
            bag.close()
            self._shutdown_node()
            raise
        assert self._subscriptions is not None
        health = self.health
        self._writer = WriteLoop(
            bag,
            self._queue,
            self._stop,
            self._subscriptions.skip,
            latched=self._latched,
            gate=self._gate,
            health=health,
            on_health_break=(
                bag.request if isinstance(bag, SnapshotSink) and health and health.trigger else None
            ),
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
        assert self._node is not None and self._triggers is not None
        try:
            self._absent_triggers = start_trigger_checks(
                self._node, self._triggers, stopping=self._stop.is_set, warn=self._warn
            )
        except TriggerError as exc:
            self.stop()
            with contextlib.suppress(OSError):  # no snapshot was written: nothing to keep
                self.path.rmdir()
            raise RecorderOptionsError(str(exc)) from None

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
        clock = SimClock.subscribe(node) if self.options.use_sim_time else None
        return TakeLoop(
            self._subscriptions,
            self._queue,
            self._stop,
            wake=wake.handle,
            clock=clock,
            discovery_period_s=self.options.discovery_period_ns / NS_PER_S,
        )

    def _write(self) -> None:
        assert self._writer is not None
        self._writer.run()
        report = self.report
        report.duration_s = time.monotonic() - self._started
        assert self._subscriptions is not None
        if self._subscriptions.complete.is_set():
            report.discovery_s = self._subscriptions.complete_at - self._started
        missing = self._subscriptions.never_appeared()
        report.topics = sorted(self._writer.records.values(), key=lambda r: r.topic)
        if self.health is not None:
            report.health = self.health.counts
        if isinstance(self._writer.bag, SnapshotSink):
            report.snapshots = self._writer.bag.snapshots
            report.evicted = self._writer.bag.evicted
        errors = self._stop.errors
        report.error = errors[0] if errors else None
        report.error_exit_code = self._stop.exit_code
        if missing and self._node is not None:
            graph = (name for name, _ in self._node.get_topic_names_and_types())
            report.never_appeared = missing_on_graph(missing, graph)
        if report.error is not None and report.lost:
            report.error += f" ({counted(report.lost, 'message')} lost)"
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
        written = [r for r in records if r.messages]
        return RecordProgress(
            elapsed_s=time.monotonic() - self._started if self._started else 0.0,
            topics=len(records),
            messages=sum(r.messages for r in records),
            bytes=sum(r.bytes for r in records),
            lost=sum(r.lost for r in records),
            before_clock=sum(r.before_clock for r in records),
            paused=sum(r.paused for r in records),
            is_paused=self._gate.paused,
            span_ns=(
                max(r.last_ns for r in written) - min(r.first_ns for r in written) if written else 0
            ),
        )
