"""The replay's rclpy-free parts of issue 27: several bags as one timeline, message order,
latched state across bags, seek/burst/stop in the controls, the progress line."""

from __future__ import annotations

import io
import threading
import time
from contextlib import ExitStack
from pathlib import Path

import pytest

from bagkit.bag import BagWriter, TopicInfo
from bagkit.playback.controls import PlayControls
from bagkit.playback.errors import PlayerError
from bagkit.playback.options import PlayWindow
from bagkit.playback.progress import ProgressLine, progress_text
from bagkit.playback.report import PlayProgress
from bagkit.playback.seeking import WindowSpan
from bagkit.playback.source import SENT_ORDER_WINDOW_NS, MessageOrder, PlaySource

START = 1_700_000_000_000_000_000
LATCHED = (
    "- history: keep_last\n  depth: 1\n  reliability: reliable\n  durability: transient_local\n"
)


def write(path: Path, rows: list[tuple[str, int, int]], qos: dict[str, str] | None = None) -> Path:
    """rows: (topic, log offset ns, publish offset ns); payload = the row's index."""
    with BagWriter(path) as writer:
        for topic in dict.fromkeys(topic for topic, _, _ in rows):
            info = TopicInfo(
                topic, "std_msgs/msg/Int32", offered_qos_profiles=(qos or {}).get(topic, "")
            )
            writer.add_topic(info, definition="int32 data\n")
        for index, (topic, log, sent) in enumerate(rows):
            writer.write(topic, bytes([index]), log_time=START + log, publish_time=START + sent)
    return path


def test_two_bags_merge_by_log_time_and_share_topics(tmp_path: Path) -> None:
    a = write(tmp_path / "a", [("/x", 0, 0), ("/y", 20, 20), ("/x", 40, 40)])
    b = write(tmp_path / "b", [("/x", 10, 10), ("/z", 30, 30)])
    with ExitStack() as stack:
        source = PlaySource.open([a, b], MessageOrder.RECEIVED, stack)
        got = [(m.topic, m.log_time - START) for m in source.messages(None, None, None)]
        assert got == [("/x", 0), ("/x", 10), ("/y", 20), ("/z", 30), ("/x", 40)]
        assert source.topic_counts == {"/x": 3, "/y": 1, "/z": 1}
        assert (source.start_ns, source.end_ns) == (START, START + 40)
        window = [m.log_time - START for m in source.messages(["/x"], START + 5, START + 40)]
        assert window == [10]


def test_same_topic_two_types_names_both_bags_and_types(tmp_path: Path) -> None:
    a = write(tmp_path / "a", [("/x", 0, 0)])
    with BagWriter(tmp_path / "b") as writer:
        writer.add_topic(TopicInfo("/x", "std_msgs/msg/String"), definition="string data\n")
        writer.write("/x", b"\x00", log_time=START)
    with ExitStack() as stack, pytest.raises(PlayerError) as caught:
        PlaySource.open([a, tmp_path / "b"], MessageOrder.RECEIVED, stack)
    message = str(caught.value)
    for part in ("/x", "std_msgs/msg/Int32", "std_msgs/msg/String", str(a), str(tmp_path / "b")):
        assert part in message


def test_sent_order_times_by_publish_time_within_its_window(tmp_path: Path) -> None:
    # Received in log order, sent in another: the second was sent first.
    window = SENT_ORDER_WINDOW_NS
    rows = [("/x", 100, 50), ("/x", 110, 10), ("/x", 120, 115)]
    rows.append(("/x", window + 500, window + 400))  # releases the three above
    rows.append(("/x", window + 1_000, 5))  # delivered later than the window: out of order
    bag = write(tmp_path / "a", rows)
    with ExitStack() as stack:
        source = PlaySource.open([bag], MessageOrder.SENT, stack)
        got = [(m.data[0], m.log_time - START) for m in source.messages(None, None, None)]
    assert got == [(1, 10), (0, 50), (2, 115), (4, 5), (3, window + 400)]


def test_latched_state_is_the_latest_of_any_bag(tmp_path: Path) -> None:
    qos = {"/map": LATCHED}
    a = write(tmp_path / "a", [("/map", 0, 0), ("/x", 10, 10), ("/map", 50, 50)], qos)
    b = write(tmp_path / "b", [("/map", 30, 30), ("/x", 60, 60)], qos)
    with ExitStack() as stack:
        source = PlaySource.open([a, b], MessageOrder.RECEIVED, stack)
        state = source.latched_before(START + 40, {"/map"})
        assert [(m.topic, m.log_time - START) for m in state] == [("/map", 30)]
        assert [m.log_time - START for m in source.latched_before(START + 51, {"/map"})] == [50]
        assert source.latched_before(START, {"/map"}) == []


def test_seek_re_anchors_the_timeline_paused_or_not() -> None:
    controls = PlayControls(2.0)
    controls.start(1_000, 0)
    controls.seek(5_000, now_ns=100)
    assert controls.interrupting and controls.position() == 5_000
    assert controls.take_seek() == 5_000 and controls.take_seek() is None
    # Due at once from the seek's moment, at the rate: no jump counted as lateness.
    assert controls.timeline.deadline(5_000) == 100
    assert controls.timeline.deadline(7_000) == 1_100
    controls.pause(now_ns=100)
    controls.seek(2_000, now_ns=200)
    controls.take_seek()
    assert controls.paused and controls.position() == 2_000
    controls.resume(now_ns=300)
    assert controls.timeline.deadline(2_000) == 300


def test_burst_counts_what_the_loop_took_and_stops_at_a_pass_end() -> None:
    assert PlayControls().burst(3) == 0  # not paused
    controls = PlayControls(paused=True)

    def loop(messages: int) -> None:
        taken = 0
        deadline = time.monotonic() + 5
        while taken < messages and time.monotonic() < deadline:
            if controls.take_step(taken):
                taken += 1
            else:
                time.sleep(0.001)
        controls.end_pass()

    thread = threading.Thread(target=loop, args=(7,))
    thread.start()
    assert controls.burst(5) == 5
    assert controls.burst(0) == 2  # the rest: two were left
    thread.join()
    stopper = threading.Timer(0.2, controls.stop)
    stopper.start()
    assert controls.burst(0, timeout_s=5.0) == 0  # nobody takes; the stop ends the wait
    assert controls.stopped


def test_progress_line_says_where_how_fast_and_paused() -> None:
    progress = PlayProgress(
        bag_time_s=12.5,
        wall_time_s=6.3,
        effective_rate=1.98,
        messages=120,
        late=2,
        loop=1,
        bag_ns=START + 12_500_000_000,
        fraction=0.25,
        rate=2.0,
        paused=True,
    )
    text = progress_text(progress)
    for part in ("12.50 s", "22:13:32.500", "25.0%", "1.98x of 2", "120 msgs", "2 late", "paused"):
        assert part in text, text
    assert "loop 2" in text
    piped = io.StringIO()
    line = ProgressLine(piped, warn=lambda _: None)
    line.update(progress)
    line.finish()
    assert piped.getvalue() == ""  # not a terminal: no progress at all


def test_a_seek_is_clamped_to_the_window_with_a_warning(tmp_path: Path) -> None:
    bag = write(tmp_path / "a", [("/x", i * 10, i * 10) for i in range(10)])
    with ExitStack() as stack:
        source = PlaySource.open([bag], MessageOrder.RECEIVED, stack)
        span = WindowSpan.of(PlayWindow.create(start="20ns", duration_ns=30), source)
        assert (span.start_ns - START, span.last_ns - START) == (20, 49)
        assert span.clamp(START + 30) == (START + 30, None)
        target, warning = span.clamp(START + 500)
        assert target == START + 49 and warning is not None and "past the end" in warning
        target, warning = span.clamp(START)
        assert target == START + 20 and warning is not None and "before the start" in warning
        whole = WindowSpan.of(PlayWindow.create(), source)
        assert (whole.end_ns, whole.last_ns) == (None, START + 90)
