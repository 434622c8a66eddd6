"""Replay for debugging over DDS: latched state on a late start, seek, burst, stop, several bags.

Real publishers and subscriptions: a late-joining transient-local subscription must get the
state a replay carried over; the player runs in a thread of the test and is driven through
its methods (the services and keys call the same ones, tested through the CLI below).
"""

from __future__ import annotations

import json
import os
import subprocess
import threading
import time
from collections.abc import Callable, Iterator
from contextlib import contextmanager
from pathlib import Path
from typing import Any

import pytest
from rcl_interfaces.msg import Parameter as ParameterMsg
from rcl_interfaces.msg import ParameterType, ParameterValue, SetParametersResult
from rcl_interfaces.srv import SetParameters
from rclpy.executors import SingleThreadedExecutor
from rclpy.node import Node
from rclpy.qos import DurabilityPolicy, QoSProfile, ReliabilityPolicy
from rclpy.serialization import deserialize_message, serialize_message
from replay_harness import CLI_KNOWN, Listener, bagkit_cli, clock_ns, known
from rosgraph_msgs.msg import Clock
from std_msgs.msg import String
from std_srvs.srv import Trigger
from waiting import wait_for

from bagkit.bag import BagWriter, TopicInfo
from bagkit.bag.latched import LatchedOptions
from bagkit.playback.options import PlayOptions
from bagkit.playback.report import PlayReport
from bagkit.ros.qos import dump_offered_qos_profiles
from bagkit.ros.replay.player import Player
from bagkit.selection.times import NS_PER_S

pytestmark = pytest.mark.ros

START_NS = 1_700_000_000_000_000_000
DATA = "/dbg/data"  # volatile, 20 Hz for 3 s: payload "data#i" at START + i * 50 ms
STATE = "/dbg/state"  # transient-local: "state#0" at 0.1 s, "state#1" at 0.5 s
STATE_TIMES_NS = (100_000_000, 500_000_000)
PERIOD_NS = 50_000_000
LATCHED_QOS = QoSProfile(
    depth=1, reliability=ReliabilityPolicy.RELIABLE, durability=DurabilityPolicy.TRANSIENT_LOCAL
)


def text(data: bytes) -> str:
    return str(deserialize_message(data, String).data)


def write_debug_bag(path: Path) -> Path:
    with BagWriter(path) as writer:
        writer.add_topic(TopicInfo(DATA, "std_msgs/msg/String"))
        writer.add_topic(
            TopicInfo(
                STATE,
                "std_msgs/msg/String",
                offered_qos_profiles=dump_offered_qos_profiles([LATCHED_QOS]),
            )
        )
        events = [(START_NS + i * PERIOD_NS, DATA, f"data#{i}") for i in range(60)]
        events += [(START_NS + t, STATE, f"state#{i}") for i, t in enumerate(STATE_TIMES_NS)]
        for log_time, topic, payload in sorted(events):
            writer.write(topic, bytes(serialize_message(String(data=payload))), log_time=log_time)
    return path


@contextmanager
def playing(options: PlayOptions) -> Iterator[tuple[Player, list[PlayReport]]]:
    """A player entered and playing in a thread; its report lands in the list when it ends."""
    reports: list[PlayReport] = []
    with Player(options) as player:
        thread = threading.Thread(target=lambda: reports.append(player.play()), daemon=True)
        thread.start()
        try:
            yield player, reports
        finally:
            player.stop()
            thread.join(timeout=20)
            assert not thread.is_alive()


def late_state_subscriber(node: Node) -> list[str]:
    """A transient-local subscription created now: what the publisher's history gives it."""
    got: list[str] = []
    node.create_subscription(String, STATE, lambda m: got.append(m.data), LATCHED_QOS)
    return got


def spin_until(node: Node, condition: Callable[[], object], timeout: float = 10.0) -> None:
    executor = SingleThreadedExecutor(context=node.context)
    executor.add_node(node)
    deadline = time.monotonic() + timeout
    while not condition() and time.monotonic() < deadline:
        executor.spin_once(timeout_sec=0.05)
    executor.remove_node(node)
    executor.shutdown()
    assert condition(), "timed out"


def test_start_offset_first_publishes_the_latched_state(
    tmp_path: Path, listener_factory: type[Listener], node: Node
) -> None:
    bag = write_debug_bag(tmp_path / "bag")
    listener = listener_factory({DATA: String, STATE: String})
    options = PlayOptions(bag, start_offset=1.0, start_paused=True, waits=known(DATA, STATE))
    with playing(options) as (_player, reports):
        wait_for(lambda: listener.messages(STATE), 10.0, what="the latched state")
        late = late_state_subscriber(node)
        spin_until(node, lambda: late)
        assert late == ["state#1"]  # the last one before the offset, from the history
    report = reports[0]
    # Only the last state went out (state#0 was not published before it), no data yet.
    assert [text(r.data) for r in listener.messages(STATE)] == ["state#1"]
    assert not listener.messages(DATA)
    assert report.latched == 1 and report.messages == 1


def test_seek_publishes_clock_and_latched_state_then_burst_and_stop(
    tmp_path: Path, listener_factory: type[Listener], node: Node
) -> None:
    bag = write_debug_bag(tmp_path / "bag")
    listener = listener_factory({DATA: String, STATE: String, "/clock": Clock})
    options = PlayOptions(bag, start_paused=True, clock_hz=40.0, waits=known(DATA, STATE, "/clock"))
    with playing(options) as (player, reports):
        time.sleep(0.5)
        target = player.seek(1.2)  # seconds from the bag's start
        assert target == START_NS + 1_200_000_000
        wait_for(lambda: listener.messages(STATE), 10.0, what="the latched state")
        wait_for(lambda: target in [clock_ns(r.data) for r in listener.messages("/clock")])
        late = late_state_subscriber(node)
        spin_until(node, lambda: late)
        assert late == ["state#1"]
        assert player.burst(5) == 5  # paused: the next five at once
        wait_for(lambda: len(listener.messages(DATA)) == 5, 10.0, what="the burst")
        assert player.resume()
        assert player.burst(3) == 0  # not paused: nothing
        time.sleep(0.3)
        player.stop()
    report = reports[0]
    wait_for(lambda: len(listener.messages(DATA)) == report.messages - 1, 10.0)
    data = [text(r.data) for r in listener.messages(DATA)]
    first = 1_200_000_000 // PERIOD_NS
    assert data[:5] == [f"data#{i}" for i in range(first, first + 5)]
    # After the resume it went on from there, in order, and the stop ended it before the end.
    assert data == [f"data#{i}" for i in range(first, first + len(data))]
    assert 5 < len(data) < 60 - first
    assert report.messages == len(data) + 1 and report.latched == 1
    assert not report.interrupted


def test_a_seek_key_during_the_wait_for_subscribers_steps_from_the_start(
    tmp_path: Path, listener_factory: type[Listener]
) -> None:
    # A user presses "." while the player still waits for its subscribers (as a loaded
    # machine's discovery makes it do): the step is taken from where the replay will start.
    bag = write_debug_bag(tmp_path / "bag")
    with Player(PlayOptions(bag, start_paused=True, waits=known(DATA, STATE))) as player:
        target = player.seek_by(NS_PER_S)  # before play(): nobody subscribed yet
        assert target == START_NS + NS_PER_S
        listener = listener_factory({DATA: String, STATE: String})
        thread = threading.Thread(target=player.play, daemon=True)
        thread.start()
        try:
            wait_for(lambda: listener.messages(STATE), 15.0, what="the latched state")
        finally:
            player.stop()
            thread.join(timeout=20)
    assert not thread.is_alive()
    assert [text(r.data) for r in listener.messages(STATE)] == ["state#1"]
    assert listener.messages(DATA) == []  # still paused


def test_a_seek_back_while_playing_is_no_lateness_and_past_the_end_is_clamped(
    tmp_path: Path, listener_factory: type[Listener]
) -> None:
    bag = write_debug_bag(tmp_path / "bag")
    listener = listener_factory({DATA: String})
    warnings: list[str] = []
    options = PlayOptions(bag, waits=known(DATA))
    reports: list[PlayReport] = []
    with Player(options, on_warning=warnings.append) as player:
        thread = threading.Thread(target=lambda: reports.append(player.play()), daemon=True)
        thread.start()
        wait_for(lambda: len(listener.messages(DATA)) >= 30, 10.0)  # 1.5 s in
        player.seek(0.2)  # back 1.3 s: overdue if the timeline were not re-anchored
        time.sleep(0.5)
        assert player.seek(99.0) == START_NS + 59 * PERIOD_NS  # the last message
        thread.join(timeout=20)
    report = reports[0]
    assert warnings and "past the end" in warnings[0]
    data = [text(r.data) for r in listener.wait_for_count(10**6, timeout=0.5)]
    assert data[-1] == "data#59"
    assert "data#4" in data[30:]  # replayed again after the seek back
    # A jump of 1.3 s counted as lateness would show as a max of about 1300 ms.
    assert report.lateness.max_ms < 500, report.lateness


def write_bag_of(path: Path, topic: str, offset_ns: int) -> Path:
    with BagWriter(path) as writer:
        writer.add_topic(TopicInfo(topic, "std_msgs/msg/String"))
        for i in range(10):
            payload = bytes(serialize_message(String(data=f"{topic}#{i}")))
            writer.write(topic, payload, log_time=START_NS + offset_ns + i * 100_000_000)
    return path


def test_two_bags_play_as_one_timeline_with_one_clock(
    tmp_path: Path, listener_factory: type[Listener], node: Node
) -> None:
    first = write_bag_of(tmp_path / "a", "/two/a", 0)
    second = write_bag_of(tmp_path / "b", "/two/b", 50_000_000)
    listener = listener_factory({"/two/a": String, "/two/b": String, "/clock": Clock})
    result = bagkit_cli(
        "play",
        str(first),
        "-i",
        str(second),
        "--rate",
        "2",
        "--clock",
        "--format",
        "json",
        *CLI_KNOWN,
        *("--wait-for", "/two/a", "--wait-for", "/two/b", "--wait-for", "/clock"),
    )
    assert result.returncode == 0, result.stderr
    got = [r for r in listener.wait_for_count(20) if r.topic != "/clock"]
    # Interleaved by log time: a#0 b#0 a#1 b#1 ...
    assert [text(r.data) for r in got] == [
        f"/two/{side}#{i}" for i in range(10) for side in ("a", "b")
    ]
    stamps = [clock_ns(r.data) for r in listener.messages("/clock")]
    assert stamps == sorted(stamps) and stamps[0] == START_NS  # one clock, never back
    report = json.loads(result.stdout)
    assert report["messages"] == 20
    assert {t["topic"]: t["messages"] for t in report["topics"]} == {"/two/a": 10, "/two/b": 10}


def test_a_topic_with_two_types_in_two_bags_is_one_error(tmp_path: Path) -> None:
    first = write_bag_of(tmp_path / "a", "/same", 0)
    with BagWriter(tmp_path / "b") as writer:
        writer.add_topic(TopicInfo("/same", "std_msgs/msg/Int32"), definition="int32 data\n")
        writer.write("/same", b"\x00\x01\x00\x00\x07\x00\x00\x00", log_time=START_NS)
    result = bagkit_cli("play", str(first), str(tmp_path / "b"), "--no-wait-for-subscribers")
    assert result.returncode == 2
    assert result.stderr.count("\n") == 1, result.stderr
    assert "std_msgs/msg/String" in result.stderr and "std_msgs/msg/Int32" in result.stderr
    assert str(first) in result.stderr and str(tmp_path / "b") in result.stderr


def test_seek_keys_through_a_terminal(
    tmp_path: Path, listener_factory: type[Listener], processes: Any
) -> None:
    bag = write_debug_bag(tmp_path / "bag")
    listener = listener_factory({DATA: String, STATE: String})
    controller, terminal = os.openpty()
    proc = processes.start(
        [
            *("bagkit", "play", str(bag), "--start-paused", "--seek-step", "1", *CLI_KNOWN),
            *("--wait-for", DATA, "--wait-for", STATE, "--format", "json"),
        ],
        stdin=terminal,
        stdout=subprocess.PIPE,
        stderr=subprocess.PIPE,
    )
    os.close(terminal)
    try:
        # The player's node exists: its keys are read a moment later.
        wait_for(lambda: listener.node.count_publishers(DATA) > 0, 20.0, what="the player")
        time.sleep(1.0)
        os.write(controller, b".")  # forward a step: 1 s
        wait_for(lambda: listener.messages(STATE), 15.0, what="the latched state")
        os.write(controller, b"\x1b[C")  # the next message
        wait_for(lambda: listener.messages(DATA), 15.0)
        os.write(controller, b"\x1b[D")  # back a step from the stepped message: 0 s
        time.sleep(0.5)
        os.write(controller, b"\x1b[C")
        wait_for(lambda: len(listener.messages(DATA)) == 2, 15.0)
        os.write(controller, b" ")  # play the rest
        stdout, stderr = proc.communicate(timeout=30)
    finally:
        os.close(controller)
    assert proc.returncode == 0, stderr
    data = [text(r.data) for r in listener.messages(DATA)]
    assert data[:3] == ["data#20", "data#0", "data#1"]
    assert text(listener.messages(STATE)[0].data) == "state#1"
    assert json.loads(stdout)["latched"] == 1


def test_each_loop_pass_starts_with_the_latched_state(
    tmp_path: Path, listener_factory: type[Listener]
) -> None:
    bag = write_debug_bag(tmp_path / "bag")
    listener = listener_factory({DATA: String, STATE: String})
    report = Player(
        PlayOptions(bag, start_offset=2.5, loops=2, rate=2.0, waits=known(DATA, STATE))
    ).run()
    wait_for(lambda: len(listener.messages()) == report.messages, 10.0)
    assert [text(r.data) for r in listener.messages(STATE)] == ["state#1", "state#1"]
    assert [text(r.data) for r in listener.messages(DATA)] == [
        f"data#{i}" for i in range(50, 60)
    ] * 2
    assert (report.loops, report.latched, report.messages) == (2, 2, 22)


@pytest.mark.parametrize(
    ("latched", "extra", "expected"),
    [(False, (), []), (True, (DATA,), [(DATA, "data#19"), (STATE, "state#1")])],
)
def test_no_latched_and_latched_topics(
    tmp_path: Path,
    listener_factory: type[Listener],
    latched: bool,
    extra: tuple[str, ...],
    expected: list[tuple[str, str]],
) -> None:
    bag = write_debug_bag(tmp_path / "bag")
    listener = listener_factory({DATA: String, STATE: String})
    options = PlayOptions(
        bag,
        start_offset=1.0,
        duration_ns=10_000_000,  # the window holds data#20 only
        latched=LatchedOptions(enabled=latched, extra_topics=extra),
        waits=known(DATA, STATE),
    )
    report = Player(options).run()
    wait_for(lambda: len(listener.messages()) == report.messages, 10.0)
    got = [(r.topic, text(r.data)) for r in listener.messages()]
    assert sorted(got[:-1]) == expected  # the latched state first, then the window
    assert got[-1] == (DATA, "data#20")
    assert report.latched == len(expected)


def _call(node: Node, client: Any, request: Any) -> Any:
    future = client.call_async(request)
    executor = SingleThreadedExecutor(context=node.context)
    executor.add_node(node)
    executor.spin_until_future_complete(future, timeout_sec=30.0)
    executor.remove_node(node)
    executor.shutdown()
    assert future.done(), "no answer"
    return future.result()


def _set(node: Node, client: Any, name: str, value: ParameterValue) -> SetParametersResult:
    request = SetParameters.Request()
    request.parameters = [ParameterMsg(name=name, value=value)]
    return _call(node, client, request).results[0]


def test_seek_and_burst_parameters_play_and_stop_services(
    tmp_path: Path, listener_factory: type[Listener], processes: Any, node: Node
) -> None:
    bag = write_debug_bag(tmp_path / "bag")
    listener = listener_factory({DATA: String, STATE: String})
    proc = processes.start(
        [
            *("bagkit", "play", str(bag), "--start-paused", "--disable-keyboard-controls"),
            *(*CLI_KNOWN, "--wait-for", DATA, "--wait-for", STATE, "--format", "json"),
        ],
        stdout=subprocess.PIPE,
        stderr=subprocess.PIPE,
        text=True,
    )
    parameters = node.create_client(SetParameters, "/bagkit_player/set_parameters")
    play = node.create_client(Trigger, "/bagkit_player/play")
    stop = node.create_client(Trigger, "/bagkit_player/stop")
    for client in (parameters, play, stop):
        assert client.wait_for_service(timeout_sec=20.0)
    text_value = ParameterValue(type=ParameterType.PARAMETER_STRING, string_value="soon")
    refused = _set(node, parameters, "seek", text_value)
    assert not refused.successful and "soon" in refused.reason
    before = ParameterValue(type=ParameterType.PARAMETER_STRING, string_value="-1m")
    assert _set(node, parameters, "seek", before).successful  # clamped to the first message
    seconds = ParameterValue(type=ParameterType.PARAMETER_DOUBLE, double_value=1.0)
    assert _set(node, parameters, "seek", seconds).successful
    wait_for(lambda: listener.messages(STATE), 15.0, what="the latched state")
    three = ParameterValue(type=ParameterType.PARAMETER_INTEGER, integer_value=3)
    burst = _set(node, parameters, "burst", three)
    assert burst.successful, burst.reason
    wait_for(lambda: len(listener.messages(DATA)) == 3, 15.0)
    assert _call(node, play, Trigger.Request()).success
    assert not _call(node, play, Trigger.Request()).success  # playing already
    refused = _set(node, parameters, "burst", three)
    assert not refused.successful and "published 0 of 3" in refused.reason
    assert _call(node, stop, Trigger.Request()).success
    stdout, stderr = proc.communicate(timeout=30)
    assert proc.returncode == 0, stderr
    assert "before the start" in stderr and stderr.count("warning:") == 1, stderr
    data = [text(r.data) for r in listener.messages(DATA)]
    assert data[:3] == ["data#20", "data#21", "data#22"]
    assert data == [f"data#{i}" for i in range(20, 20 + len(data))]
    assert len(data) < 40  # stopped before the end
    assert json.loads(stdout)["messages"] == len(data) + 1
