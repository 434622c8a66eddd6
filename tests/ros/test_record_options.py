"""ros2 bag record's options in bagkit record: selection by type, exclusions, custom data,
splitting with -d, --duration counted from subscription, sim time before the first /clock."""

from __future__ import annotations

import os
import re
import threading
import time
from pathlib import Path

import pytest
import yaml
from rclpy.node import Node
from rclpy.qos import QoSProfile, ReliabilityPolicy
from rosgraph_msgs.msg import Clock
from std_msgs.msg import Int32, String
from test_record_cli import STARTUP_TIMEOUT_S, record, report_json
from waiting import wait_for, wait_matched

from bagkit.bag import BagReader
from bagkit.recording.options import RecordOptions
from bagkit.recording.report import RecordProgress
from bagkit.ros.record.recorder import Recorder

pytestmark = pytest.mark.ros


def test_sim_time_writes_nothing_before_the_first_clock(node: Node, tmp_path: Path) -> None:
    clock = node.create_publisher(
        Clock, "/clock", QoSProfile(depth=1, reliability=ReliabilityPolicy.BEST_EFFORT)
    )
    data = node.create_publisher(String, "/sim/early", 100)
    bag = tmp_path / "sim"
    with Recorder(RecordOptions(bag, topics=("/sim/early",), use_sim_time=True)) as recorder:
        wait_matched(clock, data)
        for i in range(5):
            data.publish(String(data=f"early {i}"))
        wait_for(lambda: recorder.progress().before_clock == 5)
        sim = Clock()
        sim.clock.sec = 700
        clock.publish(sim)
        time.sleep(0.2)  # the clock is taken before the next messages
        for i in range(3):
            data.publish(String(data=f"late {i}"))
        wait_for(lambda: recorder.progress().messages == 3)
        assert recorder.progress().span_ns == 0
        sim.clock.sec, sim.clock.nanosec = 702, 500_000_000
        clock.publish(sim)
        time.sleep(0.2)
        data.publish(String(data="later"))
        wait_for(lambda: recorder.progress().messages == 4)
        assert recorder.progress().span_ns == 2_500_000_000  # golden record stops on it
    assert recorder.report.topic("/sim/early").before_clock == 5
    assert recorder.report.to_dict()["topics"][0]["before_clock"] == 5
    with BagReader(bag) as reader:
        log_times = [m.log_time for m in reader.messages()]
    assert log_times == [700 * 1_000_000_000] * 3 + [702_500_000_000]


def _publish_until(stop: threading.Event, publishers: list[object], period: float) -> None:
    i = 0
    while not stop.is_set():
        for publisher in publishers:
            message = Int32(data=i) if publisher.msg_type is Int32 else String(data=str(i))  # type: ignore[attr-defined]
            publisher.publish(message)  # type: ignore[attr-defined]
        i += 1
        time.sleep(period)


def test_selection_by_type_exclusions_custom_data_and_splitting(
    node: Node, processes: object, tmp_path: Path
) -> None:
    publishers = [
        node.create_publisher(String, "/opt/a", 100),
        node.create_publisher(String, "/opt/b", 100),
        node.create_publisher(String, "/opt/c", 100),
        node.create_publisher(Int32, "/opt/n", 100),
    ]
    stop = threading.Event()
    thread = threading.Thread(target=_publish_until, args=(stop, publishers, 0.02))
    thread.start()
    bag = tmp_path / "selected"
    try:
        proc = record(
            processes,
            "--topic-types",
            "std_msgs/msg/String",
            "std_msgs/Int32",
            "--exclude-topics",
            "/opt/b",
            "--exclude-topic-types",
            "std_msgs/msg/Int32",
            "-x",
            "^/opt/c$",
            "--custom-data",
            "vehicle=car 7,trailer",
            "driver=ann,shift=night",
            "-d",
            "1",
            "--duration",
            "3",
            "-o",
            str(bag),
            "--format",
            "json",
        )
        stdout, stderr = proc.communicate(timeout=60)
    finally:
        stop.set()
        thread.join()
    assert proc.returncode == 0, stderr.decode()
    report = report_json(stdout)
    assert [t["topic"] for t in report["topics"]] == ["/opt/a"]
    assert report["topics"][0]["messages"] > 0
    assert report["discovery_s"] is not None
    metadata = yaml.safe_load((bag / "metadata.yaml").read_text())["rosbag2_bagfile_information"]
    custom = metadata["custom_data"]
    assert (custom["vehicle"], custom["driver"], custom["shift"]) == (
        "car 7,trailer",
        "ann",
        "night",
    )
    # -d is --max-bag-duration: the recording went on past it, into several files.
    assert len(metadata["relative_file_paths"]) >= 2
    with BagReader(bag) as reader:
        assert reader.topic_counts == {"/opt/a": report["topics"][0]["messages"]}


def test_duration_counts_from_subscription_and_the_table_fits_80_columns(
    node: Node, processes: object, tmp_path: Path
) -> None:
    """A named topic that appears late still gets its whole --duration of recording."""
    late = "/a/rather/long/namespace/for/a/late/topic_published_after_discovery"
    bag = tmp_path / "late"
    proc = record(
        processes,
        "--topics",
        late,
        "/opt/other",
        "--duration",
        "1",
        "-o",
        str(bag),
        env={**os.environ, "COLUMNS": "80"},
    )
    wait_for(bag.exists, STARTUP_TIMEOUT_S)
    time.sleep(2.0)  # discovery goes on: neither topic is published yet
    publishers = [
        node.create_publisher(String, late, 100),
        node.create_publisher(String, "/opt/other", 100),
    ]
    stop = threading.Event()
    thread = threading.Thread(target=_publish_until, args=(stop, publishers, 0.02))
    thread.start()
    try:
        stdout, stderr = proc.communicate(timeout=60)
    finally:
        stop.set()
        thread.join()
    assert proc.returncode == 0, stderr.decode()
    lines = stdout.decode().splitlines()
    # The bag's path has a line of its own, as long as the temporary directory makes it.
    assert lines[0] == str(bag)
    assert all(len(line) <= 80 for line in lines[1:]), stdout.decode()
    assert any(late in line.split() for line in lines), stdout.decode()
    # The publishers appeared 2 s after the bag did: a --duration counted from start would
    # have ended before them (0 messages). It ran 1 s past the subscriptions instead. (How long
    # after its own start the recorder subscribed depends on how slowly it started: the bag
    # directory exists before rclpy is up.)
    title = re.search(r"\(([0-9.]+) s,\s+topics subscribed after ([0-9.]+) s\)", stdout.decode())
    assert title is not None, stdout.decode()
    total, discovery = float(title.group(1)), float(title.group(2))
    assert discovery > 0.0 and total >= discovery + 0.9
    with BagReader(bag) as reader:
        counts = reader.topic_counts
    assert counts[late] > 0 and counts["/opt/other"] > 0


def test_storage_other_than_mcap_and_bad_custom_data_are_bad_input(
    processes: object, tmp_path: Path
) -> None:
    for args, message in (
        (
            ["-s", "sqlite3", "-a"],
            "--storage sqlite3: bagkit records MCAP only (it reads sqlite3 bags)",
        ),
        (["-a", "--custom-data", "novalue"], "--custom-data 'novalue' is not KEY=VALUE"),
        (
            ["-a", "--compression-mode", "none", "--compression-format", "lz4"],
            "--compression-format needs a --compression-mode other than none",
        ),
    ):
        proc = record(processes, "-o", str(tmp_path / "never"), *args)
        _, stderr = proc.communicate(timeout=30)
        assert proc.returncode == 2
        assert stderr.decode().strip() == f"error: {message}"
        assert not (tmp_path / "never").exists()


def test_run_stops_at_max_messages_on_a_condition_and_on_an_event(
    node: Node, tmp_path: Path
) -> None:
    publisher = node.create_publisher(String, "/run/data", 100)
    feeding_done = threading.Event()
    feeding = threading.Thread(target=_publish_until, args=(feeding_done, [publisher], 0.01))
    feeding.start()
    reports = []
    try:
        options = RecordOptions(tmp_path / "limited", topics=("/run/data",), max_messages=5)
        progress: list[int] = []
        reports.append(Recorder(options).run(on_progress=lambda p: progress.append(p.messages)))
        assert progress  # called as the recording starts, then every half second
        # A condition: stop once three messages are in.
        recorder = Recorder(RecordOptions(tmp_path / "condition", topics=("/run/data",)))
        reports.append(recorder.run(lambda: recorder.progress().messages >= 3))
        # An event, set from another thread (here, the progress callback's).
        stop = threading.Event()

        def stop_after_three(progress: RecordProgress) -> None:
            if progress.messages >= 3:
                stop.set()

        options = RecordOptions(tmp_path / "event", topics=("/run/data",))
        reports.append(Recorder(options).run(stop, on_progress=stop_after_three))
    finally:
        feeding_done.set()
        feeding.join()
    assert [r.error for r in reports] == [None, None, None]
    assert reports[0].messages >= 5  # counted between two looks: a few more may be in
    assert reports[1].messages >= 3 and reports[2].messages >= 3
    for report in reports:
        with BagReader(report.path) as reader:
            assert reader.topic_counts == {"/run/data": report.messages}
