"""What the recorder asks of a live health check (``bagkit record --health``), rclpy-free.

The recorder's writer thread feeds a :class:`HealthWatch` what it writes and the time between
batches; the watch answers with :class:`HealthEvent` s (a check broke, a check cleared) and
keeps a :class:`HealthCount` per assertion for the report. The implementation,
:class:`bagkit.health.live.LiveHealth`, lives above the recorder in the import layers and is
handed to :class:`~bagkit.ros.record.recorder.Recorder`.
"""

from __future__ import annotations

import json
from collections.abc import Sequence
from dataclasses import dataclass
from typing import Any, Protocol

from bagkit.bag import TopicInfo

HEALTH_CUSTOM_DATA_KEY = "bagkit.record.health"
"""metadata.yaml custom_data key: JSON ``[{topic, assertion, breaks, clears, broken}]``."""


@dataclass(frozen=True, slots=True)
class HealthEvent:
    """A check broke (``broken``) or cleared, at ``at_ns`` (log time)."""

    broken: bool
    topic: str
    assertion: str
    at_ns: int
    since_ns: int
    """Where the episode began (for a clear: how long it was broken)."""

    def line(self) -> str:
        """``health: broken /imu/data: gap > 500ms`` (or ``cleared ... after 1.20 s``)."""
        if self.broken:
            return f"health: broken {self.topic}: {self.assertion}"
        lasted = (self.at_ns - self.since_ns) / 1e9
        return f"health: cleared {self.topic}: {self.assertion} (after {lasted:.2f} s)"


@dataclass(slots=True)
class HealthCount:
    """One assertion over a recording: how often it broke and cleared; broken at the end."""

    topic: str
    assertion: str
    breaks: int = 0
    clears: int = 0
    broken_since_ns: int | None = None

    def to_dict(self) -> dict[str, Any]:
        """JSON-ready view."""
        return {
            "topic": self.topic,
            "assertion": self.assertion,
            "breaks": self.breaks,
            "clears": self.clears,
            "broken": self.broken_since_ns is not None,
        }


def health_summary(counts: Sequence[HealthCount]) -> str:
    """The counts as JSON for metadata.yaml's custom_data (string -> string)."""
    return json.dumps([count.to_dict() for count in counts])


class HealthWatch(Protocol):
    """A contract evaluated on what the recorder writes.

    Attributes:
        trigger: in snapshot mode, a broken check triggers a snapshot at the time it broke.
        stop_after_ns: stop the recording once a check has been broken this long (None:
            never).
    """

    trigger: bool
    stop_after_ns: int | None

    def add_topic(self, info: TopicInfo, definition: str) -> list[HealthEvent]:
        """A topic is recorded (its type is checked). Raises BagkitError for a contract that
        names a field the type lacks (exit status 2)."""

    def observe(
        self, topic: str, payloads: Sequence[bytes], log_times: Sequence[int]
    ) -> list[HealthEvent]:
        """Messages of ``topic`` were written."""

    def advance(self, now_ns: int) -> list[HealthEvent]:
        """Time has come to ``now_ns`` (a silence is known while it lasts)."""

    def finish(self, end_ns: int) -> list[HealthEvent]:
        """The recording ended at ``end_ns``: every episode is closed."""

    def overdue(self, now_ns: int) -> HealthCount | None:
        """An assertion broken for ``stop_after_ns`` or longer at ``now_ns``, if any."""

    @property
    def counts(self) -> list[HealthCount]:
        """Per assertion, in the contract's order."""
