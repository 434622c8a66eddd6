"""Service calls from a service's introspection events: requests paired with their responses.

Each call of a service with introspection on publishes up to four events on
``/name/_service_event``, two from the client (REQUEST_SENT, RESPONSE_RECEIVED) and two from the
server (REQUEST_RECEIVED, RESPONSE_SENT), all carrying the call's ``client_gid`` and
``sequence_number``. A call is those events grouped by that pair (and, because the gid a server
reports is its middleware's id of the client's request writer, not the client's own, a client's
half is joined with the server's half of the same sequence number received in between); its
latency is measured on
one side, the client's where both of its events are there (what a caller waits), else the
server's (what the handler took), from the events' own ``info.stamp``. Pure: works on decoded
messages of any decoder (rosbags-style objects or rclpy messages). No rclpy import.
"""

from __future__ import annotations

from collections.abc import Iterable
from dataclasses import dataclass, field
from typing import Any

REQUEST_SENT, REQUEST_RECEIVED, RESPONSE_SENT, RESPONSE_RECEIVED = 0, 1, 2, 3
EVENT_NAMES = ("REQUEST_SENT", "REQUEST_RECEIVED", "RESPONSE_SENT", "RESPONSE_RECEIVED")
_REQUESTS = (REQUEST_SENT, REQUEST_RECEIVED)
_RESPONSES = (RESPONSE_SENT, RESPONSE_RECEIVED)

CallId = tuple[bytes, int]
"""A call: its client's gid (16 octets) and the client's sequence number."""


@dataclass(frozen=True, slots=True)
class ServiceEvent:
    """One introspection event: its kind, its own stamp, when it was logged, and its payload.

    ``message`` is the request or response (None when introspection is METADATA only).
    """

    kind: int
    stamp_ns: int
    log_time_ns: int
    call: CallId
    message: Any = None


@dataclass(slots=True)
class ServiceCall:
    """A call: its events by kind, request and response where recorded."""

    call: CallId
    events: dict[int, ServiceEvent] = field(default_factory=dict)

    @property
    def request(self) -> Any:
        """The request (client's copy first), None if no event carries it."""
        return _first_message(self.events, _REQUESTS)

    @property
    def response(self) -> Any:
        """The response (server's copy first), None if no event carries it."""
        return _first_message(self.events, (RESPONSE_SENT, RESPONSE_RECEIVED))

    @property
    def request_ns(self) -> int | None:
        """When the request was sent (client), else received (server)."""
        event = self.events.get(REQUEST_SENT) or self.events.get(REQUEST_RECEIVED)
        return None if event is None else event.stamp_ns

    @property
    def log_time_ns(self) -> int:
        """The first log time of the call's events (where the call sits in the bag)."""
        return min(e.log_time_ns for e in self.events.values())

    @property
    def latency_ns(self) -> int | None:
        """Response minus request, on the client's side where it has both events, else the
        server's; None when neither side has both."""
        for start, end in ((REQUEST_SENT, RESPONSE_RECEIVED), (REQUEST_RECEIVED, RESPONSE_SENT)):
            if start in self.events and end in self.events:
                return self.events[end].stamp_ns - self.events[start].stamp_ns
        return None

    @property
    def latency_side(self) -> str | None:
        """``client`` or ``server``: whose events :attr:`latency_ns` comes from."""
        if REQUEST_SENT in self.events and RESPONSE_RECEIVED in self.events:
            return "client"
        if REQUEST_RECEIVED in self.events and RESPONSE_SENT in self.events:
            return "server"
        return None


def _first_message(events: dict[int, ServiceEvent], kinds: Iterable[int]) -> Any:
    for kind in kinds:
        event = events.get(kind)
        if event is not None and event.message is not None:
            return event.message
    return None


def event_from_message(message: Any, log_time_ns: int) -> ServiceEvent:
    """A decoded ``pkg/srv/Name_Event`` message as a :class:`ServiceEvent`."""
    info = message.info
    kind = int(info.event_type)
    payload = message.request if kind in _REQUESTS else message.response
    gid = bytes(int(octet) & 0xFF for octet in info.client_gid)
    return ServiceEvent(
        kind=kind,
        stamp_ns=int(info.stamp.sec) * 1_000_000_000 + int(info.stamp.nanosec),
        log_time_ns=log_time_ns,
        call=(gid, int(info.sequence_number)),
        message=payload[0] if len(payload) else None,
    )


def pair_calls(events: Iterable[ServiceEvent]) -> list[ServiceCall]:
    """Group events into calls, in the order of each call's first event in the bag.

    A repeated event of a kind (two clients cannot share a gid, so only a duplicate delivery)
    keeps the first.
    """
    calls: dict[CallId, ServiceCall] = {}
    for event in events:
        call = calls.get(event.call)
        if call is None:
            call = calls[event.call] = ServiceCall(event.call)
        call.events.setdefault(event.kind, event)
    return sorted(_join_halves(list(calls.values())), key=lambda c: c.log_time_ns)


def _join_halves(calls: list[ServiceCall]) -> list[ServiceCall]:
    """Join each server-only half to the client-only half of its call: same sequence number,
    received after the client sent it and (if the client got its answer) before that."""
    servers: dict[int, list[ServiceCall]] = {}
    for call in calls:
        if REQUEST_SENT not in call.events and RESPONSE_RECEIVED not in call.events:
            servers.setdefault(call.call[1], []).append(call)
    joined: set[int] = set()
    for call in calls:
        sent = call.events.get(REQUEST_SENT)
        if sent is None or REQUEST_RECEIVED in call.events or RESPONSE_SENT in call.events:
            continue
        received = call.events.get(RESPONSE_RECEIVED)
        end = received.stamp_ns if received is not None else None
        for half in servers.get(call.call[1], []):
            start = half.request_ns
            if id(half) in joined or start is None or start < sent.stamp_ns:
                continue
            if end is not None and start > end:
                continue
            call.events.update(half.events)
            joined.add(id(half))
            break
    return [call for call in calls if id(call) not in joined]


@dataclass(frozen=True, slots=True)
class ServiceCounts:
    """``ros2 bag info -v``'s counts of a service: events, distinct requests and responses."""

    events: int
    requests: int
    responses: int


def count_events(events: Iterable[ServiceEvent]) -> ServiceCounts:
    """Events, and requests and responses counted once per call whichever side logged them
    (the calls of :func:`pair_calls`)."""
    events = list(events)
    calls = pair_calls(events)
    return ServiceCounts(
        len(events),
        sum(1 for c in calls if not set(_REQUESTS).isdisjoint(c.events)),
        sum(1 for c in calls if not set(_RESPONSES).isdisjoint(c.events)),
    )


@dataclass(frozen=True, slots=True)
class LatencySummary:
    """Latency of a service's answered calls, in ns; None where no call has a latency."""

    count: int
    p50_ns: float | None
    p99_ns: float | None
    max_ns: int | None


def latency_summary(calls: Iterable[ServiceCall]) -> LatencySummary:
    """Count, median, 99th percentile (linear interpolation, as numpy's) and maximum."""
    values = sorted(c.latency_ns for c in calls if c.latency_ns is not None)
    if not values:
        return LatencySummary(0, None, None, None)
    return LatencySummary(len(values), _percentile(values, 50), _percentile(values, 99), values[-1])


def _percentile(ordered: list[int], percent: float) -> float:
    position = (len(ordered) - 1) * percent / 100
    low = int(position)
    high = min(low + 1, len(ordered) - 1)
    return ordered[low] + (ordered[high] - ordered[low]) * (position - low)
