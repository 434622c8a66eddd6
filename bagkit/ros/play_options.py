"""The ranges of the player's options, checked before anything is opened (no rclpy here)."""

from __future__ import annotations

from bagkit.ros.errors import PlayerError


def check_play_options(  # noqa: PLR0917 (the Player's options, checked together)
    rate: float,
    start_offset: float,
    duration: float | None,
    delay: float,
    clock_hz: float | None,
    loops: int,
) -> None:
    """Raise PlayerError for an option out of its range."""
    if not rate > 0:
        raise PlayerError(f"rate must be positive, got {rate}")
    if start_offset < 0:
        raise PlayerError(f"start offset must not be negative, got {start_offset}")
    if duration is not None and not duration > 0:
        raise PlayerError(f"duration must be positive, got {duration}")
    if delay < 0:
        raise PlayerError(f"delay must not be negative, got {delay}")
    if clock_hz is not None and not clock_hz > 0:
        raise PlayerError(f"clock rate must be positive, got {clock_hz}")
    if loops < 0:
        raise PlayerError(f"loops must be 0 (forever) or positive, got {loops}")
