"""A broken candidate never passes: a golden topic it lacks, or has no message of, fails."""

from __future__ import annotations

import json
import os
import subprocess
import sys
from pathlib import Path

import pytest
from rclpy.serialization import serialize_message
from std_msgs.msg import String

from bagkit.bag import BagReader, BagWriter, TopicInfo
from bagkit.compare import CompareOptions, compare_bags

BAGKIT = str(Path(sys.executable).with_name("bagkit"))
SEC = 1_000_000_000
TOPICS = ("/fusion/odometry", "/gps/fix")


def write(path: Path, counts: dict[str, int]) -> Path:
    with BagWriter(path) as bag:
        for topic in counts:
            bag.add_topic(TopicInfo(topic, "std_msgs/msg/String"))
        for topic, count in counts.items():
            for i in range(count):
                data = serialize_message(String(data=f"{topic} {i}"))
                bag.write(topic, data, log_time=SEC + i * SEC // 10)
    return path


@pytest.fixture
def golden(tmp_path: Path) -> Path:
    return write(tmp_path / "golden", dict.fromkeys(TOPICS, 20))


@pytest.mark.parametrize(
    ("counts", "reason"),
    [
        ({"/fusion/odometry": 20}, "not in the candidate"),
        ({"/fusion/odometry": 20, "/gps/fix": 0}, "no message in the candidate"),
    ],
    ids=["topic missing", "no message"],
)
def test_a_golden_topic_the_candidate_lacks_fails(
    golden: Path, tmp_path: Path, counts: dict[str, int], reason: str
) -> None:
    candidate = write(tmp_path / "candidate", counts)
    with BagReader(candidate) as reader:  # the candidate is what the case says
        assert reader.topic_counts.get("/gps/fix", 0) == 0
    # Even a pass rate that forgives every message does not pass a missing topic.
    report = compare_bags(golden, candidate, CompareOptions(pass_rate=0.0))
    (gps,) = [t for t in report.topics if t.topic == "/gps/fix"]
    assert gps.absent == reason and not gps.passed and not report.passed
    # Golden checks compare the spec's output topics: the same verdict.
    outputs = compare_bags(golden, candidate, CompareOptions(topics=TOPICS))
    assert [t.absent for t in outputs.topics] == ["", reason] and not outputs.passed
    done = subprocess.run(
        [BAGKIT, "compare", str(golden), str(candidate)],
        check=False,
        capture_output=True,
        text=True,
        timeout=60,
        env={**os.environ, "COLUMNS": "200"},
    )
    assert done.returncode == 1, done.stderr
    assert f"/gps/fix: {reason}" in done.stdout
    rows = [line for line in done.stdout.splitlines() if line.startswith("  /gps/fix ")]
    (row,) = [line for line in rows if " msgs " in line]  # its row of the table
    assert row.split()[-1] == "absent", row
    assert "FAIL" in done.stdout and "/gps/fix" in done.stdout.split("FAIL")[-1]
    as_json = subprocess.run(
        [BAGKIT, "compare", str(golden), str(candidate), "--format", "json"],
        check=False,
        capture_output=True,
        text=True,
        timeout=60,
    )
    verdict = json.loads(as_json.stdout)
    assert as_json.returncode == 1 and verdict["verdict"] == "fail"
    assert [t["absent"] for t in verdict["topics"] if t["topic"] == "/gps/fix"] == [reason]


def test_a_complete_candidate_passes_and_extra_topics_warn(golden: Path, tmp_path: Path) -> None:
    candidate = write(tmp_path / "candidate", {**dict.fromkeys(TOPICS, 20), "/extra": 3})
    report = compare_bags(golden, candidate)
    assert report.passed
    assert report.warnings == ["not compared, only in the candidate: /extra"]
