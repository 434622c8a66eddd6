"""The latched state of a bag at a time: the last message before it of each latched topic.

A replay that starts late (``--start-offset``, a seek, a loop) or a cut that starts late
(``filter --start``) first hands out the state a late-joining transient-local subscriber would
have had at that time: the last message before it of each topic recorded transient-local (from
the offered QoS the bag stores; no list needed), plus topics named by the user, none with
``--no-latched``. The messages are found from the storage's indexes
(:meth:`bagkit.bag.reader.BagReader.last_messages`: MCAP Message Index records of the chunks
near the time, an SQL query for SQLite3), never by reading the bag from its start.

Only the last message per topic: what a transient-local publisher of depth 1 (``/tf_static``,
maps, state topics) keeps. Pure of ROS: the QoS text is read with :mod:`bagkit.bag.safe_yaml`.
"""

from __future__ import annotations

from collections.abc import Collection, Iterable, Mapping
from dataclasses import dataclass

import yaml

from bagkit.bag import safe_yaml
from bagkit.bag.messages import BagMessage, TopicInfo
from bagkit.bag.reader import BagReader
from bagkit.selection.topics import require_topics

# rmw's durability policy: the short name (metadata version 9, MCAP channel metadata) or the
# enum value (metadata versions 4 to 8).
_TRANSIENT_LOCAL = ("transient_local", 1)


@dataclass(frozen=True)
class LatchedOptions:
    """Which topics carry their state over to a later start.

    Attributes:
        enabled: False (``--no-latched``): no latched state at all.
        extra_topics: topics recorded volatile whose last message is carried over too
            (``--latched-topics``).
    """

    enabled: bool = True
    extra_topics: tuple[str, ...] = ()


def is_transient_local(offered_qos_profiles: str) -> bool:
    """Whether any publisher offered transient-local durability, from rosbag2's QoS text.

    Any, not all: replay publishes such a topic transient-local (the strictest offer wins,
    :func:`bagkit.ros.qos.adapt_publisher_qos`). Unparsable text (a bag is untrusted) is
    volatile.
    """
    if not offered_qos_profiles.strip():
        return False
    try:
        profiles = safe_yaml.load(offered_qos_profiles)
    except yaml.YAMLError:
        return False
    if not isinstance(profiles, list):
        return False
    return any(
        isinstance(p, dict) and _durability(p.get("durability")) in _TRANSIENT_LOCAL
        for p in profiles
    )


def _durability(value: object) -> object:
    if isinstance(value, str):
        return value.strip().lower()
    return value if isinstance(value, int) and not isinstance(value, bool) else None


def transient_local_topics(topics: Mapping[str, TopicInfo]) -> set[str]:
    """The topics (``BagReader.topics``) recorded from a transient-local publisher."""
    return {name for name, info in topics.items() if is_transient_local(info.offered_qos_profiles)}


def latched_topics(
    topics: Mapping[str, TopicInfo],
    options: LatchedOptions,
    selected: Iterable[str] | None = None,
) -> set[str]:
    """The topics whose state is carried over: transient-local ones plus ``extra_topics``,
    among ``selected`` (all of ``topics`` when None).

    Raises:
        UnknownTopicError: an extra topic is not in ``topics``.
    """
    if not options.enabled:
        return set()
    extra = set(require_topics(list(options.extra_topics), topics))
    wanted = transient_local_topics(topics) | extra
    if selected is not None:
        wanted &= set(selected)
    return wanted


def last_messages_before(
    bag: BagReader, topics: Iterable[str], before_ns: int
) -> dict[str, BagMessage]:
    """The last message with ``log_time < before_ns`` of each of ``topics`` that has one.

    ``bag`` is open; any storage (MCAP, SQLite3, split bags of both). Ties in log time: the
    one stored last, the last one :meth:`BagReader.messages` would yield.
    """
    return bag.last_messages(topics, before_ns)


def latched_state(
    bag: BagReader,
    before_ns: int,
    options: LatchedOptions | None = None,
    selected: Iterable[str] | None = None,
) -> list[BagMessage]:
    """The latched state of ``bag`` at ``before_ns``, in log-time order (ties: by topic).

    Args:
        bag: an open bag.
        before_ns: the log time the replay or the cut starts at (exclusive).
        options: which topics (default: every transient-local one).
        selected: the topics the replay or cut keeps (all when None).

    Raises:
        UnknownTopicError: an extra topic of ``options`` is not in the bag.
    """
    topics = latched_topics(bag.topics, options or LatchedOptions(), selected)
    if not topics:
        return []
    found = last_messages_before(bag, topics, before_ns)
    return sorted(found.values(), key=lambda m: (m.log_time, m.topic))


def is_state_topic(reader: BagReader, topic: str, state_topics: Collection[str] = ()) -> bool:
    """Whether ``topic``'s value holds until its next message (named, or latched)."""
    return topic in state_topics or is_transient_local(reader.topics[topic].offered_qos_profiles)
