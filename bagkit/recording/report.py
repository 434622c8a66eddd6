"""What a recording produced: per-topic counts and losses, the report, progress snapshots."""

from __future__ import annotations

import json
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

from bagkit.bag.rates import message_rate
from bagkit.recording.health_watch import HealthCount


@dataclass(slots=True)
class TopicRecord:
    """What was recorded on one topic, and what was lost."""

    topic: str
    type: str
    messages: int = 0
    bytes: int = 0
    gaps: int = 0
    overflow: int = 0
    write_failed: int = 0
    publishers: int = 0
    first_ns: int = 0
    last_ns: int = 0
    # Taken before the first /clock with --use-sim-time: not written (no time to stamp with).
    before_clock: int = 0
    # Taken while the recording was paused: not written by request, not lost.
    paused: int = 0

    @property
    def lost(self) -> int:
        """Every message of this topic that is not in the bag."""
        return self.gaps + self.overflow + self.write_failed

    @property
    def rate_hz(self) -> float | None:
        """Message rate between the first and the last message (log time); see message_rate."""
        return message_rate(self.messages, self.first_ns, self.last_ns)

    def to_dict(self) -> dict[str, Any]:
        """JSON-ready view, with ``lost`` and ``rate_hz``."""
        return {
            "topic": self.topic,
            "type": self.type,
            "messages": self.messages,
            "lost": self.lost,
            "gaps": self.gaps,
            "overflow": self.overflow,
            "write_failed": self.write_failed,
            "publishers": self.publishers,
            "rate_hz": self.rate_hz,
            "bytes": self.bytes,
            "before_clock": self.before_clock,
            "paused": self.paused,
        }


@dataclass(slots=True)
class SnapshotRecord:
    """One snapshot of a snapshot-mode recording: its bag, its window, what it holds."""

    path: Path
    trigger: str
    """What opened it: ``service``, ``key``, ``request`` or the ``--trigger`` text."""
    trigger_ns: int
    start_ns: int
    end_ns: int
    triggers: int = 1
    """Triggers inside its window (each one extends it)."""
    messages: dict[str, int] = field(default_factory=dict)
    latched: int = 0
    """Copies of latched messages written at its start."""
    error: str | None = None

    def to_dict(self) -> dict[str, Any]:
        """JSON-ready view."""
        return {
            "path": str(self.path),
            "trigger": self.trigger,
            "trigger_ns": self.trigger_ns,
            "start_ns": self.start_ns,
            "end_ns": self.end_ns,
            "triggers": self.triggers,
            "messages": dict(sorted(self.messages.items())),
            "latched": self.latched,
            "error": self.error,
        }


@dataclass(slots=True)
class RecordReport:
    """The outcome of a recording: per-topic counts, skipped topics, the error that stopped it."""

    path: Path
    duration_s: float = 0.0
    # From start until every named topic (or, none named, the first topic) was subscribed.
    discovery_s: float | None = None
    # The named topics never seen, with the closest names the graph had (a misspelt name
    # waits for ever): bad input for the CLI, which exits 2 with it.
    never_appeared: str | None = None
    topics: list[TopicRecord] = field(default_factory=list)
    skipped: dict[str, str] = field(default_factory=dict)
    error: str | None = None
    # The exit status ``error`` calls for: 1 a failed run, 2 bad input found while recording
    # (a trigger's field that a topic appearing late lacks).
    error_exit_code: int = 1
    # Snapshot mode only (None otherwise): the snapshots written, and per topic the messages
    # evicted from the buffer by its bound (by design: not lost, not in a snapshot).
    snapshots: list[SnapshotRecord] | None = None
    evicted: dict[str, int] = field(default_factory=dict)
    # With a live health check only (None otherwise): per assertion, its breaks and clears.
    health: list[HealthCount] | None = None

    @property
    def messages(self) -> int:
        """Messages in the bag."""
        return sum(t.messages for t in self.topics)

    @property
    def lost(self) -> int:
        """Messages lost on every topic together."""
        return sum(t.lost for t in self.topics)

    @property
    def bytes(self) -> int:
        """Serialized message bytes in the bag."""
        return sum(t.bytes for t in self.topics)

    def topic(self, name: str) -> TopicRecord:
        """The record of topic ``name`` (KeyError if it was not recorded)."""
        for record in self.topics:
            if record.topic == name:
                return record
        raise KeyError(name)

    def to_dict(self) -> dict[str, Any]:
        """JSON-ready view."""
        view = {
            "path": str(self.path),
            "duration_s": self.duration_s,
            "discovery_s": self.discovery_s,
            "never_appeared": self.never_appeared,
            "messages": self.messages,
            "lost": self.lost,
            "bytes": self.bytes,
            "topics": [t.to_dict() for t in self.topics],
            "skipped": dict(self.skipped),
            "error": self.error,
        }
        if self.snapshots is not None:
            view["snapshots"] = [s.to_dict() for s in self.snapshots]
            view["evicted"] = dict(sorted(self.evicted.items()))
        if self.health is not None:
            view["health"] = [count.to_dict() for count in self.health]
        return view


@dataclass(frozen=True, slots=True)
class RecordProgress:
    """A snapshot of a running recording, for a progress line."""

    elapsed_s: float
    topics: int
    messages: int
    bytes: int
    lost: int
    before_clock: int = 0
    paused: int = 0
    """Messages taken while paused (not written, not lost)."""
    is_paused: bool = False
    span_ns: int = 0
    """Log time from the first message written to the last."""


# Where the recorder stores loss_summary in metadata.yaml's custom_data (bagkit doctor reads it).
LOSS_CUSTOM_DATA_KEY = "bagkit.record.loss"


def loss_summary(records: list[TopicRecord]) -> str:
    """JSON ``{topic: {messages, bytes, gaps, overflow, write_failed, publishers}}``
    (custom_data is string -> string)."""
    return json.dumps(
        {
            r.topic: {
                "messages": r.messages,
                "bytes": r.bytes,
                "gaps": r.gaps,
                "overflow": r.overflow,
                "write_failed": r.write_failed,
                "publishers": r.publishers,
            }
            for r in sorted(records, key=lambda r: r.topic)
        },
        sort_keys=True,
    )
