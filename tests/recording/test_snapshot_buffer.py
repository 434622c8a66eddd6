"""The snapshot buffer and the latched state: bounds, windows, eviction counts, latched copies."""

from __future__ import annotations

import random

import pytest

from bagkit.bag.messages import BagMessage
from bagkit.recording.errors import RecorderOptionsError
from bagkit.recording.latched import LatchedState, parse_repeat
from bagkit.recording.snapshot_buffer import MESSAGE_OVERHEAD, SnapshotBuffer

S = 1_000_000_000


def add(buffer: SnapshotBuffer, topic: str, times: list[int], size: int = 100) -> None:
    buffer.add(
        topic,
        [bytes([len(times) % 256]) * size for _ in times],
        times,
        [t - 5 for t in times],
        list(range(1, len(times) + 1)),
    )


def test_byte_bound_holds_and_every_message_is_held_or_evicted() -> None:
    rng = random.Random(7)
    bound = 50_000
    buffer = SnapshotBuffer(max_bytes=bound)
    added = 0
    now = 0
    for _ in range(500):
        count = rng.randint(1, 40)
        times = [now + i for i in range(count)]
        now += count
        add(buffer, rng.choice(["/a", "/b"]), times, size=rng.randint(1, 900))
        added += count
        assert buffer.held_bytes <= bound
        assert buffer.held_messages + sum(buffer.evicted.values()) == added
    # Nearly full: the bound is used, not just respected (one message of slack at most).
    assert buffer.held_bytes > bound - (900 + MESSAGE_OVERHEAD)


def test_duration_bound_keeps_the_newest_seconds() -> None:
    buffer = SnapshotBuffer(max_duration_ns=30 * S)
    for second in range(100):
        add(buffer, "/imu", [second * S + k * S // 10 for k in range(10)])
    oldest = buffer.oldest_ns
    assert oldest is not None
    assert buffer.newest_ns - oldest <= 30 * S
    assert buffer.newest_ns - oldest > 29 * S
    assert buffer.held_messages == 301  # 30 s at 10 Hz, both ends included
    assert buffer.evicted["/imu"] == 1000 - 301


def test_window_returns_messages_in_range_without_evicted_ones() -> None:
    buffer = SnapshotBuffer(max_duration_ns=10 * S)
    for second in range(20):
        add(buffer, "/a", [second * S])
        add(buffer, "/b", [second * S + 1, second * S + 2])
    slices = buffer.window(12 * S, 15 * S)
    times = sorted(t for s in slices for t in s.log_times)
    expected = sorted(
        [s * S for s in range(12, 16)] + [s * S + k for s in range(12, 15) for k in (1, 2)]
    )
    assert times == expected
    everything = buffer.window()
    oldest = min(t for s in everything for t in s.log_times)
    assert oldest == buffer.oldest_ns


def test_latched_before_finds_evicted_and_held_messages() -> None:
    latched = LatchedState({"/state": 1, "/tf_static": 2})
    buffer = SnapshotBuffer(max_duration_ns=10 * S, latched=latched)
    add(buffer, "/tf_static", [0, 1])
    for second in range(1, 40):
        add(buffer, "/imu", [second * S])
        if second % 5 == 0:
            add(buffer, "/state", [second * S + 7])
    start = buffer.oldest_ns
    assert start is not None
    copies = buffer.latched_before(start)
    by_topic = {m.topic: [c.log_time for c in copies if c.topic == m.topic] for m in copies}
    # The buffer holds 29 - 39 s: the last /state before it (25 s + 7 ns) was evicted.
    assert start == 29 * S
    assert by_topic == {"/state": [25 * S + 7], "/tf_static": [0, 1]}
    # A later start finds the held /state message of 35 s.
    later = buffer.latched_before(36 * S)
    assert [m.log_time for m in later if m.topic == "/state"] == [35 * S + 7]


def test_latched_state_keeps_the_last_n() -> None:
    state = LatchedState({"/map": 2})
    for i in range(5):
        state.observe(BagMessage("/map", b"m", i, i, i))
    state.observe(BagMessage("/other", b"x", 9, 9, 9))
    assert [m.log_time for m in state.messages()] == [3, 4]
    assert [m.log_time for m in state.messages(before_ns=4)] == [3]


def test_parse_repeat() -> None:
    assert parse_repeat(["/tf_static", "map=3"]) == {"/tf_static": 1, "/map": 3}
    for bad in ("=2", "/map=0", "/map=x"):
        with pytest.raises(RecorderOptionsError, match=r"^repeat_transient_local: "):
            parse_repeat([bad])


def test_a_bound_is_required() -> None:
    with pytest.raises(ValueError, match="bound"):
        SnapshotBuffer()
