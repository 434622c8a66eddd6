"""Replay controls over DDS: keys through a pseudo-terminal, the services, Ctrl-Z; warnings.

Every test runs the real ``bagkit play`` in a subprocess and receives with a real subscriber
(``tests/ros/replay_harness.py``'s listener, which keeps the middleware's reception timestamps).
"""

from __future__ import annotations

import itertools
import json
import os
import signal
import statistics
import subprocess
import time
from collections.abc import Callable
from pathlib import Path
from typing import Any

from rcl_interfaces.msg import Parameter as ParameterMsg
from rcl_interfaces.msg import ParameterType, ParameterValue
from rcl_interfaces.srv import SetParameters
from rclpy.executors import SingleThreadedExecutor
from rclpy.node import Node
from rclpy.serialization import serialize_message
from replay_harness import Listener, Received
from std_msgs.msg import String
from std_srvs.srv import Trigger
from waiting import wait_for

from bagkit.bag import BagWriter, TopicInfo

TOPIC = "/ctl/data"
START_NS = 1_700_000_000_000_000_000
PLAYER = "/bagkit_player"


def write_bag(path: Path, hz: float, seconds: float) -> Path:
    """One String topic at ``hz``; payload ``#index``."""
    period = int(1e9 / hz)
    with BagWriter(path) as writer:
        writer.add_topic(TopicInfo(TOPIC, "std_msgs/msg/String"))
        for index in range(int(seconds * hz)):
            data = bytes(serialize_message(String(data=f"#{index}")))
            writer.write(TOPIC, data, log_time=START_NS + index * period)
    return path


def indices(received: list[Received]) -> list[int]:
    return [int(r.text.lstrip("#")) for r in received]


def assert_follows_the_bag_spacing(received: list[Received], period_ns: int) -> None:
    """Inter-arrival times follow the bag's: no burst after a resume or a step.

    Received in this process, so a loaded machine widens them; a burst would put the median
    error near a whole period (50 ms), far above these bounds.
    """
    gaps = [b.received_ns - a.received_ns for a, b in itertools.pairwise(received)]
    errors_ms = sorted(abs(gap - period_ns) / 1e6 for gap in gaps)
    assert statistics.median(errors_ms) < 0.1 * period_ns / 1e6, errors_ms
    assert errors_ms[int(0.9 * len(errors_ms))] < 0.4 * period_ns / 1e6, errors_ms
    assert errors_ms[-1] < 150.0, errors_ms


def received_rate_hz(listener: Listener, seconds: float = 1.0) -> float:
    """Messages per second received over about ``seconds``, by the window actually slept: on a
    loaded machine ``sleep`` returns late, and a fixed count would then count the extra time."""
    start_ns = time.time_ns()
    time.sleep(seconds)
    end_ns = time.time_ns()
    count = sum(start_ns <= r.received_ns < end_ns for r in listener.messages())
    return count / ((end_ns - start_ns) / 1e9)


def play_args(bag: Path, *extra: str) -> list[str]:
    return ["bagkit", "play", str(bag), "--discovery-time", "0", "--wait-for", TOPIC, *extra]


def check_pause_step_resume(
    listener: Listener,
    toggle: Callable[[], None],
    step: Callable[[], None],
    period_ns: int,
) -> None:
    """Pause after a few messages, step twice, resume; check each phase from what arrived."""
    wait_for(lambda: len(listener.messages()) >= 5, 15.0)
    toggle()
    time.sleep(0.3)  # in flight when paused
    paused_count = len(listener.messages())
    time.sleep(1.0)
    assert len(listener.messages()) == paused_count, "published while paused"
    for stepped in (paused_count + 1, paused_count + 2):
        step()
        wait_for(lambda count=stepped: len(listener.messages()) == count, 15.0)
        time.sleep(0.3)
        assert len(listener.messages()) == stepped, "a step published more than one"
    paused_count += 2
    resumed_ns = time.time_ns()
    toggle()
    wait_for(lambda: len(listener.messages()) >= paused_count + 20, 15.0)
    got = listener.messages()
    assert indices(got) == list(range(len(got))), "every message once, in order"
    after = got[paused_count:]
    # No burst: the first message after the resume is due one bag period after it.
    first_delay_ms = (after[0].received_ns - resumed_ns) / 1e6
    assert period_ns / 1e6 - 10.0 < first_delay_ms < period_ns / 1e6 + 150.0, first_delay_ms
    assert_follows_the_bag_spacing(after, period_ns)


def test_keys_in_a_terminal_pause_step_and_resume(
    tmp_path: Path, listener_factory: type[Listener], processes: Any
) -> None:
    bag = write_bag(tmp_path / "bag", hz=20, seconds=10)
    listener = listener_factory({TOPIC: String})
    controller, terminal = os.openpty()
    proc = processes.start(
        play_args(bag), stdin=terminal, stdout=subprocess.PIPE, stderr=subprocess.PIPE
    )
    os.close(terminal)
    try:
        check_pause_step_resume(
            listener,
            toggle=lambda: os.write(controller, b" "),
            step=lambda: os.write(controller, b"\x1b[C"),
            period_ns=50_000_000,
        )
        os.write(controller, b"\x1b[A" * 10)  # up x10: rate 2
        time.sleep(0.5)
        assert 30 <= received_rate_hz(listener) <= 50  # 40 messages/s at rate 2
    finally:
        os.close(controller)
    _, stderr = proc.communicate(timeout=30)
    assert proc.returncode == 0, stderr
    assert len(listener.messages()) == 200


def _call(node: Node, client: Any, request: Any) -> Any:
    future = client.call_async(request)
    executor = SingleThreadedExecutor(context=node.context)
    executor.add_node(node)
    executor.spin_until_future_complete(future, timeout_sec=10.0)
    executor.remove_node(node)
    executor.shutdown()
    assert future.done(), "no answer"
    return future.result()


def test_services_pause_step_resume_and_set_the_rate(
    tmp_path: Path, listener_factory: type[Listener], processes: Any, node: Node
) -> None:
    bag = write_bag(tmp_path / "bag", hz=20, seconds=10)
    listener = listener_factory({TOPIC: String})
    proc = processes.start(
        play_args(bag, "--disable-keyboard-controls", "--format", "json"),
        stdout=subprocess.PIPE,
        stderr=subprocess.PIPE,
    )
    clients = {
        name: node.create_client(Trigger, f"{PLAYER}/{name}")
        for name in ("toggle_paused", "play_next", "is_paused", "get_rate", "pause", "resume")
    }
    for client in clients.values():
        assert client.wait_for_service(timeout_sec=15.0)
    answers: list[Trigger.Response] = []

    def toggle() -> None:
        answers.append(_call(node, clients["toggle_paused"], Trigger.Request()))
        answers.append(_call(node, clients["is_paused"], Trigger.Request()))

    def step() -> None:
        answer = _call(node, clients["play_next"], Trigger.Request())
        assert (answer.success, answer.message) == (True, "published the next message")

    check_pause_step_resume(listener, toggle, step, period_ns=50_000_000)
    assert [(a.success, a.message) for a in answers] == [
        (True, "paused"),
        (True, "paused"),
        (True, "playing"),
        (False, "playing"),
    ]
    refused = _call(node, clients["play_next"], Trigger.Request())  # not paused
    assert (refused.success, refused.message) == (False, "not paused, or no message left")
    # Every answer says what happened, a refusal too.
    for name, done, message in (
        ("resume", False, "was not paused"),
        ("pause", True, "paused"),
        ("pause", False, "was paused already"),
        ("resume", True, "resumed"),
    ):
        reply = _call(node, clients[name], Trigger.Request())
        assert (reply.success, reply.message) == (done, message), name

    set_parameters = node.create_client(SetParameters, f"{PLAYER}/set_parameters")
    assert set_parameters.wait_for_service(timeout_sec=10.0)

    def set_rate(value: float) -> bool:
        request = SetParameters.Request()
        request.parameters = [
            ParameterMsg(
                name="rate",
                value=ParameterValue(type=ParameterType.PARAMETER_DOUBLE, double_value=value),
            )
        ]
        return bool(_call(node, set_parameters, request).results[0].successful)

    assert not set_rate(-1.0)
    assert set_rate(2.0)
    assert _call(node, clients["get_rate"], Trigger.Request()).message == "2"
    time.sleep(0.3)
    assert 30 <= received_rate_hz(listener) <= 50  # 40 messages/s at rate 2
    stdout, stderr = proc.communicate(timeout=30)
    assert proc.returncode == 0, stderr
    assert indices(listener.messages()) == list(range(200))
    report = json.loads(stdout)
    assert report["rate"] == 2.0  # the rate in force, not the one started with
    # The pauses are told apart from the time played.
    assert report["paused_s"] > 0
    assert report["played_s"] == report["wall_duration_s"] - report["paused_s"]


def _stopped(pid: int) -> bool:
    stat = Path(f"/proc/{pid}/stat").read_text()
    return stat.rsplit(")", 1)[1].split()[0] == "T"


def test_ctrl_z_then_fg_does_not_burst(
    tmp_path: Path, listener_factory: type[Listener], processes: Any
) -> None:
    # 50 messages before the stop, 50 after it, and as many again for a stop that comes late.
    hz, seconds = 100.0, 3
    bag = write_bag(tmp_path / "bag", hz=hz, seconds=seconds)
    listener = listener_factory({TOPIC: String})
    proc = processes.start(play_args(bag), stdout=subprocess.PIPE, stderr=subprocess.PIPE)
    wait_for(lambda: len(listener.messages()) >= 50, 15.0)
    os.kill(proc.pid, signal.SIGTSTP)
    wait_for(lambda: _stopped(proc.pid), timeout=5.0)
    time.sleep(0.2)
    stopped_count = len(listener.messages())
    time.sleep(1.0)  # 100 messages fall due meanwhile
    assert len(listener.messages()) == stopped_count
    continued_ns = time.time_ns()
    os.kill(proc.pid, signal.SIGCONT)
    wait_for(lambda: len(listener.messages()) >= stopped_count + 50, 15.0)
    burst = [r for r in listener.messages() if 0 <= r.received_ns - continued_ns <= 50_000_000]
    assert len(burst) <= 0.05 * hz + 2, len(burst)  # the bag's rate, not a backlog
    _, stderr = proc.communicate(timeout=30)
    assert proc.returncode == 0, stderr
    assert indices(listener.messages()) == list(range(int(hz * seconds)))


def test_remap_stays_out_of_rcl_and_live_publishers_are_named(
    tmp_path: Path, listener_factory: type[Listener], processes: Any, node: Node
) -> None:
    bag = write_bag(tmp_path / "bag", hz=50, seconds=0.5)
    with BagWriter(tmp_path / "two") as writer:  # a second topic that nobody else publishes
        for topic in (TOPIC, "/ctl/other"):
            writer.add_topic(TopicInfo(topic, "std_msgs/msg/String"))
            writer.write(topic, bytes(serialize_message(String(data="#0"))), log_time=START_NS)
    live = node.create_publisher(String, "/ctl/live", 10)
    listener = listener_factory({"/ctl/renamed": String})
    remap = ["--remap", f"{TOPIC}:=/ctl/renamed"]
    first = processes.start(
        ["bagkit", "play", str(bag), "--discovery-time", "0", "--wait-for", "/ctl/renamed", *remap],
        stdout=subprocess.PIPE,
        stderr=subprocess.PIPE,
        text=True,
    )
    _, stderr = first.communicate(timeout=60)
    assert first.returncode == 0, stderr
    assert len(listener.wait_for_count(25)) == 25
    assert "remap" not in stderr.lower() and "deprecated" not in stderr
    assert "warning" not in stderr.lower(), stderr  # nobody else publishes /ctl/renamed

    # The node publishes /ctl/live; the bag's TOPIC is remapped onto it: one warning.
    assert live.topic_name == "/ctl/live"
    proc = processes.start(
        ["bagkit", "play", str(tmp_path / "two"), "--remap", f"{TOPIC}:=/ctl/live"],
        stdout=subprocess.PIPE,
        stderr=subprocess.PIPE,
        text=True,
    )
    _, stderr = proc.communicate(timeout=60)
    assert proc.returncode == 0, stderr
    warnings = [line for line in stderr.splitlines() if "also published" in line]
    assert len(warnings) == 1, stderr
    assert "/ctl/live" in warnings[0] and "test_replay_controls_node" in warnings[0]
    assert "/ctl/other" not in warnings[0]
