"""One query for every command: which topics, which fields, which times, which messages.

A :class:`Query` is what the user asked for, parsed once: topic names (a recorded service's or
action's name stands for its topics, as ``echo`` takes them), field patterns
(:mod:`bagkit.selection.fields`), a :class:`~bagkit.selection.windows.TimeRange` and a
condition (:mod:`bagkit.selection.conditions`). It says nothing of where a bag lives:
:meth:`Query.resolve` takes what a bag tells of itself (its topics with their types, the span
of its messages) and gives a :class:`ResolvedQuery`, the names as that bag stores them and the
window in its log times. An unknown name is an error that names the closest ones
(:func:`~bagkit.selection.topics.require_topics`); a window outside the bag is the one
warning (:func:`~bagkit.selection.windows.outside_warning`). No bag reading, no rclpy.
"""

from __future__ import annotations

from collections.abc import Iterable, Mapping
from dataclasses import dataclass, field, replace
from typing import TYPE_CHECKING, Protocol

from bagkit.selection.actions import action_part_topics
from bagkit.selection.fields import FieldSelection
from bagkit.selection.times import TimeLike
from bagkit.selection.topics import require_topics
from bagkit.selection.windows import TimeRange, Window, outside_warning

if TYPE_CHECKING:
    from bagkit.selection.conditions import Condition


class TopicType(Protocol):
    """A topic as a bag describes it: anything with a ``type`` (``bagkit.bag.TopicInfo``)."""

    @property
    def type(self) -> str: ...


class BagOutline(Protocol):
    """What a query is resolved against: a bag's topics and the span of its messages
    (``bagkit.bag.BagReader`` is one, wherever the bag lives)."""

    @property
    def topics(self) -> Mapping[str, TopicType]: ...

    @property
    def start_ns(self) -> int: ...

    @property
    def end_ns(self) -> int: ...

    @property
    def message_count(self) -> int: ...


def _names(value: str | Iterable[str] | None) -> tuple[str, ...]:
    if value is None:
        return ()
    return (value,) if isinstance(value, str) else tuple(value)


@dataclass(frozen=True, slots=True)
class Query:
    """Topics, fields, a time range and a condition, as given; empty parts select everything.

    Attributes:
        topics: topic, service or action names (``imu/data`` is ``/imu/data``).
        fields: field patterns, ``[TOPIC_GLOB:]FIELD_GLOB``.
        span: ``--start``/``--end``, resolved against each bag.
        where: only the messages satisfying this condition.
    """

    topics: tuple[str, ...] = ()
    fields: tuple[str, ...] = ()
    span: TimeRange = field(default_factory=TimeRange)
    where: Condition | None = None

    @classmethod
    def create(
        cls,
        topics: str | Iterable[str] | None = None,
        fields: str | Iterable[str] | None = None,
        start: TimeLike | None = None,
        end: TimeLike | None = None,
        where: str | Condition | None = None,
        *,
        prefix: str = "--",
    ) -> Query:
        """A query from a command's options or a library call's keywords.

        ``prefix`` starts the option names that errors cite (``--start``; ``""`` for a library
        call's ``start``).

        Raises:
            SelectionError: a time or the condition does not parse, or the range is empty.
        """
        topic_names, field_names = _names(topics), _names(fields)
        span = TimeRange.parse(start, end, prefix=prefix)
        if isinstance(where, str):
            # The condition language is imported for a condition only: echo starts without.
            from bagkit.selection.conditions import parse_condition

            where = parse_condition(where)
        return cls(topic_names, field_names, span, where)

    def with_topics(self, topics: str | Iterable[str] | None) -> Query:
        """This query for other topics (a command that takes its topic as an argument)."""
        return replace(self, topics=_names(topics))

    @property
    def field_selection(self) -> FieldSelection:
        """The field patterns as a selection (all fields when there is none)."""
        return FieldSelection(self.fields)

    def resolve(self, bag: BagOutline, *, label: str = "the bag") -> ResolvedQuery:
        """This query against one bag: its names as the bag stores them, its window.

        Raises:
            UnknownTopicError: a name is neither a topic, a service nor an action of the bag;
                the message names the closest ones.
        """
        types = {name: info.type for name, info in bag.topics.items()}
        window = self.span.resolve(bag.start_ns, bag.end_ns)
        outside = (
            outside_warning(label, window, bag.start_ns, bag.end_ns) if bag.message_count else None
        )
        return ResolvedQuery(
            self, label, resolve_names(self.topics, types), window, outside=outside
        )


@dataclass(frozen=True, slots=True)
class ResolvedQuery:
    """A query against one bag.

    Attributes:
        query: what was asked.
        label: the bag as the user named it.
        topics: the topics asked for, as the bag stores them (a service's event topic, an
            action's topics); empty when the query names none (all topics).
        window: the time range in the bag's log times.
        outside: the one warning when the window holds none of the bag's messages, else None.
    """

    query: Query
    label: str
    topics: tuple[str, ...]
    window: Window
    outside: str | None = None

    @property
    def condition(self) -> Condition | None:
        """The condition messages must satisfy, or None."""
        return self.query.where

    @property
    def fields(self) -> tuple[str, ...]:
        """The field patterns."""
        return self.query.fields

    def selects(self, topic: str) -> bool:
        """Whether ``topic`` (a name the bag stores) is asked for."""
        return not self.topics or topic in self.topics


def resolve_names(
    wanted: Iterable[str], topic_types: Mapping[str, str], where: str = "the bag"
) -> tuple[str, ...]:
    """Topic, service and action names as the bag (``topic_types``: name -> type) stores them.

    A topic name is itself (``imu/data`` and ``/imu/data`` are one), a service's name its event
    topic, an action's name the topics of its parts; duplicates are dropped, order kept.
    ``where`` names the bags in the error (``any of the bags``).

    Raises:
        UnknownTopicError: a name is none of these; the message names the closest ones.
    """
    found: list[str] = []
    for name in wanted:
        parts = [] if name in topic_types else action_part_topics(name, topic_types.items())
        found += parts or require_topics([name], topic_types, where)
    return tuple(dict.fromkeys(found))
