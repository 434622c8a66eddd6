"""Where a pass reads: the window's messages and the latched state, each migrated on the fly.

A topic whose stored definition drifted from the installed one is replayed migrated (``--on-
drift migrate``): each payload goes through its topic's :class:`PayloadMigration` (a
:class:`bagkit.migrate.TopicMigration`, which sits above playback in the layering) as it is read.
"""

from __future__ import annotations

import functools
from collections.abc import Callable, Iterator, Mapping
from dataclasses import dataclass
from typing import TYPE_CHECKING, Protocol

from bagkit.bag import BagMessage
from bagkit.bag.messages import make_message

if TYPE_CHECKING:
    from bagkit.playback.seeking import WindowSpan
    from bagkit.playback.source import PlaySource


class PayloadMigration(Protocol):
    """A topic's migration to the installed definition (a ``bagkit.migrate.TopicMigration``)."""

    def payload(self, data: bytes | memoryview) -> bytes:
        """One payload of the stored definition as a payload of the installed one."""


@dataclass(frozen=True, slots=True)
class PassReader:
    """Where a pass reads: the window's messages from a bag time, the latched state at one."""

    messages_from: Callable[[int], Iterator[BagMessage]]
    """Messages of the replayed topics from this log time to the window's end, in order."""
    latched_before: Callable[[int], list[BagMessage]]
    """The last message before this log time of each latched topic (issue 27, item 1)."""
    end_ns: int
    """The window's last log time (for the progress line's percentage)."""


def pass_reader(
    source: PlaySource,
    topics: list[str],
    span: WindowSpan,
    *,
    latched: set[str],
    migrations: Mapping[str, PayloadMigration],
) -> PassReader:
    """The :class:`PassReader` of ``topics`` of ``source`` in ``span``; the last message of
    each of ``latched`` is the latched state; the topics of ``migrations`` are migrated."""

    def messages_from(bag_ns: int) -> Iterator[BagMessage]:
        found = iter(source.messages(topics, bag_ns, span.end_ns))
        return map(functools.partial(_migrated, migrations), found) if migrations else found

    def latched_before(bag_ns: int) -> list[BagMessage]:
        found = source.latched_before(bag_ns, latched) if latched else []
        return [_migrated(migrations, m) for m in found]

    return PassReader(messages_from, latched_before, span.last_ns)


def _migrated(migrations: Mapping[str, PayloadMigration], message: BagMessage) -> BagMessage:
    """``message`` with its payload migrated when its topic is one of ``migrations``."""
    migration = migrations.get(message.topic)
    if migration is None:
        return message
    data = migration.payload(message.data)
    return make_message(
        message.topic, data, message.log_time, message.publish_time, message.sequence
    )
