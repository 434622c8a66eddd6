"""The one rclpy shell every node uses: parameters, QoS, subscriptions, timer, publishers."""

from __future__ import annotations

import functools
import sys
from collections.abc import Sequence
from typing import Any

import rclpy
from rcl_interfaces.msg import ParameterDescriptor
from rclpy.executors import ExternalShutdownException
from rclpy.impl.implementation_singleton import rclpy_implementation as _rclpy
from rclpy.node import Node
from rclpy.qos import DurabilityPolicy, HistoryPolicy, QoSProfile, ReliabilityPolicy
from rclpy.service_introspection import ServiceIntrospectionState

from bagkit.errors import BagkitError
from fusion import topics
from fusion.params import default_parameters
from fusion.processors import ProcessorBase, Severity, create_processor, parameter_descriptions

# Streams: reliable with a deep queue, so that a recorder or a replay at several times real time
# loses nothing to a momentarily slow subscriber (10 s of IMU at 10 Hz).
STREAM_QOS = QoSProfile(
    history=HistoryPolicy.KEEP_LAST,
    depth=100,
    reliability=ReliabilityPolicy.RELIABLE,
    durability=DurabilityPolicy.VOLATILE,
)
# State: the last message is the current state; transient local hands it to late subscribers.
STATE_QOS = QoSProfile(
    history=HistoryPolicy.KEEP_LAST,
    depth=1,
    reliability=ReliabilityPolicy.RELIABLE,
    durability=DurabilityPolicy.TRANSIENT_LOCAL,
)

# Service introspection events: a call's REQUEST_RECEIVED and RESPONSE_SENT are published
# back to back; with keep-last 1 (rclpy's examples pass the system default) the first is
# overwritten before delivery in most calls. 100 holds every event of a burst of calls.
EVENT_QOS = QoSProfile(
    history=HistoryPolicy.KEEP_LAST,
    depth=100,
    reliability=ReliabilityPolicy.RELIABLE,
    durability=DurabilityPolicy.VOLATILE,
)
_INTROSPECTION = {
    "metadata": ServiceIntrospectionState.METADATA,
    "contents": ServiceIntrospectionState.CONTENTS,
}


def topic_qos(topic: str) -> QoSProfile:
    """The QoS profile of ``topic`` for both publishers and subscribers."""
    return STATE_QOS if topic in topics.STATE_TOPICS else STREAM_QOS


def _parameter_value(value: Any) -> object:
    # rclpy hands arrays back as array.array; the cores expect plain lists.
    if isinstance(value, Sequence) and not isinstance(value, str):
        return list(value)
    if hasattr(value, "tolist"):
        return value.tolist()
    return value


class ProcessorNode(Node):
    """A node that declares its processor's parameters and wires it to topics and a timer."""

    def __init__(self, node_name: str) -> None:
        super().__init__(node_name)
        descriptions = parameter_descriptions(node_name)
        for name, default in default_parameters(node_name).items():
            self.declare_parameter(
                name,
                default,
                ParameterDescriptor(
                    description=descriptions[name],
                    # Read once at start-up: refuse changes that would silently do nothing.
                    read_only=True,
                    # Let 1 stand for 1.0 in user parameter files.
                    dynamic_typing=True,
                ),
            )
        params = {
            name: _parameter_value(self.get_parameter(name).value)
            for name in default_parameters(node_name)
        }
        self.processor: ProcessorBase = create_processor(node_name, params)
        self._publishers_by_topic = {
            topic: self.create_publisher(topics.TOPIC_TYPES[topic], topic, topic_qos(topic))
            for topic in self.processor.output_topics
        }
        for topic in self.processor.input_topics:
            self.create_subscription(
                topics.TOPIC_TYPES[topic],
                topic,
                functools.partial(self._on_message, topic),
                topic_qos(topic),
            )
        for service, service_type in self.processor.services.items():
            self._offer(service, service_type)
        period_ns = self.processor.timer_period_ns
        if period_ns is not None:
            # The node clock: follows /clock under use_sim_time.
            self.create_timer(period_ns / 1e9, self._on_timer)

    def _offer(self, name: str, service_type: type) -> None:
        """Serve ``name`` from the processor's ``on_request``; introspection as the processor's
        ``service_introspection`` parameter says, with a deep event queue (EVENT_QOS)."""

        def answer(request: Any, _response: Any) -> Any:
            response = self.processor.on_request(name, request, self._now_ns())
            self._publish([])  # log what the handler queued
            return response

        service = self.create_service(service_type, name, answer)
        state = getattr(self.processor, "service_introspection", "off")
        if state != "off":
            service.configure_introspection(self.get_clock(), EVENT_QOS, _INTROSPECTION[state])

    def _now_ns(self) -> int:
        return self.get_clock().now().nanoseconds

    def _on_message(self, topic: str, msg: Any) -> None:
        self._publish(self.processor.on_message(topic, msg, self._now_ns()))

    def _on_timer(self) -> None:
        self._publish(self.processor.on_timer(self._now_ns()))

    def _publish(self, outputs: list[tuple[str, Any]]) -> None:
        for topic, msg in outputs:
            self._publishers_by_topic[topic].publish(msg)
        logger = self.get_logger()
        for line in self.processor.drain_log():
            if line.severity >= Severity.ERROR:
                logger.error(line.text)
            elif line.severity >= Severity.WARN:
                logger.warning(line.text)
            elif line.severity >= Severity.INFO:
                logger.info(line.text)
            else:
                logger.debug(line.text)


def run_node(node_name: str, args: list[str] | None = None) -> int:
    """Run ``node_name`` until SIGINT/SIGTERM; returns the process exit code.

    ``args`` are ROS arguments (``--ros-args --params-file FILE -p use_sim_time:=true``);
    None takes them from ``sys.argv``.
    """
    try:
        rclpy.init(args=sys.argv if args is None else [node_name, *args])
    except _rclpy.RCLError as exc:
        # rcl's message ends with source locations after the first line: keep the useful part.
        reason = str(exc).split(", at /")[0].strip()
        print(f"error: {node_name}: cannot start: {reason}", file=sys.stderr)
        return 2
    node = None
    try:
        try:
            node = ProcessorNode(node_name)
            rclpy.spin(node)
        except (KeyboardInterrupt, ExternalShutdownException):
            pass
        except _rclpy.RCLError:
            # SIGINT shuts the context down from rclpy's signal handler; a callback publishing
            # at that moment fails with "context is invalid". That is the shutdown, not an error.
            if rclpy.ok():
                raise
        finally:
            if node is not None:
                node.destroy_node()
            rclpy.try_shutdown()
    except KeyboardInterrupt:
        # rclpy's handler also raises KeyboardInterrupt in the main thread, which can land
        # during the clean-up above.
        pass
    except BagkitError as exc:
        message = str(exc)
        if not message.startswith(f"{node_name}:"):
            message = f"{node_name}: {message}"
        print(f"error: {message}", file=sys.stderr)
        return exc.exit_code
    return 0
