"""What ``bagkit record`` selects (:class:`RecordSelection`): topics as :class:`TopicSelection`
selects them, plus the topics of the services and actions asked for. Kept apart from
:mod:`bagkit.selection.services`, which every command reading a bag with services imports. No
rclpy import."""

from __future__ import annotations

from collections.abc import Iterable
from dataclasses import dataclass, fields

from bagkit.selection.actions import action_topic_part
from bagkit.selection.services import is_service_event_topic, service_name
from bagkit.selection.topics import TopicSelection, absolute_topic_name


@dataclass(frozen=True, slots=True)
class RecordSelection(TopicSelection):
    """Topics as :class:`TopicSelection` selects them, plus services' and actions' topics.

    ``exclude`` (``--exclude-regex``) applies to event and action topics too, as in rosbag2.
    """

    services: frozenset[str] = frozenset()
    all_services: bool = False
    exclude_services: frozenset[str] = frozenset()
    actions: frozenset[str] = frozenset()
    all_actions: bool = False
    exclude_actions: frozenset[str] = frozenset()

    @classmethod
    def of(
        cls,
        topics: TopicSelection,
        services: Iterable[str] = (),
        *,
        all_services: bool = False,
        exclude_services: Iterable[str] = (),
        actions: Iterable[str] = (),
        all_actions: bool = False,
        exclude_actions: Iterable[str] = (),
    ) -> RecordSelection:
        """``topics`` extended by the service and action options (names with or without ``/``)."""
        return cls(
            **{f.name: getattr(topics, f.name) for f in fields(TopicSelection)},
            services=_names(services),
            all_services=all_services,
            exclude_services=_names(exclude_services),
            actions=_names(actions),
            all_actions=all_actions,
            exclude_actions=_names(exclude_actions),
        )

    @property
    def empty(self) -> bool:
        """Whether nothing can be selected, topic, service or action."""
        topics_empty = super(RecordSelection, self).empty
        services_empty = not self.services and not self.all_services
        return topics_empty and services_empty and not self.actions and not self.all_actions

    def matches(self, name: str, types: Iterable[str] = ()) -> bool:
        """Whether topic ``name`` is selected; a service's or action's by their own options."""
        types = list(types)
        if name in self.topics:
            return super(RecordSelection, self).matches(name, types)
        if self.exclude is not None and self.exclude.search(name):
            return False
        action_part = action_topic_part(name, types)
        if action_part is not None:
            action = action_part[0]
            if action in self.exclude_actions:
                return False
            return self.all_actions or action in self.actions
        if not is_service_event_topic(name, types):
            return super(RecordSelection, self).matches(name, types)
        service = service_name(name)
        if service in self.exclude_services:
            return False
        return self.all_services or service in self.services


def _names(names: Iterable[str]) -> frozenset[str]:
    """Service or action names, absolute and without a trailing ``/``."""
    return frozenset(absolute_topic_name(n).rstrip("/") for n in names)
