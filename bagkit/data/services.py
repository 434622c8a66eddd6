"""Services in a bag: their event topics read, calls paired, counted and timed.

The reading side of :mod:`bagkit.bag.service_calls` (which is pure): ``bagkit info`` lists
:func:`service_summaries` (:mod:`bagkit.data.service_summaries`, which reads the events'
headers without the decoder), ``bagkit echo BAG /service`` prints :func:`echo_calls`.
"""

from __future__ import annotations

import dataclasses
from collections.abc import Iterator
from pathlib import Path
from typing import Any

import numpy as np

from bagkit.bag import BagReader
from bagkit.bag.service_calls import (
    EVENT_NAMES,
    ServiceCall,
    ServiceEvent,
    pair_calls,
)
from bagkit.data.call_selection import call_filter
from bagkit.data.echo import Plain
from bagkit.data.errors import UndecodableTopicError
from bagkit.data.service_summaries import find_service, read_events, service_topics
from bagkit.decode import DecodeError, MessageTypes
from bagkit.decode.msgdef import EMPTY_STRUCT_MEMBER
from bagkit.selection.query import Query
from bagkit.selection.services import service_name
from bagkit.selection.topics import absolute_topic_name


def call_latencies(bag: str | Path) -> dict[str, list[int]]:
    """Event topic -> the latency (ns) of each answered call of its service, in the bag's
    order; undecodable services are left out."""
    with BagReader(bag, allow_empty=True) as reader:
        return {
            topic: [c.latency_ns for c in pair_calls(events) if c.latency_ns is not None]
            for _, topic, events in _service_events(reader)
        }


def _service_events(reader: BagReader) -> Iterator[tuple[str, str, list[ServiceEvent]]]:
    """(service, event topic, its events) of every service of an open bag that decodes."""
    types = MessageTypes.for_bag(reader)
    for service, topic in service_topics(reader).items():
        try:
            events = list(read_events(reader, types, topic))
        except (UndecodableTopicError, DecodeError):
            continue
        yield service, topic, events


def read_calls(bag: str | Path, service: str) -> list[ServiceCall]:
    """The calls of one service of ``bag``, paired, in the bag's order.

    Raises:
        UndecodableTopicError: the bag has no such service, or its events do not decode.
    """
    return _service_calls(bag, service)[1]


def _service_calls(
    bag: str | Path, service: str, query: Query | None = None
) -> tuple[str, list[ServiceCall]]:
    """The event topic of ``service`` in ``bag`` and its calls, paired (those ``query``
    keeps)."""
    with BagReader(bag, allow_empty=True) as reader:
        topic = find_service(reader, service)
        if topic is None:
            raise UndecodableTopicError(f"no service {absolute_topic_name(service)} in {bag}")
        types = MessageTypes.for_bag(reader)
        keep = call_filter(reader, types.for_topic(topic), topic, query or Query())
        return topic, [c for c in pair_calls(read_events(reader, types, topic)) if keep(c)]


def echo_calls(
    bag: str | Path,
    service: str,
    *,
    limit: int | None = None,
    query: Query | None = None,
) -> Iterator[Plain]:
    """Each call of ``service`` as plain data: ids, events seen, request, response, latency.

    ``query``: only the calls in its window that satisfy its condition.

    Raises:
        UndecodableTopicError: the bag has no such service, or its events do not decode.
        UnknownFieldError, SelectionError: the condition does not fit the service's calls.
    """
    topic, calls = _service_calls(bag, service, query)
    for call in calls:
        latency = call.latency_ns
        yield {
            "topic": topic,
            "log_time": call.log_time_ns,
            "service": service_name(absolute_topic_name(topic)),
            "client_gid": call.call[0].hex(),
            "sequence_number": call.call[1],
            "events": [EVENT_NAMES[k] for k in sorted(call.events) if k < len(EVENT_NAMES)],
            "request": plain_message(call.request, limit),
            "response": plain_message(call.response, limit),
            "latency_s": None if latency is None else latency / 1e9,
            "latency_side": call.latency_side,
        }


def plain_message(message: Any, limit: int | None = None) -> Any:
    """A decoded message as nested dicts and lists (numbers as Python's); None stays None.

    ``limit``: sequences longer than this are cut as ``echo`` cuts them.
    """
    if message is None or isinstance(message, (bool, int, float, str)):
        return message
    if isinstance(message, np.ndarray):
        return plain_message(message.tolist(), limit)
    if isinstance(message, np.generic):
        return message.item()
    if isinstance(message, (list, tuple)):
        items = [plain_message(item, limit) for item in message]
        if limit is not None and len(items) > limit:
            return [*items[:limit], f"... ({len(items) - limit} more)"]
        return items
    if dataclasses.is_dataclass(message):
        return {
            f.name.rstrip("_"): plain_message(getattr(message, f.name), limit)
            for f in dataclasses.fields(message)
            if f.name != EMPTY_STRUCT_MEMBER[0]
        }
    return str(message)
