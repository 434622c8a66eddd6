"""Which of a bag's topics a replay publishes: selected, not excluded, cdr, type installed."""

from __future__ import annotations

from collections.abc import Iterable, Mapping
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

from bagkit.bag import TopicInfo
from bagkit.ros.clock import CLOCK_TOPIC
from bagkit.ros.errors import MessageClassNotFoundError, PlayerError
from bagkit.ros.message_classes import import_message_type
from bagkit.selection.topics import TopicSelection, closest_names, require_topics


@dataclass(slots=True)
class PublishableTopics:
    """The topics to publish with their message classes, and the selected ones that cannot be."""

    selected: list[tuple[TopicInfo, Any]] = field(default_factory=list)
    skipped_types: dict[str, str] = field(default_factory=dict)
    """Topic -> its message type, not installed."""
    skipped_formats: dict[str, str] = field(default_factory=dict)
    """Topic -> its serialization format, not cdr."""
    missing: list[str] = field(default_factory=list)
    """Topics named by the selection that the bag does not have."""
    known: list[str] = field(default_factory=list)
    """The bag's topics, for the closest names to the missing ones."""

    def missing_text(self) -> str:
        """``/imu/dat (did you mean /imu/data? it has ...)``: the missing topics, for a warning."""
        return f"{', '.join(self.missing)} ({closest_names(self.missing[0], self.known)})"


def publishable_topics(
    topics: Mapping[str, TopicInfo],
    selection: TopicSelection,
    *,
    clock_published: bool,
    bag_path: Path,
) -> PublishableTopics:
    """The topics of ``topics`` to publish; a recorded ``/clock`` not when the player makes one.

    Raises:
        UnknownTopicError: nothing is selected and a named topic is not in the bag.
        PlayerError: nothing is left to publish (the message says why).
    """
    found = PublishableTopics(missing=selection.missing(topics), known=sorted(topics))
    for name, info in sorted(topics.items()):
        if not selection.matches(name):
            continue
        if clock_published and name == CLOCK_TOPIC:
            continue
        if info.serialization_format != "cdr":
            found.skipped_formats[name] = info.serialization_format
            continue
        try:
            message_class = import_message_type(info.type)
        except MessageClassNotFoundError:
            found.skipped_types[name] = info.type
            continue
        found.selected.append((info, message_class))
    if not found.selected and found.missing:
        require_topics(found.missing, topics)  # raises, with the closest topics of the bag
    if not found.selected:
        reason = "no topic of the bag matches the topic selection"
        if found.skipped_types or found.skipped_formats:
            reason = "no selected topic can be published: " + "; ".join(
                [
                    f"{name}: {type_name} not installed"
                    for name, type_name in sorted(found.skipped_types.items())
                ]
                + [
                    f"{name}: serialization format {fmt!r} is not cdr"
                    for name, fmt in sorted(found.skipped_formats.items())
                ]
            )
        raise PlayerError(f"nothing to replay in {bag_path}: {reason}")
    return found


def parse_remaps(pairs: Iterable[str]) -> dict[str, str]:
    """Parse ``OLD:=NEW`` topic remappings (as ``ros2 bag play --remap``)."""
    remap = {}
    for pair in pairs:
        old, sep, new = pair.partition(":=")
        if not sep or not old or not new:
            raise PlayerError(f"remapping {pair!r} is not of the form OLD:=NEW")
        remap[old] = new
    return remap
