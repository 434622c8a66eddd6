"""Snapshot mode over real DDS: data, service and overlapping triggers; latched state at start."""

from __future__ import annotations

import os
import pty
import signal
import subprocess
import time
from pathlib import Path
from typing import Any

import pytest
from diagnostic_msgs.msg import DiagnosticArray, DiagnosticStatus
from mcap.reader import make_reader
from rclpy.executors import SingleThreadedExecutor
from rclpy.node import Node
from rclpy.qos import DurabilityPolicy, QoSProfile
from rosbags.highlevel import AnyReader
from sensor_msgs.msg import Imu
from std_msgs.msg import String
from std_srvs.srv import Trigger
from test_record_cli import report_json
from waiting import wait_for, wait_matched

from bagkit.bag import BagReader
from bagkit.recording.options import FileOptions, RecordOptions, SnapshotOptions, SnapshotTrigger
from bagkit.ros.errors import RecorderOptionsError
from bagkit.ros.record.recorder import Recorder

pytestmark = pytest.mark.ros

S = 1_000_000_000
LATCHED = QoSProfile(depth=1, durability=DurabilityPolicy.TRANSIENT_LOCAL)


def alert(level: bytes) -> DiagnosticArray:
    return DiagnosticArray(status=[DiagnosticStatus(level=level, name="fault", message="x")])


class Scene:
    """Publishers of the tests: an Imu stream, an alert topic, a latched state topic."""

    def __init__(self, node: Node) -> None:
        self.imu = node.create_publisher(Imu, "/snap/imu", 1000)
        self.alerts = node.create_publisher(DiagnosticArray, "/snap/alerts", LATCHED)
        self.state = node.create_publisher(String, "/snap/state", LATCHED)
        self.sent = 0

    def stream(self, seconds: float, rate_hz: float = 200.0) -> None:
        end = time.monotonic() + seconds
        while time.monotonic() < end:
            msg = Imu()
            msg.header.stamp.sec = self.sent
            self.imu.publish(msg)
            self.sent += 1
            time.sleep(1 / rate_hz)


def options(
    bag: Path, *, triggers: tuple[str, ...] = (), node_name: str = "bagkit_recorder", **bounds: Any
) -> RecordOptions:
    """Snapshot mode on /snap/*: ``bounds`` are :class:`SnapshotOptions`' fields."""
    snapshot = SnapshotOptions(triggers=tuple(SnapshotTrigger.parse(t) for t in triggers), **bounds)
    return RecordOptions(bag, regex="^/snap/", node_name=node_name, snapshot=snapshot)


def read_snapshot(path: Path) -> dict[str, list[tuple[int, Any]]]:
    """(log time, message) per topic, read with rosbags; mcap reads the same count."""
    by_topic: dict[str, list[tuple[int, Any]]] = {}
    with AnyReader([path]) as reader:
        for connection, log_time, raw in reader.messages():
            message = reader.deserialize(raw, connection.msgtype)
            by_topic.setdefault(connection.topic, []).append((log_time, message))
    count = 0
    for mcap_file in path.glob("*.mcap"):
        with mcap_file.open("rb") as stream:
            count += sum(1 for _ in make_reader(stream).iter_messages())
    assert count == sum(map(len, by_topic.values()))
    return by_topic


def test_data_trigger_writes_the_window_with_the_latched_state_first(
    node: Node, tmp_path: Path
) -> None:
    scene = Scene(node)
    scene.state.publish(String(data="state 0"))
    out = tmp_path / "blackbox"
    opts = options(
        out,
        max_duration_ns=S,
        triggers=("/snap/alerts: status[*].level >= 2",),
        post_ns=S // 2,
    )
    with Recorder(opts) as recorder:
        wait_matched(scene.imu, scene.alerts, scene.state)
        scene.stream(1.5)
        scene.alerts.publish(alert(DiagnosticStatus.WARN))  # below the condition
        scene.stream(0.2)
        scene.state.publish(String(data="state 1"))
        scene.stream(1.3)  # "state 1" is evicted by now: > 1 s before the trigger
        scene.alerts.publish(alert(DiagnosticStatus.ERROR))
        scene.stream(1.0)
        wait_for(lambda: recorder.progress().messages >= scene.sent + 3)
    report = recorder.report
    assert report.error is None and report.lost == 0
    assert report.snapshots is not None
    (snapshot,) = report.snapshots
    assert snapshot.path == out / "snapshot_0"
    assert snapshot.trigger == "/snap/alerts: status[*].level >= 2"
    assert (snapshot.path / "metadata.yaml").is_file()
    taken = report.topic("/snap/imu").messages
    assert taken == scene.sent
    by_topic = read_snapshot(snapshot.path)
    imu_times = [t for t, _ in by_topic["/snap/imu"]]
    # The window: 1 s before the trigger (the buffer's bound) to 0.5 s after it.
    assert snapshot.start_ns >= snapshot.trigger_ns - S
    assert snapshot.end_ns == snapshot.trigger_ns + S // 2
    assert snapshot.start_ns <= imu_times[0] <= snapshot.start_ns + 50_000_000
    assert snapshot.end_ns - 50_000_000 <= imu_times[-1] <= snapshot.end_ns
    assert len(imu_times) == snapshot.messages["/snap/imu"]
    # Every Imu taken in the window is there, none twice: stamps are consecutive.
    stamps = [m.header.stamp.sec for _, m in by_topic["/snap/imu"]]
    assert stamps == list(range(stamps[0], stamps[0] + len(stamps)))
    # The latched state before the window, copied at its start; the alert that triggered.
    assert [(t, m.data) for t, m in by_topic["/snap/state"]] == [(snapshot.start_ns, "state 1")]
    assert snapshot.latched == 1 + 1  # the state and the WARN alert (latched too)
    alerts = [m.status[0].level for _, m in by_topic["/snap/alerts"]]
    assert alerts == [ord(DiagnosticStatus.WARN), ord(DiagnosticStatus.ERROR)]
    # Exact accounting: every Imu taken is evicted or still in memory at the end.
    assert report.evicted["/snap/imu"] > 0
    with BagReader(snapshot.path) as reader:
        assert reader.topic_counts["/snap/imu"] == len(imu_times)


def test_service_and_overlapping_triggers(node: Node, tmp_path: Path) -> None:
    scene = Scene(node)
    out = tmp_path / "service"
    client = node.create_client(Trigger, "/snap_recorder/snapshot")
    with Recorder(
        options(out, node_name="snap_recorder", max_bytes=1 << 20, post_ns=6 * S // 10)
    ) as recorder:
        wait_matched(scene.imu)
        assert client.wait_for_service(timeout_sec=10)
        scene.stream(0.5)
        first = recorder.snapshot("request")
        scene.stream(0.3)
        second = client.call_async(Trigger.Request())  # inside the window: extends it
        _spin_until(node, second)
        scene.stream(1.2)
        third = client.call_async(Trigger.Request())  # after it: a second snapshot
        _spin_until(node, third)
        scene.stream(0.8)
    response = second.result()
    assert response.success and "snapshot_0" in response.message
    report = recorder.report
    assert report.error is None and report.snapshots is not None
    assert [s.path.name for s in report.snapshots] == ["snapshot_0", "snapshot_1"]
    assert report.snapshots[0] is first
    assert first.triggers == 2
    assert first.end_ns - first.trigger_ns > 0.8 * S  # extended past the first 0.6 s
    assert report.snapshots[1].trigger == "service"
    for snapshot in report.snapshots:
        with BagReader(snapshot.path) as reader:
            assert reader.topic_counts["/snap/imu"] == snapshot.messages["/snap/imu"] > 0


def _spin_until(node: Node, future: Any) -> None:
    executor = SingleThreadedExecutor(context=node.context)
    executor.add_node(node)
    try:
        executor.spin_until_future_complete(future, timeout_sec=10)
    finally:
        executor.remove_node(node)
        executor.shutdown()
    assert future.done()


def test_trigger_on_a_missing_field_is_refused_before_recording(node: Node, tmp_path: Path) -> None:
    scene = Scene(node)  # /snap/alerts has a publisher: its type is known at the start
    out = tmp_path / "bad"
    recorder = Recorder(
        options(out, max_duration_ns=S, triggers=("/snap/alerts: status[*].levle >= 2",))
    )
    try:
        recorder.start()
    except RecorderOptionsError as exc:
        assert "levle" in str(exc)
        assert not out.exists()
        return
    # Discovery took longer than the start's check (1 s, a loaded machine): the field is
    # checked when the topic's first message arrives, and the recording stops as bad input.
    try:
        scene.alerts.publish(DiagnosticArray())
        assert recorder.stopped.wait(30.0), "the recording went on"
    finally:
        report = recorder.stop()
    assert report.error is not None and "levle" in report.error
    assert report.error_exit_code == 2


def test_every_split_file_starts_with_the_latched_state(node: Node, tmp_path: Path) -> None:
    scene = Scene(node)
    scene.state.publish(String(data="state 0"))
    bag = tmp_path / "split"
    opts = RecordOptions(
        bag,
        regex="^/snap/",
        files=FileOptions(max_bag_duration_ns=S // 2),
        repeat_all_transient_local=True,
    )
    with Recorder(opts) as recorder:
        wait_matched(scene.imu, scene.state)
        scene.stream(0.8)
        scene.state.publish(String(data="state 1"))
        scene.stream(1.0)
        wait_for(lambda: recorder.progress().messages >= scene.sent + 2)
    assert recorder.report.lost == 0
    files = sorted(bag.glob("*.mcap"), key=lambda p: int(p.stem.rsplit("_", 1)[1]))
    assert len(files) >= 3
    states_seen = []
    for index, path in enumerate(files):
        with path.open("rb") as stream:
            messages = [
                (channel.topic, message.log_time, message.data)
                for _schema, channel, message in make_reader(stream).iter_messages(
                    log_time_order=False
                )
            ]
        first_log_time = min(t for _, t, _ in messages)
        states = [(t, data) for topic, t, data in messages if topic == "/snap/state"]
        if index:
            # The copy comes first, logged with the file's first message.
            assert messages[0][0] == "/snap/state"
            assert states[0][0] == first_log_time
        states_seen.append(states[0][1])
    # Each file's first state message is the latest one before it.
    with BagReader(bag) as reader:
        published = [m.data for m in reader.messages(topics=["/snap/state"])]
    assert states_seen[0] == published[0]
    assert states_seen[-1].endswith(b"state 1\x00")


def test_the_s_key_in_a_terminal_triggers_a_snapshot(
    node: Node, processes: Any, tmp_path: Path
) -> None:
    scene = Scene(node)
    out = tmp_path / "keyed"
    controller, terminal = pty.openpty()
    try:
        recorder = processes.start(
            [
                "bagkit",
                "record",
                "-e",
                "^/snap/",
                "-o",
                str(out),
                "--snapshot-mode",
                "--max-cache-duration",
                "5",
                "--format",
                "json",
            ],
            stdin=terminal,
            stdout=subprocess.PIPE,
            stderr=subprocess.PIPE,
        )
        wait_matched(scene.imu, timeout=30)
        scene.stream(0.5)
        os.write(controller, b"s")
        wait_for((out / "snapshot_0" / "metadata.yaml").is_file, 10)
        scene.stream(0.2)
        recorder.send_signal(signal.SIGINT)
        stdout, stderr = recorder.communicate(timeout=30)
    finally:
        os.close(controller)
        os.close(terminal)
    assert recorder.returncode == 130, stderr.decode()
    (snapshot,) = report_json(stdout)["snapshots"]
    assert snapshot["trigger"] == "key"
    with BagReader(out / "snapshot_0") as reader:
        assert reader.topic_counts["/snap/imu"] == snapshot["messages"]["/snap/imu"] > 0


def test_pre_post_windows_and_extension_without_dds(tmp_path: Path) -> None:
    """The sink on its own (the writer thread's calls, a fake clock): --pre, --post, extension."""
    from bagkit.bag import TopicInfo
    from bagkit.recording.snapshot import SnapshotSink
    from bagkit.ros.record.triggers import DataTriggers
    from bagkit.ros.serialization import serialize

    now = [0]
    errors: list[tuple[str, int]] = []
    opts = options(tmp_path / "sink", max_duration_ns=10 * S, pre_ns=S, post_ns=S // 2)
    sink = SnapshotSink(
        opts.output,
        opts,
        DataTriggers.of(opts),
        lambda *error: errors.append(error),
        now_ns=lambda: now[0],
    ).open()
    sink.add_topic(TopicInfo("/snap/imu", "sensor_msgs/msg/Imu"), "")
    payload = serialize(Imu())

    def feed(until_s: float) -> None:
        while now[0] < until_s * S:
            now[0] += S // 100
            sink.write_batch(
                "/snap/imu", [payload], log_times=[now[0]], publish_times=[now[0]],
                sequences=[now[0] // (S // 100)],
            )  # fmt: skip

    feed(5.0)
    first = sink.request("request")  # at 5 s: 4 s - 5.5 s
    feed(5.3)
    assert sink.request("request") is first  # inside the window: extends it to 5.8 s
    feed(7.0)  # the window closes 0.25 s after its end
    second = sink.request("request")  # a new snapshot: 6 s - 7.5 s
    feed(8.0)
    sink.close()
    assert not errors
    assert (first.start_ns, first.trigger_ns, first.end_ns) == (4 * S, 5 * S, 58 * S // 10)
    assert first.triggers == 2
    assert (second.start_ns, second.end_ns) == (6 * S, 75 * S // 10)
    for snapshot in (first, second):
        with BagReader(snapshot.path) as reader:
            times = [m.log_time for m in reader.messages()]
        assert times == list(range(snapshot.start_ns, snapshot.end_ns + 1, S // 100))
        assert snapshot.messages["/snap/imu"] == len(times)


def test_a_silence_triggers_while_it_lasts_without_dds(tmp_path: Path) -> None:
    """``gap > 500ms`` fires from the sink's periodic flush during the dropout, and
    ``unchanged(...) for 1s`` on the message that makes the run 1 s long."""
    from bagkit.bag import TopicInfo
    from bagkit.recording.snapshot import SnapshotSink
    from bagkit.ros.record.triggers import DataTriggers
    from bagkit.ros.serialization import serialize

    now = [0]
    errors: list[tuple[str, int]] = []
    triggers = ("/snap/imu: gap > 500ms", "/snap/imu: unchanged(linear_acceleration.z) for 1s")
    opts = options(tmp_path / "sink", max_duration_ns=10 * S, pre_ns=S, triggers=triggers)
    sink = SnapshotSink(
        opts.output,
        opts,
        DataTriggers.of(opts),
        lambda *error: errors.append(error),
        now_ns=lambda: now[0],
    ).open()
    sink.add_topic(TopicInfo("/snap/imu", "sensor_msgs/msg/Imu"), "")

    def feed(until_s: float, z: float | None = None) -> None:
        while now[0] < until_s * S:
            now[0] += S // 100
            msg = Imu()
            msg.linear_acceleration.z = float(now[0]) if z is None else z
            sink.write_batch(
                "/snap/imu", [serialize(msg)], log_times=[now[0]], publish_times=[now[0]],
                sequences=[now[0] // (S // 100)],
            )  # fmt: skip

    feed(5.0)
    for silent_s in (5.2, 5.4, 5.6, 5.8):  # the recorder's flushes during the dropout
        now[0] = int(silent_s * S)
        sink.flush()
    feed(8.0)
    feed(9.5, z=1.0)  # frozen from 8.01 s: 1 s long at 9.01 s
    sink.close()
    assert not errors
    gap, frozen = sink.snapshots
    assert gap.trigger == triggers[0]
    assert gap.trigger_ns == int(5.6 * S)  # the first flush more than 500 ms into the silence
    assert gap.start_ns == int(4.6 * S)  # --pre 1: the second before it, messages included
    assert frozen.trigger == triggers[1]
    assert frozen.trigger_ns == int(9.01 * S)


def test_a_dropout_writes_the_second_before_it_over_dds(node: Node, tmp_path: Path) -> None:
    """Real DDS: the Imu stream falls silent; ``gap > 500ms`` writes a snapshot holding the
    messages before the silence, without any message after it being needed."""
    scene = Scene(node)
    out = tmp_path / "blackbox"
    opts = options(out, max_duration_ns=S, triggers=("/snap/imu: gap > 500ms",))
    with Recorder(opts) as recorder:
        wait_matched(scene.imu)
        scene.stream(1.5)
        before = scene.sent
        time.sleep(2.5)  # the dropout: the recorder's flushes (every second) see it
    report = recorder.report
    assert report.error is None and report.snapshots
    # The last snapshot is the dropout's (a loaded machine may stall the publisher long
    # enough for an earlier one: a real silence too).
    snapshot = report.snapshots[-1]
    assert snapshot.trigger == "/snap/imu: gap > 500ms"
    stamps = [m.header.stamp.sec for _, m in read_snapshot(snapshot.path)["/snap/imu"]]
    assert stamps and stamps[-1] == before - 1  # the last message before the silence
    assert stamps == list(range(stamps[0], before))
