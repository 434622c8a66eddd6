"""``replay --publish-service-requests``: call the real services with the recorded requests.

For each replayed service-event topic the player publishes nothing; at the time of each request
event of the chosen source (``service_introspection``: the server's REQUEST_RECEIVED, as
rosbag2's default; ``client_introspection``: the client's REQUEST_SENT) the recorded request is
sent to the live service. Unlike rosbag2, the answers are kept and compared with the responses
recorded for the same calls (:mod:`bagkit.playback.service_responses`). The clients live on a
node of their own, spun by a thread of their own, so that the publishing loop never waits.
"""

from __future__ import annotations

import contextlib
import functools
import threading
import time
from collections.abc import Callable
from dataclasses import dataclass
from types import TracebackType
from typing import Any

import numpy as np
from rclpy.client import Client
from rclpy.executors import ExternalShutdownException, SingleThreadedExecutor
from rclpy.node import Node
from rclpy.serialization import deserialize_message
from rclpy.task import Future

from bagkit.bag import TopicInfo
from bagkit.bag.service_calls import (
    REQUEST_RECEIVED,
    REQUEST_SENT,
    ServiceCall,
    event_from_message,
    pair_calls,
)
from bagkit.playback.errors import PlayerError
from bagkit.playback.service_responses import (
    ServiceReplaySummary,
    Tolerance,
    compare_response,
)
from bagkit.playback.source import PlaySource
from bagkit.ros.errors import MessageClassNotFoundError
from bagkit.ros.message_classes import import_message_type
from bagkit.ros.replay.publishers import TopicOutput
from bagkit.selection.services import service_name, service_type

SOURCES = {"service_introspection": REQUEST_RECEIVED, "client_introspection": REQUEST_SENT}
_POLL_S = 0.01


@dataclass(slots=True)
class _Service:
    name: str
    client: Client
    event_class: Any
    calls: dict[tuple[bytes, int], ServiceCall]
    """Call id of each of its events -> the call (its recorded response)."""


@dataclass(slots=True)
class _Pending:
    service: str
    sequence_number: int
    log_time_ns: int
    recorded: Any
    future: Future


class ServiceRequests:
    """Send recorded requests at their time; collect and compare the live responses.

    Args:
        node: the player's node (its context is used for the clients' node).
        reader: the open bags (every recorded call is found across them).
        source: ``service_introspection`` or ``client_introspection``.
        timeout_s: how long after the last request the answers are waited for.
        tolerance: how far live numbers may be from the recorded ones.
        on_warning: called with each warning (a METADATA-only service, once).
    """

    def __init__(
        self,
        node: Node,
        reader: PlaySource,
        *,
        source: str,
        timeout_s: float,
        tolerance: Tolerance = Tolerance(),
        on_warning: Callable[[str], None] | None = None,
    ) -> None:
        if source not in SOURCES:
            raise PlayerError(f"service requests source {source!r}: use {' or '.join(SOURCES)}")
        self.kind = SOURCES[source]
        self.timeout_s = timeout_s
        self.tolerance = tolerance
        self.summary = ServiceReplaySummary()
        self._reader = reader
        self._warn = on_warning or (lambda _message: None)
        self._node = Node(f"{node.get_name()}_service_client", context=node.context)
        self._executor = SingleThreadedExecutor(context=node.context)
        self._executor.add_node(self._node)
        self._thread = threading.Thread(target=self._spin, daemon=True, name="service clients")
        self._services: dict[str, _Service] = {}
        self._pending: list[_Pending] = []
        self._warned: set[str] = set()

    def __enter__(self) -> ServiceRequests:
        self._thread.start()
        return self

    def __exit__(
        self, kind: type[BaseException] | None, exc: BaseException | None, tb: TracebackType | None
    ) -> None:
        self._executor.shutdown(timeout_sec=1.0)
        self._thread.join(timeout=2.0)
        self._node.destroy_node()

    def _spin(self) -> None:
        # Shutting the player's context down ends the spin.
        with contextlib.suppress(ExternalShutdownException):
            self._executor.spin()

    def output(self, info: TopicInfo, publisher_output: TopicOutput) -> TopicOutput:
        """``publisher_output`` with its publish replaced by sending the event's request.

        Raises:
            PlayerError: the service type is not installed.
        """
        name = service_name(info.name)
        srv_type = service_type(info.type)
        try:
            srv_class = import_message_type(srv_type)
        except MessageClassNotFoundError:
            raise PlayerError(
                f"cannot call {name}: service type {srv_type} is not installed"
            ) from None
        calls = self._recorded_calls(info.name, srv_class.Event)
        client = self._node.create_client(srv_class, name)
        # A request sent before the server is discovered is lost: wait for it (a service that
        # is not there costs the timeout once, and its requests count unanswered).
        if not client.wait_for_service(timeout_sec=self.timeout_s):
            self._warn(f"{name} is not available: its requests will go unanswered")
        self._services[info.name] = _Service(name, client, srv_class.Event, calls)
        publisher_output.publish = functools.partial(self._on_event, info.name)
        return publisher_output

    def _recorded_calls(self, topic: str, event_class: Any) -> dict[tuple[bytes, int], ServiceCall]:
        events = [
            event_from_message(deserialize_message(bytes(m.data), event_class), m.log_time)
            for m in self._reader.messages([topic], None, None)
        ]
        return {e.call: call for call in pair_calls(events) for e in call.events.values()}

    def _on_event(self, topic: str, data: bytes) -> None:
        service = self._services[topic]
        event = deserialize_message(bytes(data), service.event_class)
        if int(event.info.event_type) != self.kind:
            return
        gid = bytes(int(v) & 0xFF for v in np.asarray(event.info.client_gid).tolist())
        sequence = int(event.info.sequence_number)
        if not len(event.request):
            counts = self.summary.empty_requests
            counts[service.name] = counts.get(service.name, 0) + 1
            if service.name not in self._warned:
                self._warned.add(service.name)
                self._warn(
                    f"{service.name}: recorded request events carry no request (introspection "
                    "was METADATA, not CONTENTS): nothing to send"
                )
            return
        call = service.calls.get((gid, sequence))
        recorded = call.response if call is not None else None
        self.summary.sent[service.name] = self.summary.sent.get(service.name, 0) + 1
        future = service.client.call_async(event.request[0])
        log_time = call.log_time_ns if call is not None else 0
        self._pending.append(_Pending(service.name, sequence, log_time, recorded, future))

    def finish(self) -> ServiceReplaySummary:
        """Wait up to ``timeout_s`` for the answers, then compare; unanswered ones count so."""
        deadline = time.monotonic() + self.timeout_s
        while time.monotonic() < deadline and not all(p.future.done() for p in self._pending):
            time.sleep(_POLL_S)
        for pending in self._pending:
            live = pending.future.result() if pending.future.done() else None
            if not pending.future.done():
                pending.future.cancel()
            self.summary.add(
                compare_response(
                    pending.service,
                    pending.sequence_number,
                    pending.log_time_ns,
                    recorded=ros_plain(pending.recorded),
                    live=ros_plain(live),
                    tolerance=self.tolerance,
                )
            )
        self._pending = []
        return self.summary


def ros_plain(message: Any) -> Any:
    """An rclpy message as nested dicts and lists of Python values; None stays None."""
    if message is None:
        return None
    if hasattr(message, "get_fields_and_field_types"):
        return {
            name: ros_plain(getattr(message, name)) for name in message.get_fields_and_field_types()
        }
    if isinstance(message, np.ndarray):
        return [ros_plain(v) for v in message.tolist()]
    if isinstance(message, (list, tuple)) or type(message).__name__ == "array":
        return [ros_plain(v) for v in message]
    if isinstance(message, np.generic):
        return message.item()
    if isinstance(message, bytes):
        return list(message)
    return message
