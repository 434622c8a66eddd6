"""Which of a bag's topics a replay publishes: selected, not excluded, cdr, type installed."""

from __future__ import annotations

from collections.abc import Callable, Iterable, Mapping
from dataclasses import dataclass, field
from pathlib import Path
from typing import TYPE_CHECKING, Any

from bagkit.bag import TopicInfo
from bagkit.bag.clock import CLOCK_TOPIC
from bagkit.playback.options import OnDrift
from bagkit.ros.errors import MessageClassNotFoundError, PlayerError
from bagkit.ros.message_classes import import_message_type
from bagkit.selection.topics import TopicSelection

if TYPE_CHECKING:
    from bagkit.migrate import Rules, TopicMigration


@dataclass(slots=True)
class PublishableTopics:
    """The topics to publish with their message classes, and the selected ones that cannot be."""

    selected: list[tuple[TopicInfo, Any]] = field(default_factory=list)
    skipped_types: dict[str, str] = field(default_factory=dict)
    """Topic -> its message type, not installed."""
    skipped_formats: dict[str, str] = field(default_factory=dict)
    """Topic -> its serialization format, not cdr."""
    drifted: dict[str, list[str]] = field(default_factory=dict)
    """Topic -> how its stored definition differs from the installed one (skipped unless
    published raw or migrated)."""
    migrations: dict[str, TopicMigration] = field(default_factory=dict)
    """Topic -> its migration to the installed definition (``on_drift`` migrate)."""


def publishable_topics(
    topics: Mapping[str, TopicInfo],
    selection: TopicSelection,
    *,
    clock_published: bool,
    bag_path: Path,
    definition: Callable[[str], str | None] = lambda _: None,
    on_drift: OnDrift = OnDrift.SKIP,
    rules: Rules | None = None,
) -> PublishableTopics:
    """The topics of ``topics`` to publish; a recorded ``/clock`` not when the player makes one.

    ``definition`` gives a topic's stored definition: a topic whose definition drifted from
    the installed type's is in ``drifted``, and published only with ``on_drift`` RAW (as
    recorded) or MIGRATE (each message migrated, with ``rules``: ``migrations``).

    Raises:
        MigrateError: with MIGRATE, a drifted topic cannot be migrated.
        PlayerError: nothing is left to publish (the message says why).
    """
    # Here, not at the top: the player's PublishableTopics() must not import the decoder
    # (rosbags, numpy) or the migrator before its node exists (see Player._open).
    from bagkit.decode.drift import DriftStatus, topic_drift
    from bagkit.migrate import Target, migrate_topic

    found = PublishableTopics()
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
        drift = topic_drift(info, definition(name))
        if drift.status is DriftStatus.DRIFTED:
            found.drifted[name] = drift.changes
            if on_drift is OnDrift.SKIP:
                continue
            if on_drift is OnDrift.MIGRATE:
                migration = migrate_topic(info, definition(name), Target(), rules)
                if migration is not None:
                    found.migrations[name] = migration
        found.selected.append((info, message_class))
    if not found.selected:
        reason = "no topic of the bag matches the topic selection"
        if found.skipped_types or found.skipped_formats or found.drifted:
            reason = "no selected topic can be published: " + "; ".join(
                [
                    f"{name}: {type_name} not installed"
                    for name, type_name in sorted(found.skipped_types.items())
                ]
                + [
                    f"{name}: serialization format {fmt!r} is not cdr"
                    for name, fmt in sorted(found.skipped_formats.items())
                ]
                + [
                    f"{name}: its definition drifted from the installed one "
                    f"({'; '.join(changes)}; --on-drift raw publishes it as recorded, migrate "
                    "migrated)"
                    for name, changes in sorted(found.drifted.items())
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
