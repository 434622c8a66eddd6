"""Services in lockstep: the golden's recorded requests answered by the processors.

A spec that names ``services`` has their event topics among its outputs. Lockstep reads the
golden's events of each in log-time order; at a call's first request event it hands the request
to the processor that offers the service (``services`` maps names to types, ``on_request(service,
request, now_ns)`` answers); every event is written to the candidate as recorded, with the
response of its response events replaced by the processor's answer. The candidate's event topic
then compares with the golden's like any output, under the spec's tolerances, in the same
report (the ``info`` fields, ids and stamps, are left out of the comparison: see
:func:`service_ignore_fields`).
"""

from __future__ import annotations

from collections.abc import Callable, Iterable, Sequence
from dataclasses import dataclass, field
from typing import Any

from bagkit.bag import BagMessage, BagReader
from bagkit.bag.service_calls import (
    REQUEST_RECEIVED,
    REQUEST_SENT,
    ServiceCall,
    event_from_message,
    pair_calls,
)
from bagkit.regression.errors import RegressionError
from bagkit.regression.processor import Processor
from bagkit.selection.services import event_topic, service_name

_REQUESTS = (REQUEST_SENT, REQUEST_RECEIVED)


def service_ignore_fields(services: Iterable[str]) -> list[str]:
    """The fields of the services' event topics left out of a comparison: their ``info``
    (gids, sequence numbers and stamps, which a new run cannot reproduce)."""
    return [f"{event_topic(s)}:info.*" for s in services]


@dataclass(slots=True)
class _Service:
    name: str
    processor: Processor
    decode: Callable[[bytes], Any]
    calls: dict[tuple[bytes, int], ServiceCall]
    answers: dict[int, Any] = field(default_factory=dict)


class LockstepServices:
    """The services of a lockstep run: the golden's events, answered by the processors.

    Raises:
        RegressionError: a service's events are not in the golden, no processor offers it, or
            its type is not installed.
    """

    def __init__(
        self, reader: BagReader, processors: Sequence[Processor], services: Sequence[str]
    ) -> None:
        from bagkit.ros.errors import MessageClassNotFoundError
        from bagkit.ros.serialization import deserializer

        self._services: dict[str, _Service] = {}
        for name in services:
            topic = event_topic(name)
            if topic not in reader.topics:
                raise RegressionError(f"{reader.path}: no events of service {name} ({topic})")
            offering = [p for p in processors if name in getattr(p, "services", {})]
            if not offering:
                raise RegressionError(f"no processor offers service {name} (its services)")
            try:
                decode = deserializer(reader.topics[topic].type)
            except MessageClassNotFoundError as exc:
                raise RegressionError(f"{reader.path}: {exc}") from exc
            events = [
                event_from_message(decode(m.data), m.log_time) for m in reader.messages([topic])
            ]
            calls = {e.call: c for c in pair_calls(events) for e in c.events.values()}
            self._services[topic] = _Service(name, offering[0], decode, calls)

    @property
    def topics(self) -> set[str]:
        """The event topics fed through :meth:`feed`."""
        return set(self._services)

    def feed(self, message: BagMessage, write: Callable[[str, Any, int], None]) -> None:
        """Answer ``message``'s request (a call's first request event) or replace its response
        with the answer; ``write(topic, event, now_ns)`` the event."""
        service = self._services[message.topic]
        event = service.decode(message.data)
        info = event.info
        gid = bytes(int(v) & 0xFF for v in info.client_gid)
        call = service.calls.get((gid, int(info.sequence_number)))
        key = id(call)
        if int(info.event_type) in _REQUESTS:
            if key not in service.answers and len(event.request):
                service.answers[key] = service.processor.on_request(  # type: ignore[attr-defined]
                    service_name(message.topic), event.request[0], message.log_time
                )
        elif len(event.response):
            answer = service.answers.get(key)
            event.response = [answer] if answer is not None else []
        write(message.topic, event, message.log_time)
