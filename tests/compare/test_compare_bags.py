"""Comparing real MCAP bags built in code, through the library and the ``bagkit`` CLI."""

from __future__ import annotations

import json
import subprocess
import sys
from collections.abc import Callable
from pathlib import Path

import pytest
from diagnostic_msgs.msg import DiagnosticArray, DiagnosticStatus
from geometry_msgs.msg import PoseWithCovarianceStamped
from rclpy.serialization import serialize_message
from std_msgs.msg import String

from bagkit.bag import BagWriter, TopicInfo
from bagkit.compare import CompareError, CompareOptions, Tolerance, compare_bags
from bagkit.selection.errors import UnknownTopicError

SEC = 1_000_000_000
BAGKIT = str(Path(sys.executable).with_name("bagkit"))
ALTITUDE = "/fusion/baro_altitude"
ALERTS = "/alerts"
NOTES = "/notes"

Mutation = Callable[[str, int, object], object | None]


def altitude(t_ns: int, z: float) -> PoseWithCovarianceStamped:
    msg = PoseWithCovarianceStamped()
    msg.header.stamp.sec, msg.header.stamp.nanosec = divmod(t_ns, SEC)
    msg.header.frame_id = "map"
    msg.pose.pose.position.z = z
    msg.pose.covariance[14] = 4.0
    return msg


def alert(t_ns: int, name: str, level: bytes) -> DiagnosticArray:
    msg = DiagnosticArray()
    msg.header.stamp.sec, msg.header.stamp.nanosec = divmod(t_ns, SEC)
    msg.status = [DiagnosticStatus(name=name, level=level, message="out of range")]
    return msg


def write_bag(path: Path, mutate: Mutation | None = None) -> Path:
    """A 10 s bag: 2 Hz altitude, one note per second (no header), two alerts.

    ``mutate(topic, index, msg)`` may change a message, replace it with bytes written as they
    are, or return None to drop it.
    """
    messages: list[tuple[str, int, object]] = []
    for i in range(20):
        t = i * SEC // 2
        messages.append((ALTITUDE, t, altitude(t, 100.0 + 0.5 * i)))
    for i in range(10):
        messages.append((NOTES, i * SEC, String(data=f"note {i}")))
    messages.append((ALERTS, 3 * SEC, alert(3 * SEC, "barometer", DiagnosticStatus.ERROR)))
    messages.append((ALERTS, 7 * SEC, alert(7 * SEC, "barometer", DiagnosticStatus.OK)))
    messages.sort(key=lambda m: m[1])
    types = {
        ALTITUDE: "geometry_msgs/msg/PoseWithCovarianceStamped",
        ALERTS: "diagnostic_msgs/msg/DiagnosticArray",
        NOTES: "std_msgs/msg/String",
    }
    index: dict[str, int] = {}
    with BagWriter(path) as bag:
        for topic, type_name in types.items():
            bag.add_topic(TopicInfo(topic, type_name))
        for topic, t, msg in messages:
            i = index[topic] = index.get(topic, -1) + 1
            changed = mutate(topic, i, msg) if mutate else msg
            if changed is not None:
                # receive times differ from run to run: they must not matter by default
                receive = t + (7_000_000 if mutate else 0)
                data = changed if isinstance(changed, bytes) else serialize_message(changed)
                bag.write(topic, data, log_time=receive, publish_time=t)
    return path


@pytest.fixture
def golden(tmp_path: Path) -> Path:
    return write_bag(tmp_path / "golden")


def candidate(tmp_path: Path, mutate: Mutation) -> Path:
    return write_bag(tmp_path / "candidate", mutate)


def unchanged(topic: str, index: int, msg: object) -> object:
    return msg


def test_an_undecodable_message_costs_that_message_only(golden: Path, tmp_path: Path) -> None:
    """Lengths the payload cannot hold: the message is left out and counted, a failed message
    each; the rest of its topic is compared as usual."""

    def corrupt(topic: str, index: int, msg: object) -> object:
        if (topic, index) not in {(ALTITUDE, 3), (ALTITUDE, 8), (NOTES, 9)}:
            return msg
        data = bytearray(serialize_message(msg))
        # header.frame_id's length (altitude), the string's (note)
        offset = 12 if topic == ALTITUDE else 4
        data[offset : offset + 4] = (2**31 if index == 3 else 2**32 - 1).to_bytes(4, "little")
        return bytes(data)

    report = compare_bags(golden, candidate(tmp_path, corrupt))

    by_topic = {t.topic: t for t in report.topics}
    heights = by_topic[ALTITUDE]
    assert (heights.golden_undecodable, heights.candidate_undecodable) == (0, 2)
    assert (heights.matched, heights.missing, heights.extra) == (18, 2, 0)
    assert heights.failed_messages == 4 and heights.divergence_count == 2 and not heights.passed
    notes = by_topic[NOTES]
    assert (notes.candidate_undecodable, notes.matched, notes.missing) == (1, 9, 1)
    assert notes.failed_messages == 2
    assert by_topic[ALERTS].passed and by_topic[ALERTS].candidate_undecodable == 0
    assert [w.split(" (")[0] for w in report.warnings] == [
        f"{ALTITUDE}: 0 golden messages and 2 candidate messages could not be decoded and are "
        "left out",
        f"{NOTES}: 0 golden messages and 1 candidate message could not be decoded and are left out",
    ]
    topic_json = next(t for t in report.to_dict()["topics"] if t["topic"] == ALTITUDE)
    assert (topic_json["golden_undecodable"], topic_json["candidate_undecodable"]) == (0, 2)


def test_identical_bags_pass(golden: Path, tmp_path: Path) -> None:
    report = compare_bags(golden, candidate(tmp_path, unchanged))
    assert report.passed, report.first_divergences()
    by_topic = {t.topic: t for t in report.topics}
    assert by_topic[ALTITUDE].matched_by == "stamp" and by_topic[ALTITUDE].matched == 20
    assert by_topic[NOTES].matched_by == "order" and by_topic[NOTES].matched == 10
    assert by_topic[ALERTS].matched_by == "event" and by_topic[ALERTS].matched == 2


def test_perturbed_field_is_named_with_its_error(golden: Path, tmp_path: Path) -> None:
    def nudge(topic: str, index: int, msg: object) -> object:
        if topic == ALTITUDE and index == 5:
            assert isinstance(msg, PoseWithCovarianceStamped)
            msg.pose.pose.position.z += 0.02
        return msg

    bag = candidate(tmp_path, nudge)
    strict = compare_bags(golden, bag, CompareOptions(tolerance=Tolerance(atol=0.01)))
    assert not strict.passed
    topic = next(t for t in strict.topics if t.topic == ALTITUDE)
    assert [f.path for f in topic.failed_fields] == ["pose.pose.position.z"]
    (divergence,) = topic.divergences
    assert divergence.time_ns == 5 * SEC // 2
    assert divergence.abs_error == pytest.approx(0.02, rel=1e-6)
    assert compare_bags(golden, bag, CompareOptions(tolerance=Tolerance(atol=0.05))).passed


def test_missing_and_extra_messages(golden: Path, tmp_path: Path) -> None:
    def drop_one(topic: str, index: int, msg: object) -> object | None:
        return None if topic == ALTITUDE and index == 4 else msg

    report = compare_bags(golden, candidate(tmp_path, drop_one))
    topic = next(t for t in report.topics if t.topic == ALTITUDE)
    assert (topic.missing, topic.extra, topic.matched) == (1, 0, 19)
    assert topic.divergences[0].kind == "missing_message"
    assert topic.divergences[0].time_ns == 2 * SEC
    reverse = compare_bags(write_bag(tmp_path / "other", drop_one), golden)
    topic = next(t for t in reverse.topics if t.topic == ALTITUDE)
    assert (topic.missing, topic.extra) == (0, 1)


def test_changed_string_fails(golden: Path, tmp_path: Path) -> None:
    def rename(topic: str, index: int, msg: object) -> object:
        if topic == ALTITUDE and index == 0:
            assert isinstance(msg, PoseWithCovarianceStamped)
            msg.header.frame_id = "odom"
        return msg

    report = compare_bags(
        golden, candidate(tmp_path, rename), CompareOptions(tolerance=Tolerance(1.0, 1.0))
    )
    (divergence,) = report.first_divergences()
    assert (divergence.field, divergence.golden, divergence.candidate) == (
        "header.frame_id",
        "map",
        "odom",
    )


@pytest.mark.parametrize(("shift_s", "passes"), [(0.3, True), (-0.45, True), (0.8, False)])
def test_alert_shift_against_the_window(
    golden: Path, tmp_path: Path, shift_s: float, passes: bool
) -> None:
    def shift(topic: str, index: int, msg: object) -> object:
        if topic in {ALTITUDE, NOTES} or index != 0:
            return msg
        return alert(3 * SEC + round(shift_s * SEC), "barometer", DiagnosticStatus.ERROR)

    report = compare_bags(golden, candidate(tmp_path, shift))
    topic = next(t for t in report.topics if t.topic == ALERTS)
    assert topic.passed is passes
    if passes:
        assert topic.max_event_shift_ns == round(abs(shift_s) * SEC)
    else:
        assert [d.kind for d in topic.divergences] == ["missing_event", "extra_event"]
        assert topic.divergences[0].field == "barometer"


def test_unreadable_bag_is_a_compare_error(golden: Path, tmp_path: Path) -> None:
    with pytest.raises(CompareError):
        compare_bags(golden, tmp_path / "nothing")
    with pytest.raises(UnknownTopicError, match="not in either bag"):
        compare_bags(golden, golden, CompareOptions(topics=("/nope",)))


def run_cli(*args: str | Path) -> subprocess.CompletedProcess[str]:
    return subprocess.run(
        [BAGKIT, "compare", *map(str, args)],
        check=False,
        capture_output=True,
        text=True,
        timeout=60,
    )


def test_cli_exit_codes_and_json_report(golden: Path, tmp_path: Path) -> None:
    def nudge(topic: str, index: int, msg: object) -> object:
        if topic == ALTITUDE:
            assert isinstance(msg, PoseWithCovarianceStamped)
            msg.pose.pose.position.z += 0.001 * index
        return msg

    bag = candidate(tmp_path, nudge)
    same = run_cli(golden, bag, "--atol", "0.05")
    assert same.returncode == 0, same.stdout + same.stderr
    assert "PASS" in same.stdout

    report_file = tmp_path / "report.json"
    different = run_cli(golden, bag, "--topics", ALTITUDE, "--report", report_file)
    assert different.returncode == 1
    assert "pose.pose.position.z" in different.stdout and "FAIL" in different.stdout
    verdict = json.loads(report_file.read_text())
    assert verdict["verdict"] == "fail"
    (topic,) = verdict["topics"]
    assert topic["failed_fields"] == ["pose.pose.position.z"]
    field = next(f for f in topic["fields"] if f["path"] == "pose.pose.position.z")
    assert field["max_abs_error"] == pytest.approx(0.019, rel=1e-6)

    ignored = run_cli(
        golden, bag, "--ignore-fields", f"{ALTITUDE}:pose.pose.position.*", "--format", "json"
    )
    assert ignored.returncode == 0, ignored.stdout
    assert json.loads(ignored.stdout)["verdict"] == "pass"


def test_cli_unusable_input_exits_2_with_one_line(golden: Path, tmp_path: Path) -> None:
    broken = tmp_path / "broken.mcap"
    broken.write_bytes(b"not an mcap file at all")
    result = run_cli(golden, broken)
    assert result.returncode == 2
    assert result.stderr.startswith("error:") and "Traceback" not in result.stderr


def test_every_interop_bag_equals_itself(interop_dir: Path) -> None:
    bags = sorted(p.parent for p in interop_dir.rglob("metadata.yaml"))
    assert len(bags) >= 10
    for bag in bags:
        if "empty" in bag.name:  # no messages: unusable input, exit 2
            with pytest.raises(CompareError):
                compare_bags(bag, bag)
            continue
        report = compare_bags(bag, bag)
        assert report.passed, (bag, report.first_divergences())
        assert sum(t.matched for t in report.topics) > 0, bag


def test_undecodable_topic_is_compared_byte_for_byte(tmp_path: Path) -> None:
    def bag(name: str, payloads: list[bytes]) -> Path:
        with BagWriter(tmp_path / name) as writer:
            writer.add_topic(
                TopicInfo("/blob", "vendor_msgs/msg/Blob"), definition="this is not ros2msg !!"
            )
            for i, data in enumerate(payloads):
                writer.write("/blob", data, log_time=i * SEC)
        return tmp_path / name

    golden = bag("golden", [b"\x00\x01\x00\x00abcd", b"\x00\x01\x00\x00efgh"])
    same = bag("same", [b"\x00\x01\x00\x00abcd", b"\x00\x01\x00\x00efgh"])
    other = bag("other", [b"\x00\x01\x00\x00abcd", b"\x00\x01\x00\x00efgX"])
    passed = compare_bags(golden, same)
    assert passed.passed and any("byte for byte" in w for w in passed.warnings)
    failed = compare_bags(golden, other)
    (divergence,) = failed.first_divergences()
    assert (divergence.field, divergence.time_ns) == ("~cdr", SEC)


def test_skip_leaves_out_the_warm_up(golden: Path, tmp_path: Path) -> None:
    def cold_start(topic: str, index: int, msg: object) -> object | None:
        if topic == ALTITUDE and index < 4:  # the first 2 s differ or are missing
            return None if index == 0 else altitude(index * SEC // 2, 0.0)
        return msg

    bag = candidate(tmp_path, cold_start)
    assert not compare_bags(golden, bag).passed
    assert compare_bags(golden, bag, CompareOptions(skip_ns=2 * SEC)).passed
    assert not compare_bags(golden, bag, CompareOptions(skip_ns=SEC)).passed
