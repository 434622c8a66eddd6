"""The live system over real DDS: `fusion launch` in a subprocess, observed with rclpy."""

from __future__ import annotations

import itertools
import math
import os
import signal
import subprocess
import time
from collections.abc import Iterator
from pathlib import Path
from typing import Any

import pytest
import rclpy
from diagnostic_msgs.msg import DiagnosticStatus
from rclpy.context import Context
from rclpy.executors import SingleThreadedExecutor
from rclpy.node import Node

from fusion import topics
from fusion.nodes.shell import topic_qos
from fusion.processors.messages import stamp_ns

NOMINAL_HZ = {
    topics.IMU: 10.0,
    topics.GPS: 1.0,
    topics.TEMPERATURE: 2.0,
    topics.PRESSURE: 2.0,
    topics.ODOMETRY: 10.0,
    topics.BARO_ALTITUDE: 2.0,
}
COLLECT_S = 8.0


@pytest.fixture
def observer() -> Iterator[tuple[Node, SingleThreadedExecutor]]:
    context = Context()
    rclpy.init(context=context)
    node = rclpy.create_node("fusion_observer", context=context)
    executor = SingleThreadedExecutor(context=context)
    executor.add_node(node)
    try:
        yield node, executor
    finally:
        executor.shutdown()
        node.destroy_node()
        rclpy.shutdown(context=context)


def _subscribe(node: Node, topic: str, sink: list[tuple[float, Any]]) -> None:
    node.create_subscription(
        topics.TOPIC_TYPES[topic],
        topic,
        lambda msg: sink.append((time.monotonic(), msg)),
        topic_qos(topic),
    )


def _spin_until(executor: SingleThreadedExecutor, done: Any, timeout: float) -> None:
    deadline = time.monotonic() + timeout
    while not done() and time.monotonic() < deadline:
        executor.spin_once(timeout_sec=0.05)


@pytest.mark.ros
def test_launch_publishes_at_rate_raises_alerts_and_tracks_altitude(
    processes: Any, observer: tuple[Node, SingleThreadedExecutor], tmp_path: Path
) -> None:
    params = tmp_path / "params.yaml"
    params.write_text(
        'sensor_publisher:\n  ros__parameters:\n    faults: "temperature_spike@2+2"\n    seed: 3\n'
    )
    log_path = tmp_path / "launch.log"
    with log_path.open("wb") as log:
        launcher = processes.start(
            ["fusion", "launch", "--params", str(params)], stdout=log, stderr=subprocess.STDOUT
        )
    node, executor = observer
    received: dict[str, list[tuple[float, Any]]] = {
        t: [] for t in (*NOMINAL_HZ, topics.TRUTH, topics.ALERTS)
    }
    for topic, sink in received.items():
        _subscribe(node, topic, sink)

    # Discovery matches each publisher separately: start counting once every topic flows.
    _spin_until(executor, lambda: all(received[t] for t in NOMINAL_HZ), timeout=20.0)
    assert all(received[t] for t in NOMINAL_HZ), "not every topic flowing 20 s after launch"
    start = time.monotonic()
    _spin_until(executor, lambda: time.monotonic() - start > COLLECT_S, timeout=COLLECT_S + 1)

    # Rates: messages received in the steady window, and no gaps in the stamps.
    for topic, hz in NOMINAL_HZ.items():
        window = [msg for t, msg in received[topic] if t >= start]
        assert len(window) == pytest.approx(hz * COLLECT_S, rel=0.15, abs=1.5), topic
        stamps = [stamp_ns(msg.header.stamp) for _, msg in received[topic]]
        assert max(b - a for a, b in itertools.pairwise(stamps)) < 1.6e9 / hz, topic

    # The injected temperature spike shows up on /alerts as an ERROR, then clears.
    temperature_levels = [
        s.level
        for _, alerts in received[topics.ALERTS]
        for s in alerts.status
        if s.hardware_id == topics.TEMPERATURE
    ]
    assert DiagnosticStatus.ERROR in temperature_levels
    assert temperature_levels[-1] == DiagnosticStatus.OK

    # The fused altitude tracks the simulated truth better than GPS's vertical sigma (2.9 m).
    truth = {stamp_ns(m.header.stamp): m.pose.pose.position.z for _, m in received[topics.TRUTH]}
    errors = [
        m.pose.pose.position.z - truth[stamp_ns(m.header.stamp)]
        for _, m in received[topics.ODOMETRY]
        if stamp_ns(m.header.stamp) in truth
    ]
    assert len(errors) >= 0.9 * len(received[topics.ODOMETRY])
    assert math.sqrt(sum(e * e for e in errors) / len(errors)) < 2.9
    # It climbs: the flight takes off 3 s after start.
    climbs = [m.twist.twist.linear.z for _, m in received[topics.ODOMETRY][-20:]]
    assert sum(climbs) / len(climbs) > 0.5

    # A late subscriber to /alerts (transient local) gets the current state at once.
    late: list[tuple[float, Any]] = []
    _subscribe(node, topics.ALERTS, late)
    _spin_until(executor, lambda: late, timeout=5.0)
    assert late and {s.hardware_id for s in late[0][1].status} == set(topics.SENSOR_TOPICS)

    os.killpg(launcher.pid, signal.SIGINT)
    assert launcher.wait(timeout=20) == 130
    output = log_path.read_text()
    assert "Traceback" not in output
    for name in ("sensor_publisher", "data_logger", "alert_system", "sensor_fusion"):
        assert f"[{name}] " in output
    assert "/temperature: ERROR: temperature" in output
    assert "fault injected: temperature_spike" in output


@pytest.mark.ros
def test_launch_fails_when_a_node_dies(processes: Any, tmp_path: Path) -> None:
    params = tmp_path / "bad.yaml"
    params.write_text('sensor_publisher:\n  ros__parameters:\n    faults: "wind@1+1"\n')
    proc = processes.start(
        ["fusion", "launch", "--only", "sensor_publisher,data_logger", "--params", str(params)],
        stdout=subprocess.PIPE,
        stderr=subprocess.PIPE,
    )
    out, err = proc.communicate(timeout=30)
    assert proc.returncode == 1
    assert b"unknown fault kind 'wind'" in out
    assert err.decode().strip().splitlines() == ["error: node sensor_publisher exited with code 2"]


def test_cli_rejects_unknown_nodes(processes: Any) -> None:
    proc = processes.start(
        ["fusion", "launch", "--only", "camera"], stdout=subprocess.PIPE, stderr=subprocess.PIPE
    )
    out, err = proc.communicate(timeout=30)
    assert proc.returncode == 2
    assert out == b""
    assert err.decode().startswith("error: unknown node(s) camera.")
    assert len(err.decode().strip().splitlines()) == 1
