"""Pure parts of the replay: timeline arithmetic, waits, lateness statistics, CLI parsing."""

from __future__ import annotations

import time

import pytest
from typer.testing import CliRunner

from bagkit.cli.main import app
from bagkit.playback.errors import PlayerError
from bagkit.playback.lateness import LatenessSamples
from bagkit.playback.options import PlayOptions
from bagkit.playback.timing import (
    LATE_THRESHOLD_NS,
    LatenessSummary,
    Timeline,
    wait_until,
)
from bagkit.ros.replay.topics import parse_remaps


def test_timeline_scales_bag_time_by_rate() -> None:
    timeline = Timeline(bag_start_ns=1_000_000_000_000, wall_start_ns=5_000, rate=2.0)
    assert timeline.deadline(1_000_000_000_000) == 5_000
    assert timeline.deadline(1_001_000_000_000) == 5_000 + 500_000_000
    assert timeline.bag_time(5_000 + 500_000_000) == 1_001_000_000_000


def test_wait_until_never_returns_early() -> None:
    for offset_ns in (0, 200_000, 3_000_000):
        deadline = time.monotonic_ns() + offset_ns
        returned = wait_until(deadline)
        assert returned >= deadline
        assert time.monotonic_ns() >= deadline


def test_lateness_summary_percentiles_and_late_count() -> None:
    samples = [i * 10_000 for i in range(101)]  # 0 .. 1 ms in 10 us steps
    samples += [-5_000, LATE_THRESHOLD_NS + 1, 7_000_000]
    summary = LatenessSummary.from_samples(samples)
    ordered = sorted(max(0, s) for s in samples)
    middle = len(ordered) // 2
    assert ordered[middle - 1] / 1e6 <= summary.p50_ms <= ordered[middle] / 1e6
    assert summary.max_ms == pytest.approx(7.0)
    assert summary.late == 2
    assert 0.99 < summary.p99_ms <= 7.0


def test_lateness_summary_of_nothing_is_nan() -> None:
    summary = LatenessSummary.from_samples([])
    assert summary.late == 0
    assert summary.p50_ms != summary.p50_ms


def test_lateness_samples_are_exact_below_capacity_and_bounded_above() -> None:
    samples = [(i * 7_919) % 3_000_000 - 100_000 for i in range(5_000)]
    exact = LatenessSamples()
    for value in samples:
        exact.add(value)
    assert exact.summary() == LatenessSummary.from_samples(samples)
    bounded = LatenessSamples(capacity=100)
    for value in samples * 20:  # 20 passes over the same messages
        bounded.add(value)
    assert len(bounded.samples) == 100
    assert bounded.count == 100_000
    summary = bounded.summary()
    # Count, maximum and late messages stay exact; the percentiles come from the sample.
    assert summary.late == 20 * sum(1 for v in samples if v > LATE_THRESHOLD_NS)
    assert summary.max_ms == max(samples) / 1e6
    assert 0.9 < summary.p50_ms < 1.8  # the samples spread evenly over -0.1 .. 2.9 ms


def test_parse_remaps() -> None:
    assert parse_remaps(["/a:=/b", "c:=/d/e"]) == {"/a": "/b", "c": "/d/e"}
    with pytest.raises(PlayerError, match="OLD:=NEW"):
        parse_remaps(["/a=/b"])


@pytest.mark.parametrize(
    ("args", "expected"),
    [
        (["BAG", "--clock"], "40"),
        (["--clock", "BAG"], "40"),
        (["BAG", "--clock", "25"], "25"),
        (["BAG", "--clock=2.5e1"], "25"),
        (["BAG", "--clock", "--rate", "2"], "40"),
    ],
)
def test_clock_takes_an_optional_value(
    args: list[str], expected: str, monkeypatch: pytest.MonkeyPatch
) -> None:
    """A bare --clock means 40 Hz (as ros2 bag play) wherever it stands; it reaches the Player."""
    seen: dict[str, object] = {}

    class FakePlayer:
        def __init__(self, options: PlayOptions, **_callbacks: object) -> None:
            seen.update(vars(options))
            raise PlayerError("stop here")

    monkeypatch.setattr("bagkit.ros.replay.player.Player", FakePlayer)
    result = CliRunner().invoke(app, ["replay", *args])
    assert result.exit_code == 2, result.output
    assert seen["clock_hz"] == float(expected)
