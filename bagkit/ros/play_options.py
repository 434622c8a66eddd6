"""The player's options that need no rclpy: their ranges, the replayed window, the waits."""

from __future__ import annotations

from dataclasses import dataclass
from pathlib import Path

from bagkit.ros.errors import PlayerError
from bagkit.ros.timing import DEFAULT_DISCOVERY_TIME_S
from bagkit.times import seconds_to_ns


def check_play_options(rate: float, delay: float, clock_hz: float | None, loops: int) -> None:
    """Raise PlayerError for an option out of its range."""
    if not rate > 0:
        raise PlayerError(f"rate must be positive, got {rate}")
    if delay < 0:
        raise PlayerError(f"delay must not be negative, got {delay}")
    if clock_hz is not None and not clock_hz > 0:
        raise PlayerError(f"clock rate must be positive, got {clock_hz}")
    if loops < 0:
        raise PlayerError(f"loops must be 0 (forever) or positive, got {loops}")


@dataclass(frozen=True, slots=True)
class PlayWindow:
    """The part of the bag each pass replays (``--start-offset``, ``--duration``, until).

    Attributes:
        start_offset_ns: skipped from the bag's first message.
        duration_ns: bag time replayed after the offset; None = to the end.
        until_ns: last log time replayed (ns since the epoch); with ``duration_ns`` the later
            of the two ends the window (as rosbag2).
    """

    start_offset_ns: int = 0
    duration_ns: int | None = None
    until_ns: int | None = None

    @classmethod
    def create(
        cls, start_offset: float = 0.0, duration: float | None = None, until_ns: int | None = None
    ) -> PlayWindow:
        """The window of the player's options, in seconds; PlayerError out of range."""
        if start_offset < 0:
            raise PlayerError(f"start offset must not be negative, got {start_offset}")
        if duration is not None and not duration > 0:
            raise PlayerError(f"duration must be positive, got {duration}")
        duration_ns = None if duration is None else seconds_to_ns(duration, duration, PlayerError)
        return cls(seconds_to_ns(start_offset, start_offset, PlayerError), duration_ns, until_ns)

    @property
    def whole(self) -> bool:
        """Whether every message of the bag is in the window."""
        return not self.start_offset_ns and self.duration_ns is None and self.until_ns is None

    def bounds(self, start_ns: int, end_ns: int, bag: Path) -> tuple[int, int | None]:
        """Log-time bounds (start, exclusive end or None) in a bag of messages start..end.

        Raises:
            PlayerError: the offset is past the bag's last message (nothing would be replayed).
        """
        if self.start_offset_ns > end_ns - start_ns:
            raise PlayerError(
                f"--start-offset {self.start_offset_ns / 1e9:g} s is past the end of "
                f"{bag} ({(end_ns - start_ns) / 1e9:.3f} s of messages)"
            )
        window_start = start_ns + self.start_offset_ns
        ends = []
        if self.duration_ns is not None:
            ends.append(window_start + self.duration_ns)
        if self.until_ns is not None:
            ends.append(self.until_ns + 1)
        return window_start, max(ends) if ends else None


@dataclass(frozen=True, slots=True)
class SubscriberWaits:
    """How the player waits for its subscribers, before the first message and after the last.

    Attributes:
        before_start: wait until every subscription the graph shows on a replayed topic has
            matched.
        topics: topics that must have a subscriber before playback starts.
        timeout_s: how long to wait for them before giving up.
        discovery_s: after the node's creation, how long the graph is watched for
            subscriptions that already exist.
        ack_timeout_s: at the end, how long subscribers of reliable topics get to acknowledge
            every message.
    """

    before_start: bool = True
    topics: tuple[str, ...] = ()
    timeout_s: float = 10.0
    discovery_s: float = DEFAULT_DISCOVERY_TIME_S
    ack_timeout_s: float = 10.0
