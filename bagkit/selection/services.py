"""Services as rosbag2 Jazzy records them: the event topics of service introspection.

A service ``/name`` with introspection on publishes each call's events on the hidden topic
``/name/_service_event`` (type ``pkg/srv/Name_Event``). rosbag2 counts a topic as a service's
when its name ends in ``/_service_event`` and its type is a ``srv`` ``_Event``; such topics are
selected only by the service options (``--services``, ``--all-services``, ``-a``), never by the
topic options (``--all-topics``, ``--regex``, ``--include-hidden-topics``). An action's topics
(:mod:`bagkit.selection.actions`) are selected the same way, by the action options. No rclpy
import.
"""

from __future__ import annotations

from collections.abc import Iterable

from bagkit.selection.topics import SERVICE_EVENT_SUFFIX, absolute_topic_name


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
