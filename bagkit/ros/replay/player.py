"""Live replay of a bag over ROS 2: original timing scaled by a rate, /clock, no lost first message.

``Player(options).run()`` does it all; as a context manager, constructing it only checks the
options; entering opens the bag and creates one publisher per replayed topic
(:mod:`~bagkit.ros.replay.endpoints`); ``play()`` waits for the subscribers the graph knows
about, then runs the passes (:mod:`~bagkit.playback.publish_loop`) and returns a
:class:`~bagkit.playback.report.PlayReport`.
"""

from __future__ import annotations

import dataclasses
import itertools
import logging
import time
from collections.abc import Callable
from contextlib import ExitStack, nullcontext
from pathlib import Path
from typing import TYPE_CHECKING

from rclpy.context import Context
from rclpy.node import Node

from bagkit.bag.storage_files import bag_path
from bagkit.native import precise_timers
from bagkit.playback.controls import PlayControls
from bagkit.playback.options import PlayOptions
from bagkit.playback.report import PlayProgress, PlayReport, SubscriberWait, TopicPlayback
from bagkit.playback.seeking import WindowSpan
from bagkit.playback.source import PlaySource
from bagkit.ros.errors import PlayerError
from bagkit.ros.replay.endpoints import open_endpoints, sends_requests
from bagkit.ros.replay.publishers import TopicOutput, other_publishers
from bagkit.ros.replay.seek_services import serve_seek
from bagkit.ros.replay.services import serve_controls
from bagkit.ros.replay.subscriber_waits import after_last_message, before_first_message
from bagkit.ros.replay.topics import PublishableTopics
from bagkit.selection.times import NS_PER_S, TimeLike, parse_time

if TYPE_CHECKING:
    # Imported once the node exists (numpy, the decoder, rosbags, the migrator; topics.py
    # imports the decoder when called): their import overlaps discovery instead of delaying
    # the participant that discovery waits for.
    from bagkit.playback.lateness import LatenessSamples
    from bagkit.playback.pass_reader import PassReader
    from bagkit.playback.publish_loop import PassPublisher
    from bagkit.ros.replay.service_requests import ServiceRequests

_log = logging.getLogger(__name__)


class Player:
    """Replays a bag through ROS 2 publishers with the recorded timing.

    Construction only checks the options; :meth:`run` (or ``with`` and :meth:`play`) opens the
    bag, creates one publisher per replayed topic, tunes the process as ``bagkit replay`` does
    (unless ``options.tune_process`` is False), replays, and closes.

    Args:
        options: what to replay and how.
        context: rclpy context to use; None = a private one, shut down on exit.
        on_progress: called with a ``PlayProgress`` about every ``options.progress_period_ns``.
        on_live_publishers: called once before the first message with the replayed topics
            that other nodes publish too (published name -> those nodes).
        on_warning: called with each warning (a seek clamped to the window); default: logging.
        on_waited: called once before the first message with what the player waited for.

    Example:
        >>> report = Player(PlayOptions(Path("drive"), rate=2.0, clock_hz=100.0)).run()
        >>> with Player(PlayOptions(Path("drive"), start_paused=True)) as player:
        ...     player.controls.resume()
        ...     report = player.play()
    """

    def __init__(
        self,
        options: PlayOptions,
        *,
        context: Context | None = None,
        on_progress: Callable[[PlayProgress], None] | None = None,
        on_live_publishers: Callable[[dict[str, list[str]]], None] | None = None,
        on_warning: Callable[[str], None] | None = None,
        on_waited: Callable[[SubscriberWait], None] | None = None,
    ) -> None:
        """Set up a replay; nothing is opened until the player is entered."""
        self.options = options
        self.bag_path = bag_path(options.bag)  # a UrlPath for a bag in storage
        self.controls = PlayControls(options.rate, paused=options.start_paused)
        self.selection = options.selection
        self.window = options.window
        self.waits = options.waits
        self.on_progress = on_progress
        self.on_live_publishers = on_live_publishers
        self.on_warning = on_warning or _log.warning
        self.on_waited = on_waited
        self.progress_period_ns = options.progress_period_ns
        self._context = context
        self._stack = ExitStack()
        self._reader: PlaySource | None = None
        self._latched: set[str] = set()  # topics whose state a late start publishes first
        self._latched_published = 0
        self._node: Node | None = None
        self._outputs: dict[str, TopicOutput] = {}
        self._clock: TopicOutput | None = None
        self._service_requests: ServiceRequests | None = None
        self._node_created = 0.0
        self._participants_replaced = 0
        self._pass: PassPublisher | None = None  # the pass being published
        self.live_publishers: dict[str, list[str]] = {}
        """Published topic -> other nodes publishing it, found when the replay starts."""
        self.publishable = PublishableTopics()
        """The bag's topics that are replayed, and the selected ones that cannot be."""

    def run(self) -> PlayReport:
        """Open, replay (``options.loops`` passes), close; Ctrl-C stops between two messages.

        Raises:
            PlayerError: nothing to replay, or the window is past the bag's end.
            SubscriberTimeoutError: known subscribers did not match within the wait timeout.
        """
        with self:
            return self.play()

    def __enter__(self) -> Player:
        try:
            self._open()
        except BaseException:
            self._stack.close()
            raise
        return self

    def __exit__(self, *exc_info: object) -> None:
        self._stack.close()

    @property
    def node(self) -> Node:
        """The player's rclpy node (exists while the player is entered)."""
        if self._node is None:
            raise PlayerError("the player is not open: use it as a context manager")
        return self._node

    def _open(self) -> None:
        options = self.options
        reader = PlaySource.open(options.bags, options.message_order, self._stack)
        self._reader = reader
        self.window.bounds(reader.start_ns, reader.end_ns, Path(reader.name))  # raises past end
        self.selection = options.selection_in(reader, reader.name)  # raises on unknown names
        self.controls.cue(self._span().start_ns)
        endpoints = open_endpoints(
            options,
            self.selection,
            reader,
            self._stack,
            context=self._context,
            on_warning=self.on_warning,
        )
        self._node = endpoints.node
        self._node_created = endpoints.node_created
        self._participants_replaced = endpoints.participants_replaced
        self._outputs = endpoints.outputs
        self._clock = endpoints.clock
        self._latched = endpoints.latched
        self._service_requests = endpoints.service_requests
        self.publishable = endpoints.publishable
        if options.services:
            self._stack.enter_context(serve_seek(endpoints.node, self))  # before the executor spins
            self._stack.enter_context(serve_controls(endpoints.node, self.controls))

    def play(self) -> PlayReport:
        """Replay the bag (``options.loops`` passes); Ctrl-C stops between two messages.

        The calling thread publishes: its timers are made precise for the replay
        (:func:`~bagkit.native.precise_timers`) unless ``options.tune_process`` is False.

        Returns:
            What was published, the timing error and what the reader could not read.

        Raises:
            SubscriberTimeoutError: known subscribers did not match within ``wait_timeout``.
        """
        if self._reader is None:
            raise PlayerError("the player is not open: use it as a context manager")
        with precise_timers() if self.options.tune_process else nullcontext():
            return self._play()

    def _play(self) -> PlayReport:
        from bagkit.playback.lateness import LatenessSamples

        assert self._reader is not None
        options = self.options
        for output in self._outputs.values():
            output.count = 0
        self._latched_published = 0
        self.controls.stopped = False
        lateness = LatenessSamples()
        bag_ns = 0
        passes = 0
        interrupted = False
        wall_start = time.monotonic_ns()
        held_at_start = self.controls.held_ns(wall_start)
        waited = None
        try:
            if self.waits.any_before_start:
                waited = self.wait_until_matched()
                if self.on_waited is not None:
                    self.on_waited(waited)
            published = [
                output
                for output in self._outputs.values()
                # Their events are not published: the requests are sent instead.
                if not (options.service_requests and sends_requests(output.info))
            ]
            self.live_publishers = other_publishers(self.node, published)
            if self.live_publishers and self.on_live_publishers is not None:
                self.on_live_publishers(self.live_publishers)
            wall_start = time.monotonic_ns()
            held_at_start = self.controls.held_ns(wall_start)
            while options.loops == 0 or passes < options.loops:
                if options.delay_ns > 0:
                    time.sleep(options.delay_ns / NS_PER_S)
                before = lateness.count
                bag_ns += self._play_pass(passes, lateness)
                self._pass = None
                self.controls.end_pass()
                passes += 1
                if lateness.count == before or self.controls.stopped:
                    break  # an empty window: looping would only spin
            wall_end = time.monotonic_ns()
            unacknowledged = self.wait_until_acknowledged()
            requests = self._service_requests
            service_requests = requests.finish() if requests is not None else None
        except KeyboardInterrupt:
            interrupted = True
            wall_end = time.monotonic_ns()
            unacknowledged = []
            if self._pass is not None:  # the interrupted pass counts for what it published
                bag_ns += self._pass.covered_ns
                self._pass = None
            requests = self._service_requests
            service_requests = requests.summary if requests is not None else None
        return PlayReport(
            topics=self._topic_playbacks(passes, complete=not interrupted),
            messages=sum(output.count for output in self._outputs.values()),
            loops=passes,
            bag_duration_s=bag_ns / 1e9,
            wall_duration_s=(wall_end - wall_start) / 1e9,
            paused_s=(self.controls.held_ns(wall_end) - held_at_start) / 1e9,
            rate=self.controls.rate,
            lateness=lateness.summary(),
            skipped_types=dict(self.publishable.skipped_types),
            drifted=dict(self.publishable.drifted),
            skipped_formats=dict(self.publishable.skipped_formats),
            problems=list(dict.fromkeys(self._reader.problems)),
            unacknowledged=unacknowledged,
            interrupted=interrupted,
            latched=self._latched_published,
            service_requests=service_requests,
            waited=waited,
        )

    def _topic_playbacks(self, passes: int, *, complete: bool) -> list[TopicPlayback]:
        """Per-topic counts; unreadable messages where the whole bag was to be replayed."""
        assert self._reader is not None
        reader = self._reader
        whole_bag = complete and self.window.whole
        playbacks = []
        for topic, out in self._outputs.items():
            unreadable = 0
            if whole_bag and reader.problems:
                unreadable = max(0, reader.topic_counts.get(topic, 0) * passes - out.count)
            playbacks.append(TopicPlayback(topic, out.name, out.info.type, out.count, unreadable))
        return playbacks

    def _play_pass(self, loop: int, lateness: LatenessSamples) -> int:
        """Publish one pass over the window; return the bag time it covered (ns)."""
        from bagkit.playback.publish_loop import PassPublisher

        reader = self._pass_reader()
        window_start = self._span().start_ns
        messages = reader.messages_from(window_start)
        # The first chunk is read before the clock starts, so the first message is on time.
        # Later chunks are read inline, right after a publication: a read-ahead thread was
        # measured to do worse, its GIL hand-offs delaying the publishing loop.
        first = next(messages, None)
        if first is None:
            return 0
        publisher = PassPublisher(
            self._outputs,
            self._clock,
            clock_hz=self.options.clock_hz,
            lateness=lateness,
            on_progress=self.on_progress,
            progress_period_ns=self.progress_period_ns,
            loop=loop,
            controls=self.controls,
            reader=reader,
        )
        self._pass = publisher
        try:
            return publisher.run(itertools.chain([first], messages), window_start)
        finally:
            self._latched_published += publisher.latched

    def _pass_reader(self) -> PassReader:
        from bagkit.playback.pass_reader import pass_reader

        assert self._reader is not None
        return pass_reader(
            self._reader,
            list(self._outputs),
            self._span(),
            latched=self._latched,
            migrations=self.publishable.migrations,
        )

    def _span(self) -> WindowSpan:
        if self._reader is None:
            raise PlayerError("the player is not open: use it as a context manager")
        return WindowSpan.of(self.window, self._reader)

    def seek(self, to: TimeLike) -> int:
        """Continue the replay from bag time ``to`` (rosbag2's ``~/seek``), clamped to the window.

        ``to`` is a time of bagkit's grammar (:func:`~bagkit.selection.times.parse_time`:
        seconds from the bag's start, negative from its end, epoch seconds, ISO 8601,
        ``NNNns``). The latched state there and ``/clock`` are published first; the timeline
        restarts there, so the jump is no lateness. Paused, it stays paused.

        Returns:
            The log time (ns) the replay goes on from.

        Raises:
            SelectionError: ``to`` is not a time.
        """
        span = self._span()
        assert self._reader is not None
        wanted = parse_time(to, "seek").resolve(self._reader.start_ns, self._reader.end_ns)
        return self._seek_ns(span, wanted)

    def seek_by(self, step_ns: int) -> int:
        """Seek ``step_ns`` of bag time forward (negative: back) from where the replay is."""
        return self._seek_ns(self._span(), self.controls.position() + step_ns)

    def _seek_ns(self, span: WindowSpan, wanted: int) -> int:
        target, warning = span.clamp(wanted)
        if warning is not None:
            self.on_warning(warning)
        self.controls.seek(target)
        return target

    def burst(self, count: int) -> int:
        """While paused, publish the next ``count`` messages at once (0: the rest of the pass).

        Returns:
            How many were published (0 unless paused), as rosbag2's ``~/burst``.
        """
        return self.controls.burst(count)

    def pause(self) -> bool:
        """Pause; False if already paused."""
        return self.controls.pause()

    def resume(self) -> bool:
        """Resume; False if not paused."""
        return self.controls.resume()

    def stop(self) -> None:
        """End the replay after the message being published; :meth:`play` returns its report."""
        self.controls.stop()

    def wait_until_acknowledged(self) -> list[str]:
        """Wait until the subscribers of reliable topics have every message; return the others.

        A fast replay ends while messages are in flight. Waits at most ``ack_timeout`` s in all.
        """
        return after_last_message(list(self._outputs.values()), self.waits)

    def wait_until_matched(self) -> SubscriberWait:
        """Block until the subscriptions the graph knows on replayed topics have matched, as
        ``options.waits`` asks (:func:`~bagkit.ros.replay.subscriber_waits.before_first_message`).

        Returns:
            How long it waited, and for what.

        Raises:
            SubscriberTimeoutError: not matched within ``wait_timeout`` seconds.
        """
        clock = [self._clock] if self._clock is not None else []
        waited = before_first_message(
            self.node, [*self._outputs.values(), *clock], self.waits, self._node_created
        )
        return dataclasses.replace(waited, participants_replaced=self._participants_replaced)
