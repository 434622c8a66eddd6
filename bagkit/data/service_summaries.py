"""Services in a bag counted and timed from their events' fixed header, for ``bagkit info``.

Counts and latency need only each event's ``info`` (kind, stamp, client gid, sequence number):
the first field of every ``pkg/srv/Name_Event``, of one fixed layout. It is read here with
``struct``, so that ``bagkit info`` of a bag with services starts without the decoder and numpy
(benchmarks/README.md, issue 36). A topic whose definition does not start with that field, or
one of whose events does not fit it, is read by the decoder (:mod:`bagkit.data.services`).
"""

from __future__ import annotations

import struct
from collections.abc import Iterator
from dataclasses import asdict, dataclass
from pathlib import Path
from typing import TYPE_CHECKING, Any

from bagkit.bag import BagReader
from bagkit.bag.service_calls import (
    LatencySummary,
    ServiceCounts,
    ServiceEvent,
    count_events,
    event_from_message,
    latency_summary,
    pair_calls,
)
from bagkit.data.errors import UndecodableTopicError
from bagkit.selection.services import is_service_event_topic, service_name, service_type
from bagkit.selection.topics import absolute_topic_name

if TYPE_CHECKING:
    from bagkit.decode import MessageTypes

# The event type's first field, as rosbag2 and bagkit write its definition.
_INFO_FIELD = "service_msgs/ServiceEventInfo info"
# CDR after the 4-byte encapsulation: uint8 event_type, int32 sec, uint32 nanosec (aligned to
# 4), char[16] client_gid, int64 sequence_number (aligned to 8).
_INFO = {0: struct.Struct(">B3xiI16s4xq"), 1: struct.Struct("<B3xiI16s4xq")}
_ENCAPSULATION = 4
_EVENT_KINDS = 4


@dataclass(frozen=True, slots=True)
class ServiceSummary:
    """A service of a bag: its type, event topic, counts (as ``ros2 bag info -v``), latency."""

    service: str
    type: str
    topic: str
    counts: ServiceCounts
    latency: LatencySummary

    def to_dict(self) -> dict[str, Any]:
        """The JSON form (``bagkit info --format json``'s ``services``)."""
        return asdict(self)


def service_topics(reader: BagReader) -> dict[str, str]:
    """Service name -> its event topic, for every service-event topic of an open bag."""
    return {
        service_name(absolute_topic_name(name)): name
        for name, info in sorted(reader.topics.items())
        if is_service_event_topic(absolute_topic_name(name), [info.type])
    }


def find_service(reader: BagReader, name: str) -> str | None:
    """The event topic of service ``name`` (``/x`` or ``/x/_service_event``), None if absent."""
    wanted = absolute_topic_name(name)
    topics = service_topics(reader)
    if wanted in topics:
        return topics[wanted]
    return next((t for t in topics.values() if absolute_topic_name(t) == wanted), None)


def service_summaries(bag: str | Path) -> list[ServiceSummary]:
    """Every service of ``bag`` with its counts and latency; undecodable ones are left out."""
    summaries = []
    with BagReader(bag, allow_empty=True) as reader:
        for service, topic in service_topics(reader).items():
            events = _header_events(reader, topic)
            if events is None:
                events = _decoded_events(reader, topic)
            if events is None:
                continue
            summaries.append(
                ServiceSummary(
                    service=service,
                    type=service_type(reader.topics[topic].type),
                    topic=topic,
                    counts=count_events(events),
                    latency=latency_summary(pair_calls(events)),
                )
            )
    return summaries


def header_event(data: bytes, log_time_ns: int) -> ServiceEvent | None:
    """An event read from its ``info`` header alone (no request or response); None if ``data``
    does not hold one (too short, not plain CDR, an unknown kind, nanoseconds out of range)."""
    layout = _INFO.get(data[1]) if len(data) >= _ENCAPSULATION and data[0] == 0 else None
    if layout is None or len(data) < _ENCAPSULATION + layout.size:
        return None
    kind, sec, nanosec, gid, sequence = layout.unpack_from(data, _ENCAPSULATION)
    if kind >= _EVENT_KINDS or nanosec >= 1_000_000_000:
        return None
    return ServiceEvent(kind, sec * 1_000_000_000 + nanosec, log_time_ns, (gid, sequence))


def _header_events(reader: BagReader, topic: str) -> list[ServiceEvent] | None:
    """The events of ``topic`` from their headers; None when one of them has none."""
    stored = reader.topic_definitions.get(topic, reader.definitions.get(reader.topics[topic].type))
    if _first_field(stored or "") != _INFO_FIELD:
        return None
    events = []
    for message in reader.messages([topic]):
        event = header_event(message.data, message.log_time)
        if event is None:
            return None
        events.append(event)
    return events


def read_events(reader: BagReader, types: MessageTypes, topic: str) -> Iterator[ServiceEvent]:
    """The events of one service-event topic, decoded, in log-time order.

    Raises:
        UndecodableTopicError: the event type cannot be decoded from the bag's definition.
    """
    from bagkit.decode import DecodeError

    try:
        decode = types.for_topic(topic).decoder(reader.topics[topic].type)
    except DecodeError as exc:
        raise UndecodableTopicError(f"{topic} cannot be decoded: {exc}") from None
    for message in reader.messages([topic]):
        yield event_from_message(decode(message.data), message.log_time)


def _decoded_events(reader: BagReader, topic: str) -> list[ServiceEvent] | None:
    """The events of ``topic`` through the decoder; None when they do not decode."""
    from bagkit.decode import DecodeError, MessageTypes

    try:
        return list(read_events(reader, MessageTypes.for_bag(reader), topic))
    except (UndecodableTopicError, DecodeError):
        return None


def _first_field(definition: str) -> str:
    """The first field line of a message definition (comments, blanks and constants skipped)."""
    for line in definition.splitlines():
        text = line.split("#", 1)[0]
        if text.strip() and "=" not in text:
            return " ".join(text.split())
    return ""
