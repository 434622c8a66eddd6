"""What a replay publishes through, made when the player opens: its node, one output per
replayed topic (QoS from the overrides, else from the bag and the replay's rate), /clock,
and the sender of recorded service requests."""

from __future__ import annotations

import math
import os
import time
from collections.abc import Callable
from contextlib import ExitStack
from dataclasses import dataclass
from typing import TYPE_CHECKING

import rclpy
from rclpy.context import Context
from rclpy.node import Node
from rclpy.signals import SignalHandlerOptions

from bagkit.bag import TopicInfo
from bagkit.bag.latched import latched_topics
from bagkit.bag.storage_files import bag_path
from bagkit.playback.options import PlayOptions
from bagkit.playback.source import PlaySource
from bagkit.ros.fastdds import fast_dds, segment_size_for
from bagkit.ros.participants import countable, heard_the_answers
from bagkit.ros.qos import load_qos_overrides, replay_publisher_qos
from bagkit.ros.replay.publishers import TopicOutput, create_clock_output, create_output
from bagkit.ros.replay.topics import PublishableTopics, publishable_topics
from bagkit.ros.tuning import process_tuning
from bagkit.selection.services import is_service_event_topic
from bagkit.selection.times import NS_PER_S

# A participant that lost the answers to its first announcement is replaced at most this many
# times (each new one has the same chance again): beyond, the wait runs to the discovery time.
FRESH_PARTICIPANTS = 4

if TYPE_CHECKING:
    from bagkit.ros.replay.service_requests import ServiceRequests
    from bagkit.selection.topics import TopicSelection


@dataclass
class ReplayEndpoints:
    """The player's side of the graph.

    Attributes:
        node: the player's node.
        node_created: when it was created (``time.monotonic``): discovery settles from there.
        participants_replaced: participants made before the node's, which lost discovery
            answers (:func:`_create_node`).
        outputs: bag topic -> its output (a service-event topic's sends its requests).
        clock: the /clock output (``clock_hz``), or None.
        publishable: the bag's topics that are replayed, and the selected ones that cannot be.
        latched: topics whose state a late start publishes first.
        service_requests: the sender of recorded requests (``service_requests``), or None.
    """

    node: Node
    node_created: float
    participants_replaced: int
    outputs: dict[str, TopicOutput]
    clock: TopicOutput | None
    publishable: PublishableTopics
    latched: set[str]
    service_requests: ServiceRequests | None


def open_endpoints(
    options: PlayOptions,
    selection: TopicSelection,
    reader: PlaySource,
    stack: ExitStack,
    *,
    context: Context | None,
    on_warning: Callable[[str], None],
) -> ReplayEndpoints:
    """The node first (discovery, which the first message waits for, runs while the topics
    are checked against the installed types and the publishers are made), then an output per
    selected topic; what is made is closed by ``stack``.

    Raises:
        PlayerError: as :func:`~bagkit.ros.replay.topics.publishable_topics`.
    """
    overrides = load_qos_overrides(options.qos_overrides) if options.qos_overrides else {}
    # Fast DDS reads its profile when the participant is created; the player sends, so its
    # shared-memory segment is sized for the largest messages of the selected topics
    # (issue 27, item 5).
    largest = reader.largest_message(name for name in reader.topics if selection.matches(name))
    with process_tuning(options.tune_process, segment_size=segment_size_for(largest)):
        node, replaced = _create_node(options, stack, context)
        node_created = time.monotonic()
    publishable = _publishable(options, selection, reader)
    selected = publishable.selected
    latched = latched_topics(reader.topics, options.latched, [info.name for info, _ in selected])
    mean_size = reader.uncompressed_size // max(reader.message_count, 1) or 1024
    bag_duration_s = (reader.end_ns - reader.start_ns) / 1e9
    outputs: dict[str, TopicOutput] = {}
    requests: ServiceRequests | None = None
    for info, message_class in selected:
        name = options.remap.get(info.name, info.name)
        count = reader.topic_counts.get(info.name, 0)
        qos = overrides.get(name) or overrides.get(info.name)
        if qos is None:
            qos = replay_publisher_qos(
                info,
                count=count,
                mean_size=mean_size,
                messages_per_s=_replay_rate_hz(count, bag_duration_s, options.rate),
            )
        outputs[info.name] = create_output(node, info, message_class, name, qos)
        if options.service_requests is not None and sends_requests(info):
            if requests is None:
                requests = _service_requests(options, node, reader, stack, on_warning)
            outputs[info.name] = requests.output(info, outputs[info.name])
    clock = create_clock_output(node) if options.clock_hz is not None else None
    return ReplayEndpoints(
        node, node_created, replaced, outputs, clock, publishable, latched, requests
    )


def sends_requests(info: TopicInfo) -> bool:
    """Whether ``info`` is a service-event topic (``service_requests`` sends its
    requests instead of publishing it)."""
    return is_service_event_topic(info.name, [info.type])


def _create_node(
    options: PlayOptions, stack: ExitStack, context: Context | None
) -> tuple[Node, int]:
    """The player's node, and how many new participants lost the others' answers before it.

    In a context of its own, a player on Fast DDS that waits for its subscribers replaces a
    participant that did not hear every participant on this host answer
    (:func:`heard_the_answers`), at most ``FRESH_PARTICIPANTS`` times: it would otherwise find
    them up to 3 s later.
    """
    if context is not None:
        return _node(options, context, stack), 0
    replace = options.waits.any_before_start and countable(os.environ) and fast_dds(os.environ)
    replaced = 0
    while True:
        attempt = stack.enter_context(ExitStack())  # closed early when replaced
        context = Context()
        # No signal handlers: Ctrl-C must reach play() as KeyboardInterrupt so that it can
        # stop between two messages and still report.
        # args=[]: not sys.argv, whose --remap is bagkit's (applied to the publishers'
        # names), not a ROS remap rule for rcl to parse and warn about.
        rclpy.init(args=[], context=context, signal_handler_options=SignalHandlerOptions.NO)
        attempt.callback(context.try_shutdown)
        node = _node(options, context, attempt)
        if not replace or replaced == FRESH_PARTICIPANTS or heard_the_answers(node):
            return node, replaced
        attempt.close()  # its port is free again: the census counts the next one's
        replaced += 1


def _node(options: PlayOptions, context: Context, stack: ExitStack) -> Node:
    node = Node(
        options.node_name,
        context=context,
        start_parameter_services=options.services,
        enable_rosout=False,
    )
    stack.callback(node.destroy_node)
    return node


def _publishable(
    options: PlayOptions, selection: TopicSelection, reader: PlaySource
) -> PublishableTopics:
    from bagkit.migrate import load_rules

    return publishable_topics(
        reader.topics,
        selection,
        clock_published=options.clock_hz is not None,
        bag_path=bag_path(reader.name),
        definition=reader.definition,
        on_drift=options.on_drift,
        rules=load_rules(options.drift_rules) if options.drift_rules else None,
    )


def _service_requests(
    options: PlayOptions,
    node: Node,
    reader: PlaySource,
    stack: ExitStack,
    on_warning: Callable[[str], None],
) -> ServiceRequests:
    """The sender of recorded service requests (``options.service_requests``)."""
    from bagkit.ros.replay.service_requests import ServiceRequests

    replay = options.service_requests
    assert replay is not None
    return stack.enter_context(
        ServiceRequests(
            node,
            reader,
            source=replay.source,
            timeout_s=replay.timeout_ns / NS_PER_S,
            on_warning=on_warning,
        )
    )


def _replay_rate_hz(count: int, bag_duration_s: float, rate: float) -> float:
    """Messages per second of wall time of a topic with ``count`` messages, at ``rate``."""
    if bag_duration_s <= 0:
        return math.inf
    return count / bag_duration_s * rate
