"""Which messages a ``filter`` keeps: topics, exclusions, regexes and a log-time range.

The rules of ``ros2 bag convert``/``record`` (Jazzy): a topic passes when it is named in
``topics`` or matches ``regex`` (all topics when neither is given), and is neither named in
``exclude_topics`` nor matched by ``exclude_regex``. Regexes match anywhere in the name
(``re.search``), as rosbag2's do. Pure: no ROS, no files.
"""

from __future__ import annotations

import datetime
import re
from dataclasses import dataclass, field

from bagkit.surgery.errors import SurgeryError


@dataclass(frozen=True)
class Selection:
    """A topic selection and a log-time range ``[start_ns, end_ns)``.

    Raises:
        SurgeryError: a regex does not compile, or the range is empty.
    """

    topics: frozenset[str] = frozenset()
    regex: str = ""
    exclude_topics: frozenset[str] = frozenset()
    exclude_regex: str = ""
    start_ns: int | None = None
    end_ns: int | None = None
    _compiled: tuple[re.Pattern[str] | None, re.Pattern[str] | None] = field(
        init=False, repr=False, compare=False
    )

    def __post_init__(self) -> None:
        object.__setattr__(self, "_compiled", (_compile(self.regex), _compile(self.exclude_regex)))
        if self.start_ns is not None and self.end_ns is not None and self.end_ns <= self.start_ns:
            raise SurgeryError(f"empty time range: end {self.end_ns} is not after start")

    def topic_passes(self, topic: str) -> bool:
        """Whether messages of ``topic`` are kept (time aside)."""
        include, exclude = self._compiled
        if self.topics or include is not None:
            named = topic in self.topics
            if not named and (include is None or include.search(topic) is None):
                return False
        if topic in self.exclude_topics:
            return False
        return exclude is None or exclude.search(topic) is None

    def time_passes(self, log_time: int) -> bool:
        """Whether a message logged at ``log_time`` is in the range."""
        if self.start_ns is not None and log_time < self.start_ns:
            return False
        return self.end_ns is None or log_time < self.end_ns

    def covers(self, start: int, end: int) -> bool:
        """Whether every log time in ``[start, end]`` is in the range."""
        return self.time_passes(start) and self.time_passes(end)

    @property
    def restricts_time(self) -> bool:
        """Whether a time range is set."""
        return self.start_ns is not None or self.end_ns is not None


def _compile(pattern: str) -> re.Pattern[str] | None:
    if not pattern:
        return None
    try:
        return re.compile(pattern)
    except re.error as exc:
        raise SurgeryError(f"bad regex {pattern!r}: {exc}") from None


def parse_time(text: str) -> int:
    """A time option as ns since the epoch: ``1700000000.5`` (seconds), ``1700000000500000000ns``,
    or ISO 8601 (``2026-11-23T12:00:00Z``; UTC when no zone is given).

    Raises:
        SurgeryError: none of these.
    """
    ns = _epoch_ns(text.strip())
    if ns is None or not 0 <= ns < 1 << 63:
        raise SurgeryError(f"bad time {text!r} (seconds since the epoch, NNNns, or ISO 8601)")
    return ns


def _epoch_ns(value: str) -> int | None:
    try:
        if value.endswith("ns"):
            return int(value[:-2])
        if value.replace(".", "", 1).isdigit():
            seconds, _, fraction = value.partition(".")
            return int(seconds) * 1_000_000_000 + int((fraction + "0" * 9)[:9])
        stamp = datetime.datetime.fromisoformat(value.replace("Z", "+00:00"))
    except ValueError:
        return None
    if stamp.tzinfo is None:
        stamp = stamp.replace(tzinfo=datetime.UTC)
    return int(stamp.timestamp()) * 1_000_000_000 + stamp.microsecond * 1000
