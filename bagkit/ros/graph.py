"""The ROS graph as the recorder sees it: the selected topics and what their publishers offer."""

from __future__ import annotations

from dataclasses import dataclass, field

from rclpy.node import Node
from rclpy.qos import QoSProfile

from bagkit.selection.topics import TopicSelection


@dataclass(frozen=True, slots=True)
class DiscoveredTopic:
    """A topic with at least one publisher, and the profiles its publishers offer."""

    name: str
    types: tuple[str, ...]
    offered: tuple[QoSProfile, ...] = field(default=())
    type_hash: str = ""


def discover_topics(
    node: Node, selection: TopicSelection, *, include_unpublished: bool = False
) -> list[DiscoveredTopic]:
    """Topics in ``node``'s graph that ``selection`` selects and someone else publishes.

    The node's own publishers (every rclpy node publishes ``/parameter_events``) do not count.
    With ``include_unpublished``, topics that only have subscribers are found too (no offers).
    """
    own = (node.get_name(), node.get_namespace())
    found = []
    for name, types in node.get_topic_names_and_types():
        if not selection.matches(name, types):
            continue
        publishers = [
            p
            for p in node.get_publishers_info_by_topic(name)
            if (p.node_name, p.node_namespace) != own
        ]
        if not publishers and not include_unpublished:
            continue
        type_hash = str(getattr(publishers[0], "topic_type_hash", "") or "") if publishers else ""
        found.append(
            DiscoveredTopic(
                name=name,
                types=tuple(types),
                offered=tuple(p.qos_profile for p in publishers),
                type_hash=type_hash if type_hash.startswith("RIHS01_") else "",
            )
        )
    return found
