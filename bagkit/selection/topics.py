"""Which topics to record or replay: one set of rules for both, as ``ros2 bag`` selects them.

A topic is selected when it is named, or when ``all_topics`` is set, or when ``regex`` matches
somewhere in its name, or when its type is one of ``topic_types``; then every topic that
``exclude`` matches, that ``exclude_topics`` names or whose type ``exclude_topic_types`` names is
left out, named ones too (``ros2 bag``'s ``--exclude-regex`` works on top of ``--topics``,
``--all`` and ``--regex``).
Hidden topics (a name component starting with ``_``) are selected by ``all_topics`` or
``regex`` only with ``include_hidden``; a named hidden topic is always selected. Names are
absolute: ``imu/data`` means ``/imu/data``. No rclpy import.
"""

from __future__ import annotations

import difflib
import re
from collections.abc import Iterable, Sequence
from dataclasses import dataclass

from bagkit.errors import OptionError
from bagkit.selection.errors import SelectionError, UnknownTopicError
from bagkit.words import counted

SERVICE_EVENT_SUFFIX = "/_service_event"
"""What a service's name ends in as a topic: introspection's events (see ``services``)."""
ACTION_INFIX = "/_action/"
"""What separates an action's name from its parts' names (see ``actions``)."""


def absolute_topic_name(name: str) -> str:
    """``imu/data`` -> ``/imu/data``: bagkit's nodes live in the root namespace."""
    return name if name.startswith("/") else f"/{name}"


def canonical_type(name: str) -> str:
    """``std_msgs/String`` -> ``std_msgs/msg/String``: types compare in their full form."""
    parts = name.split("/")
    return f"{parts[0]}/msg/{parts[1]}" if len(parts) == 2 else name


def is_hidden(name: str) -> bool:
    """Whether a component of ``name`` starts with ``_``, as rclpy's hidden-topic rule."""
    return any(part.startswith("_") for part in name.split("/"))


def compile_topic_pattern(
    pattern: str | None, field: str, *, error: type[OptionError] = SelectionError
) -> re.Pattern[str] | None:
    """Compile the ``regex``/``exclude_regex`` option; a bad expression raises ``error``
    naming ``field``."""
    if pattern is None:
        return None
    try:
        return re.compile(pattern)
    except re.error as exc:
        raise error(f"{pattern!r} is not a valid regular expression: {exc}", field) from None


@dataclass(frozen=True, slots=True)
class TopicSelection:
    """The topics chosen by names, types, ``--all``, ``--regex``, exclusions and hidden-ness."""

    topics: frozenset[str] = frozenset()
    all_topics: bool = False
    regex: re.Pattern[str] | None = None
    exclude: re.Pattern[str] | None = None
    include_hidden: bool = False
    topic_types: frozenset[str] = frozenset()
    exclude_topics: frozenset[str] = frozenset()
    exclude_topic_types: frozenset[str] = frozenset()

    @classmethod
    def create(
        cls,
        topics: Iterable[str] = (),
        *,
        all_topics: bool = False,
        regex: str | None = None,
        exclude: str | None = None,
        include_hidden: bool = False,
        topic_types: Iterable[str] = (),
        exclude_topics: Iterable[str] = (),
        exclude_topic_types: Iterable[str] = (),
        error: type[OptionError] = SelectionError,
    ) -> TopicSelection:
        """Build a selection from command-line style options.

        Raises:
            error: a regular expression does not compile.
        """
        return cls(
            topics=frozenset(absolute_topic_name(t) for t in topics),
            all_topics=all_topics,
            regex=compile_topic_pattern(regex, "regex", error=error),
            exclude=compile_topic_pattern(exclude, "exclude_regex", error=error),
            include_hidden=include_hidden,
            topic_types=frozenset(canonical_type(t) for t in topic_types),
            exclude_topics=frozenset(absolute_topic_name(t) for t in exclude_topics),
            exclude_topic_types=frozenset(canonical_type(t) for t in exclude_topic_types),
        )

    @property
    def empty(self) -> bool:
        """Whether nothing can be selected: no name, no type, no ``--all``, no ``--regex``."""
        return (
            not self.topics and not self.topic_types and not self.all_topics and self.regex is None
        )

    def matches(self, name: str, types: Iterable[str] = ()) -> bool:
        """Whether topic ``name`` (of ``types``, where known) is selected."""
        types = {canonical_type(t) for t in types}
        if name in self.exclude_topics or not self.exclude_topic_types.isdisjoint(types):
            return False
        if self.exclude is not None and self.exclude.search(name):
            return False
        if name in self.topics:
            return True
        if not (
            self.all_topics
            or (self.regex is not None and self.regex.search(name))
            or not self.topic_types.isdisjoint(types)
        ):
            return False
        return self.include_hidden or not is_hidden(name)

    def missing(self, available: Iterable[str]) -> list[str]:
        """Named topics that are not in ``available``, sorted."""
        return sorted(self.topics - set(available))


def require_topics(
    wanted: Iterable[str], known: Iterable[str], where: str = "the bag"
) -> list[str]:
    """``wanted`` as the names ``known`` holds them: ``imu/data`` and ``/imu/data`` are one
    topic, whichever way a bag stored it (bags of other tools may hold relative names); a
    recorded service's name stands for its event topic (``/reset`` for
    ``/reset/_service_event``), as in ``echo``.

    Raises:
        UnknownTopicError: a name is not known; the message names the closest known topics
            (or all of them, when few).
    """
    known = sorted(set(known))
    stored = {absolute_topic_name(name): name for name in known}

    def stored_name(name: str) -> str | None:
        if name in known:
            return name
        topic, service_events, _ = meant_by(name)
        return stored.get(topic) or stored.get(service_events)

    names = [stored_name(name) for name in wanted]
    missing = [absolute_topic_name(w) for w, n in zip(wanted, names, strict=True) if n is None]
    if missing:
        raise UnknownTopicError(
            f"topic {', '.join(missing)} not in {where} ({closest_names(missing[0], known)})"
        )
    return [name for name in names if name is not None]


def meant_by(name: str) -> tuple[str, str, str]:
    """The topic names (or globs) a name given for a topic stands for: itself, its event topic
    if it names a service, its topics if it names an action (as :func:`require_topics` and
    ``echo`` read them)."""
    base = absolute_topic_name(name).rstrip("/")
    return absolute_topic_name(name), base + SERVICE_EVENT_SUFFIX, base + ACTION_INFIX + "*"


def missing_on_graph(missing: Sequence[str], graph: Iterable[str]) -> str:
    """``record --topics``: the named topics that never appeared, and the closest ones that did.

    ``graph`` is every topic the recorder saw on the ROS graph.
    """
    names = sorted(set(graph))
    return (
        f"topic {', '.join(missing)} never appeared on the graph "
        f"({closest_names(missing[0], names)})"
    )


def closest_names(name: str, known: Sequence[str], limit: int = 20) -> str:
    """``did you mean /a, /b?`` or ``it has /a, /b, ...``: the known names a reader wants to see.

    A service's event topic is also known by the service's name, an action's topics by the
    action's name: what a reader types.
    """
    if not known:
        return "it has none"
    services = [
        n.removesuffix(SERVICE_EVENT_SUFFIX) for n in known if n.endswith(SERVICE_EVENT_SUFFIX)
    ]
    actions = [n.partition(ACTION_INFIX)[0] for n in known if ACTION_INFIX in n]
    guess = did_you_mean(name, [*known, *services, *actions])
    if len(known) > limit:
        return f"{guess}it has {counted(len(known), 'topic')}, {', '.join(known[:limit])}, ..."
    return f"{guess}it has {', '.join(known)}"


def did_you_mean(name: str, known: Iterable[str]) -> str:
    """``did you mean a, b? `` (up to three close names), or ``""``: every command's guess."""
    close = difflib.get_close_matches(name, list(dict.fromkeys(known)), n=3, cutoff=0.6)
    return f"did you mean {', '.join(close)}? " if close else ""
