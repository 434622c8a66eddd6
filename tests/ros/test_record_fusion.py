"""``bagkit record -a`` on the live fusion system (``fusion launch``), read back three ways."""

from __future__ import annotations

import subprocess
import time
from collections.abc import Callable
from pathlib import Path
from typing import Any

import pytest
from mcap.reader import make_reader
from mcap_ros2.decoder import DecoderFactory
from rosbags.highlevel import AnyReader
from test_record_cli import report_json

from bagkit.bag import BagReader
from bagkit.ros.message_classes import message_type_name
from fusion import topics

pytestmark = pytest.mark.ros

# DDS discovery of a node started by another process can take up to ~3 s here (the periodic
# participant announcement), and the transient-local /alerts sample is only delivered once matched.
RECORD_S = 8.0
# The spike starts once the alert system has surely discovered the sensor publisher and lasts
# long enough to pass the alert debounce; the recording starts only after the alert was raised.
SPIKE = "temperature_spike@4+3"
ALERT_RAISED = "[alert_system] [ERROR]"
ALERT_TIMEOUT_S = 30.0
NOMINAL_HZ = {topics.IMU: 10.0, topics.GPS: 1.0, topics.TEMPERATURE: 2.0, topics.PRESSURE: 2.0}


def wait_for_line(log: Path, text: str, *, timeout: float, is_alive: Callable[[], bool]) -> None:
    """Wait until ``text`` appears in the growing file ``log``."""
    deadline = time.monotonic() + timeout
    while text not in log.read_text(errors="replace"):
        assert is_alive(), f"launch exited before {text!r}:\n{log.read_text(errors='replace')}"
        assert time.monotonic() < deadline, f"no {text!r} within {timeout} s"
        time.sleep(0.1)


def test_record_live_fusion_system(processes: object, tmp_path: Path) -> None:
    bag, report = _record_while_alerting(processes, tmp_path)
    recorded = {t["topic"]: t for t in report["topics"] if t["messages"]}
    _check_report(report, recorded)
    _check_bag_counts_and_sequences(bag, report, recorded)
    _check_rosbags_reads_fused_outputs(bag, recorded)
    _check_mcap_ros2_decodes_everything(bag, recorded)


def _record_while_alerting(processes: object, tmp_path: Path) -> tuple[Path, dict[str, Any]]:
    """``fusion launch`` with a temperature spike; ``bagkit record -a`` once the alert is up."""
    params = tmp_path / "params.yaml"
    # The alert fires before the recording starts: /alerts (transient local) must still be in it.
    params.write_text(f'sensor_publisher:\n  ros__parameters:\n    faults: "{SPIKE}"\n')
    log_path = tmp_path / "launch.log"
    with log_path.open("wb") as log:
        launcher = processes.start(  # type: ignore[attr-defined]
            ["fusion", "launch", "--params", str(params)], stdout=log, stderr=subprocess.STDOUT
        )
    wait_for_line(
        log_path, ALERT_RAISED, timeout=ALERT_TIMEOUT_S, is_alive=lambda: launcher.poll() is None
    )
    bag = tmp_path / "fusion"
    recorder = processes.start(  # type: ignore[attr-defined]
        ["bagkit", "record", "-a", "-o", str(bag), "--duration", str(RECORD_S), "--format", "json"],
        stdout=subprocess.PIPE,
        stderr=subprocess.PIPE,
    )
    stdout, stderr = recorder.communicate(timeout=60)
    assert recorder.returncode == 0, stderr.decode()
    return bag, report_json(stdout)


def _check_report(report: dict[str, Any], recorded: dict[str, Any]) -> None:
    """Every topic of the system, nothing lost, one publisher each, nominal rates.

    Topics are discovered at different times (DDS discovery of each node's participant), so
    each is checked from its first message on.
    """
    assert set(topics.TOPIC_TYPES) - {topics.LOGGER_SUMMARY} <= set(recorded)
    assert report["lost"] == 0
    for name in topics.TOPIC_TYPES:
        if name in recorded:
            assert recorded[name]["publishers"] == 1, name
            assert recorded[name]["type"] == message_type_name(topics.TOPIC_TYPES[name])
    for name, nominal in NOMINAL_HZ.items():
        if recorded[name]["messages"] >= 4:
            assert abs(recorded[name]["rate_hz"] - nominal) <= 0.2 * nominal, recorded[name]


def _check_bag_counts_and_sequences(
    bag: Path, report: dict[str, Any], recorded: dict[str, Any]
) -> None:
    """The bag holds exactly the report's messages; each fusion topic (one publisher) has
    contiguous sequence numbers (/parameter_events and /rosout have one publisher per node)."""
    with BagReader(bag) as reader:
        assert reader.problems == []
        assert reader.topic_counts == {t["topic"]: t["messages"] for t in report["topics"]}
        sequences: dict[str, list[int]] = {}
        for message in reader.messages():
            sequences.setdefault(message.topic, []).append(message.sequence)
    for name in recorded.keys() & topics.TOPIC_TYPES.keys():
        numbers = sequences[name]
        assert numbers == list(range(numbers[0], numbers[0] + len(numbers))), name


def _check_rosbags_reads_fused_outputs(bag: Path, recorded: dict[str, Any]) -> None:
    """rosbags deserializes everything; the fusion output follows its inputs one to one."""
    stamps: dict[str, list[int]] = {}
    with AnyReader([bag]) as any_reader:
        for connection, _timestamp, raw in any_reader.messages():
            message = any_reader.deserialize(raw, connection.msgtype)
            # /rosout and /parameter_events carry their stamp outside a header.
            stamp = getattr(message, "header", message).stamp
            stamps.setdefault(connection.topic, []).append(stamp.sec * 10**9 + stamp.nanosec)
    # One fused output per input sample, stamped like it (the last may still be in flight).
    for source, output in ((topics.IMU, topics.ODOMETRY), (topics.PRESSURE, topics.BARO_ALTITUDE)):
        assert stamps[source] == sorted(stamps[source])
        # From when both topics were being recorded.
        start = max(stamps[source][0], stamps[output][0])
        inputs = [t for t in stamps[source] if t >= start]
        outputs = [t for t in stamps[output] if t >= start]
        assert set(outputs) <= set(inputs), output
        assert len(inputs) - 2 <= len(outputs) <= len(inputs), output
    assert all(len(stamps[name]) == recorded[name]["messages"] for name in recorded)


def _check_mcap_ros2_decodes_everything(bag: Path, recorded: dict[str, Any]) -> None:
    decoded: dict[str, int] = {}
    for mcap_file in sorted(bag.glob("*.mcap")):
        with mcap_file.open("rb") as stream:
            for _schema, channel, _message, _ros in make_reader(
                stream, decoder_factories=[DecoderFactory()]
            ).iter_decoded_messages():
                decoded[channel.topic] = decoded.get(channel.topic, 0) + 1
    assert decoded == {name: t["messages"] for name, t in recorded.items()}
