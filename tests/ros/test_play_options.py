"""The player's options and window, checked without rclpy."""

from __future__ import annotations

from pathlib import Path

import pytest

from bagkit.playback.errors import PlayerError
from bagkit.playback.options import PlayOptions, PlayWindow

BAG = Path("drive")
START, END = 1_000_000_000_000, 1_010_000_000_000  # 10 s of messages


def test_whole_bag_has_no_end() -> None:
    window = PlayWindow.create()
    assert window.whole
    assert window.bounds(START, END, BAG) == (START, None)


def test_offset_and_duration_in_seconds() -> None:
    window = PlayWindow.create(start=2.5, duration_ns=1_250_000_000)
    assert not window.whole
    assert window.bounds(START, END, BAG) == (START + 2_500_000_000, START + 3_750_000_000)


def test_the_later_of_duration_and_until_ends_the_window() -> None:
    until = START + 5_000_000_000
    shorter = PlayWindow.create(duration_ns=1_000_000_000, until_ns=until)
    longer = PlayWindow.create(duration_ns=8_000_000_000, until_ns=until)
    assert shorter.bounds(START, END, BAG) == (START, until + 1)  # until is inclusive
    assert longer.bounds(START, END, BAG) == (START, START + 8_000_000_000)
    assert not PlayWindow.create(until_ns=until).whole


def test_a_start_from_the_end_as_elsewhere() -> None:
    assert PlayWindow.create(start=-2.5).bounds(START, END, BAG) == (END - 2_500_000_000, None)


def test_offset_past_the_last_message_names_the_bag() -> None:
    window = PlayWindow.create(start=10.5)
    with pytest.raises(PlayerError, match=r"^drive: the time window \[.*\) holds no message"):
        window.bounds(START, END, BAG)
    assert PlayWindow.create(start=10.0).bounds(START, END, BAG) == (END, None)


@pytest.mark.parametrize(
    ("options", "message"),
    [
        ({"start": "soon"}, "bad start offset 'soon': not a time"),
        ({"duration_ns": 0}, "^duration_ns: must be positive, got 0"),
        ({"duration_ns": -1}, "^duration_ns: must be positive, got -1"),
        ({"start": 1e300}, "1e"),
    ],
)
def test_window_out_of_range(options: dict[str, object], message: str) -> None:
    with pytest.raises(PlayerError, match=message):
        PlayWindow.create(**options)


@pytest.mark.parametrize(
    ("rate", "delay", "clock_hz", "loops", "message"),
    [
        (0.0, 0.0, None, 1, "^rate: must be positive"),
        (float("nan"), 0.0, None, 1, "^rate: must be positive"),
        (float("inf"), 0.0, None, 1, "^rate: must be positive"),
        (1.0, -1, None, 1, "^delay_ns: must not be negative"),
        (1.0, 0.0, 0.0, 1, "^clock_hz: must be positive"),
        (1.0, 0.0, None, -1, "^loops: must be 0"),
    ],
)
def test_options_out_of_range(
    rate: float, delay: float, clock_hz: float | None, loops: int, message: str
) -> None:
    with pytest.raises(PlayerError, match=message):
        PlayOptions(BAG, rate=rate, delay_ns=delay, clock_hz=clock_hz, loops=loops)
    assert PlayOptions(BAG, loops=0).loops == 0  # 0 loops: until interrupted
