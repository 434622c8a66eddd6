"""What a replay did: per-topic counts, timing error, what could not be read (no rclpy)."""

from __future__ import annotations

from dataclasses import asdict, dataclass, field
from typing import Any

from bagkit.playback.service_responses import ServiceReplaySummary
from bagkit.playback.timing import LatenessSummary
from bagkit.words import counted


@dataclass(frozen=True, slots=True)
class PlayProgress:
    """A snapshot of a running replay, for a progress line."""

    bag_time_s: float
    """Bag time played in the current pass, from the start of the replayed window."""
    wall_time_s: float
    """Wall time since the first message of the current pass was scheduled."""
    effective_rate: float
    """Bag time over wall time since the timeline was last re-anchored (start, seek, resume or
    rate change): the rate in force, not an average over pauses."""
    messages: int
    late: int
    loop: int
    bag_ns: int = 0
    """Log time reached (ns since the epoch)."""
    fraction: float = 0.0
    """Share of the replayed window reached (0 to 1)."""
    rate: float = 1.0
    """The rate in force (the controls'), next to the effective one."""
    paused: bool = False


@dataclass(frozen=True, slots=True)
class TopicPlayback:
    """What was replayed of one topic."""

    topic: str
    published_as: str
    type: str
    messages: int
    unreadable: int = 0
    """Messages the bag's index lists but that could not be read (damaged chunks)."""


@dataclass(frozen=True, slots=True)
class SubscriberWait:
    """What the player waited for before its first message."""

    seconds: float
    subscriptions: int
    """Subscriptions matched on the replayed topics (and ``/clock``)."""
    topics: int
    """Of those topics, the ones with a subscription."""
    all_discovered: bool
    """The wait ended on finding every participant on this host, not at the discovery time."""
    participants_replaced: int = 0
    """New participants that lost the answers of the others on this host before the one that
    waited (``seconds`` counts from its creation)."""

    def line(self) -> str:
        """``waited 0.4 s for 2 subscriptions on 1 topic`` (``, discovery restarted 1 time``)."""
        restarted = self.participants_replaced
        return (
            f"waited {self.seconds:.1f} s for {counted(self.subscriptions, 'subscription')} "
            f"on {counted(self.topics, 'topic')}"
            + (f", discovery restarted {counted(restarted, 'time')}" if restarted else "")
        )


@dataclass(slots=True)
class PlayReport:
    """The outcome of a replay."""

    topics: list[TopicPlayback]
    messages: int
    loops: int
    """Passes over the bag that completed."""
    bag_duration_s: float
    """Bag time covered by the replayed messages, summed over passes."""
    wall_duration_s: float
    """Wall time from the start of the first pass (its delay included) to the last message,
    time paused included."""
    rate: float
    """The rate in force at the end (the controls may have changed the one asked for)."""
    lateness: LatenessSummary
    skipped_types: dict[str, str] = field(default_factory=dict)
    """Topic -> message type that is not installed (not replayed)."""
    skipped_formats: dict[str, str] = field(default_factory=dict)
    """Topic -> serialization format other than ``cdr`` (not replayed)."""
    drifted: dict[str, list[str]] = field(default_factory=dict)
    """Topic -> how its stored definition differs from the installed one (not replayed
    unless ``on_drift`` is raw)."""
    problems: list[str] = field(default_factory=list)
    """What the reader could not read (a truncated or damaged file), naming the chunk."""
    unacknowledged: list[str] = field(default_factory=list)
    """Reliable topics whose subscribers had not acknowledged every message at the end."""
    interrupted: bool = False
    latched: int = 0
    """Of ``messages``, those published as latched state on a late start (not timed)."""
    service_requests: ServiceReplaySummary | None = None
    """With ``publish_service_requests``: requests sent and how the live responses compared."""
    waited: SubscriberWait | None = None
    """The wait for subscribers before the first message (None: no wait)."""
    paused_s: float = 0.0
    """Of ``wall_duration_s``, the time playback was held: paused (keys, services, a start
    paused) or the process stopped (Ctrl+Z)."""

    @property
    def played_s(self) -> float:
        """Of ``wall_duration_s``, the time playback ran: the wall time less the time paused."""
        return self.wall_duration_s - self.paused_s

    @property
    def unreadable(self) -> int:
        """Messages of the replayed topics that could not be read, over every pass."""
        return sum(t.unreadable for t in self.topics)

    def to_dict(self) -> dict[str, Any]:
        """The report as plain JSON-ready data."""
        data = asdict(self)
        data["unreadable"] = self.unreadable
        data["played_s"] = self.played_s
        if self.service_requests is not None:
            data["service_requests"] = self.service_requests.to_dict()
        return data
