"""Services as rosbag2 Jazzy records them: the event topics of service introspection.

A service ``/name`` with introspection on publishes each call's events on the hidden topic
``/name/_service_event`` (type ``pkg/srv/Name_Event``). rosbag2 counts a topic as a service's
when its name ends in ``/_service_event`` and its type is a ``srv`` ``_Event``; such topics are
selected only by the service options (``--services``, ``--all-services``, ``-a``), never by the
topic options (``--all-topics``, ``--regex``, ``--include-hidden-topics``). No rclpy import.
"""

from __future__ import annotations

from collections.abc import Iterable
from dataclasses import dataclass, fields

from bagkit.selection.topics import TopicSelection, absolute_topic_name

SERVICE_EVENT_SUFFIX = "/_service_event"


def is_service_event_type(type_name: str) -> bool:
    """Whether ``type_name`` is a service-event type, ``pkg/srv/Name_Event``."""
    return "/srv/" in type_name and type_name.endswith("_Event")


def is_service_event_topic(name: str, types: Iterable[str] = ()) -> bool:
    """Whether topic ``name`` (of ``types``, where known) carries a service's events."""
    types = list(types)
    return name.endswith(SERVICE_EVENT_SUFFIX) and all(is_service_event_type(t) for t in types)


def service_name(event_topic: str) -> str:
    """``/reset/_service_event`` -> ``/reset``."""
    return event_topic.removesuffix(SERVICE_EVENT_SUFFIX)


def event_topic(service: str) -> str:
    """``reset`` or ``/reset`` -> ``/reset/_service_event``."""
    return absolute_topic_name(service).rstrip("/") + SERVICE_EVENT_SUFFIX


def service_type(event_type: str) -> str:
    """``std_srvs/srv/Trigger_Event`` -> ``std_srvs/srv/Trigger``."""
    return event_type.removesuffix("_Event")


@dataclass(frozen=True, slots=True)
class RecordSelection(TopicSelection):
    """Topics as :class:`TopicSelection` selects them, plus services' event topics.

    ``exclude`` (``--exclude-regex``) applies to event topics too, as in rosbag2.
    """

    services: frozenset[str] = frozenset()
    all_services: bool = False
    exclude_services: frozenset[str] = frozenset()

    @classmethod
    def of(
        cls,
        topics: TopicSelection,
        services: Iterable[str] = (),
        *,
        all_services: bool = False,
        exclude_services: Iterable[str] = (),
    ) -> RecordSelection:
        """``topics`` extended by the service options (names with or without a leading ``/``)."""
        return cls(
            **{f.name: getattr(topics, f.name) for f in fields(TopicSelection)},
            services=frozenset(absolute_topic_name(s).rstrip("/") for s in services),
            all_services=all_services,
            exclude_services=frozenset(absolute_topic_name(s) for s in exclude_services),
        )

    @property
    def empty(self) -> bool:
        """Whether nothing can be selected, topic or service."""
        topics_empty = super(RecordSelection, self).empty
        return topics_empty and not self.services and not self.all_services

    def matches(self, name: str, types: Iterable[str] = ()) -> bool:
        """Whether topic ``name`` is selected; a service's event topic by the service options."""
        types = list(types)
        if name in self.topics:
            return super(RecordSelection, self).matches(name, types)
        if not is_service_event_topic(name, types):
            return super(RecordSelection, self).matches(name, types)
        service = service_name(name)
        if service in self.exclude_services:
            return False
        if self.exclude is not None and self.exclude.search(name):
            return False
        return self.all_services or service in self.services
