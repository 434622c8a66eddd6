"""play's window reads the one time grammar (``--start-offset -5`` as ``--start -5``)."""

from __future__ import annotations

import datetime as dt
from pathlib import Path

import pytest

from bagkit.playback.errors import PlayerError
from bagkit.playback.options import PlayWindow
from bagkit.selection.windows import TimeRange

START, END = 1_763_850_000_000_000_000, 1_763_850_060_000_000_000  # a minute of messages
S = 1_000_000_000


@pytest.mark.parametrize(
    "start",
    ["10", 10, "1m30s", "-5", -5.0, "1763850012.5", "2025-11-22T22:20:12Z", f"{START + S}ns"],
)
def test_start_offset_resolves_as_start_does_elsewhere(start: str | float) -> None:
    """The same start as filter's/echo's ``--start`` (TimeRange), clamped to the bag."""
    expected = TimeRange.parse(start, None).resolve(START, END).start_ns
    assert expected is not None
    window = PlayWindow.create(start)
    if expected > END:
        with pytest.raises(PlayerError, match="holds no message"):
            window.bounds(START, END, Path("bag"))
    else:
        assert window.bounds(START, END, Path("bag")) == (max(START, expected), None)


def test_from_the_end_and_absolute_starts() -> None:
    bag = Path("bag")
    assert PlayWindow.create("-5").bounds(START, END, bag)[0] == END - 5 * S
    iso = dt.datetime.fromtimestamp((START + 12 * S) / S, tz=dt.timezone.utc).isoformat()
    assert PlayWindow.create(iso).bounds(START, END, bag)[0] == START + 12 * S
    assert PlayWindow.create(0).whole and not PlayWindow.create("-0").whole
    with pytest.raises(PlayerError, match=r"^bag: the time window .* holds no message"):
        PlayWindow.create("2m").bounds(START, END, bag)
    with pytest.raises(PlayerError, match="bad start offset"):
        PlayWindow.create("soon")


def test_an_until_before_the_bag_is_the_one_outside_message() -> None:
    window = PlayWindow.create(until_ns=START - S)
    with pytest.raises(PlayerError, match=r"^bag: the time window \[.*holds no message"):
        window.bounds(START, END, Path("bag"))
    # Until inside the bag, or a duration reaching past it (the later end counts): a window.
    assert PlayWindow.create(until_ns=START).bounds(START, END, Path("bag")) == (START, START + 1)
    assert PlayWindow.create(duration_ns=2 * S, until_ns=START - S).bounds(
        START, END, Path("bag")
    ) == (
        START,
        START + 2 * S,
    )
