"""The ROS graph as the recorder sees it: which topics to record and what their publishers offer."""

from __future__ import annotations

import re
from dataclasses import dataclass, field

from rclpy.node import Node
from rclpy.qos import QoSProfile
from rclpy.topic_or_service_is_hidden import topic_or_service_is_hidden

from bagkit.errors import BagkitError
from bagkit.ros.errors import RecorderOptionsError


def absolute_topic_name(name: str) -> str:
    """``imu/data`` -> ``/imu/data``: the recorder's node lives in the root namespace."""
    return name if name.startswith("/") else f"/{name}"


def compile_topic_pattern(
    pattern: str | None, option: str, *, error: type[BagkitError] = RecorderOptionsError
) -> re.Pattern[str] | None:
    """Compile a ``--regex``/``--exclude`` option; a bad expression raises ``error``."""
    if pattern is None:
        return None
    try:
        return re.compile(pattern)
    except re.error as exc:
        raise error(f"{option} {pattern!r} is not a valid regular expression: {exc}") from None


@dataclass(frozen=True, slots=True)
class TopicFilter:
    """Which topics to record, as ``ros2 bag record`` selects them.

    A topic named in ``topics`` is always recorded. ``all_topics`` and ``regex`` (searched
    anywhere in the name) add more, minus those matching ``exclude``; hidden topics (a path
    component starting with ``_``) only with ``include_hidden``.
    """

    topics: frozenset[str] = frozenset()
    all_topics: bool = False
    regex: re.Pattern[str] | None = None
    exclude: re.Pattern[str] | None = None
    include_hidden: bool = False

    @classmethod
    def create(
        cls,
        topics: tuple[str, ...] | list[str] = (),
        *,
        all_topics: bool = False,
        regex: str | None = None,
        exclude: str | None = None,
        include_hidden: bool = False,
    ) -> TopicFilter:
        """Build a filter from command-line style options.

        Raises:
            RecorderOptionsError: nothing selected, or a regular expression does not compile.
        """
        if not topics and not all_topics and regex is None:
            raise RecorderOptionsError("nothing to record: name topics, or use --all or --regex")
        return cls(
            topics=frozenset(absolute_topic_name(t) for t in topics),
            all_topics=all_topics,
            regex=compile_topic_pattern(regex, "--regex"),
            exclude=compile_topic_pattern(exclude, "--exclude"),
            include_hidden=include_hidden,
        )

    def matches(self, name: str) -> bool:
        """Whether topic ``name`` is to be recorded."""
        if name in self.topics:
            return True
        if not (self.all_topics or (self.regex is not None and self.regex.search(name))):
            return False
        if self.exclude is not None and self.exclude.search(name):
            return False
        return self.include_hidden or not topic_or_service_is_hidden(name)


@dataclass(frozen=True, slots=True)
class DiscoveredTopic:
    """A topic with at least one publisher, and the profiles its publishers offer."""

    name: str
    types: tuple[str, ...]
    offered: tuple[QoSProfile, ...] = field(default=())
    type_hash: str = ""


def discover_topics(node: Node, topic_filter: TopicFilter) -> list[DiscoveredTopic]:
    """Topics in ``node``'s graph that ``topic_filter`` selects and someone else publishes.

    The node's own publishers (every rclpy node publishes ``/parameter_events``) do not count.
    """
    own = (node.get_name(), node.get_namespace())
    found = []
    for name, types in node.get_topic_names_and_types():
        if not topic_filter.matches(name):
            continue
        publishers = [
            p
            for p in node.get_publishers_info_by_topic(name)
            if (p.node_name, p.node_namespace) != own
        ]
        if not publishers:
            continue
        type_hash = str(getattr(publishers[0], "topic_type_hash", "") or "")
        found.append(
            DiscoveredTopic(
                name=name,
                types=tuple(types),
                offered=tuple(p.qos_profile for p in publishers),
                type_hash=type_hash if type_hash.startswith("RIHS01_") else "",
            )
        )
    return found
