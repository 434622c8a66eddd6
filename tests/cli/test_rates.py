"""Rates a user can trust: pooled over bags as pooled, ``-`` where too few messages or too short
a time make one meaningless (subprocesses of the CLI, checked against the bag reader)."""

from __future__ import annotations

import json
import shutil
import subprocess
import sys
from pathlib import Path

import pytest
from bagkit_runs import bagkit_in_process

from bagkit.bag import BagReader, BagWriter, TopicInfo

BAGKIT = str(Path(sys.executable).with_name("bagkit"))
BAG = Path(__file__).resolve().parents[2] / "fixtures" / "faults" / "golden"
STRING = "std_msgs/msg/String"
PAYLOAD = b"\x00\x01\x00\x00\x02\x00\x00\x00x\x00"


def _json(*args: str | Path) -> dict:
    result = bagkit_in_process([*args, "--format", "json"])  # tests/bagkit_runs.py
    assert result.returncode == 0, result.stderr
    return json.loads(result.stdout)


def _rate(bag: Path, topic: str) -> float:
    """(n - 1) / (last - first), from the reader."""
    with BagReader(bag) as reader:
        times = [m.log_time for m in reader.messages([topic])]
    return (len(times) - 1) * 1e9 / (times[-1] - times[0])


def test_a_rate_pooled_over_bags_is_the_rate_of_each(tmp_path: Path) -> None:
    """Ten copies of a 2 Hz topic are 2 Hz, not 10 x 54 messages over one bag's span."""
    bags = [shutil.copytree(BAG, tmp_path / f"copy{i}") for i in range(10)]
    summary = _json("stats", "summary", *bags, "-t", "/temperature")
    (topic,) = summary["topics"]
    assert topic["count"] == 10 * BagReader(BAG).open().topic_counts["/temperature"]
    assert topic["rate_hz"] == pytest.approx(_rate(BAG, "/temperature"), rel=1e-9)
    assert topic["rate_hz"] == pytest.approx(2.0, rel=0.01)


@pytest.mark.parametrize(
    ("times_ns", "has_rate"),
    [
        ([0, 1_400_000], False),  # two messages: one interval is no rate (was 714 Hz)
        ([0, 3_000_000, 6_000_000, 9_000_000], False),  # a burst of 4 within 10 ms
        ([0, 500_000_000, 1_000_000_000], True),  # three over a second: 2 Hz
    ],
)
def test_a_rate_needs_enough_messages_over_enough_time(
    times_ns: list[int], has_rate: bool, tmp_path: Path
) -> None:
    bag = tmp_path / "bag"
    with BagWriter(bag) as writer:
        writer.add_topic(TopicInfo("/a", STRING))
        for t in times_ns:
            writer.write("/a", PAYLOAD, log_time=1_700_000_000_000_000_000 + t)
    expected = _rate(bag, "/a") if has_rate else None
    (info_topic,) = _json("info", bag)["topics"]
    (stats_topic,) = _json("stats", "summary", bag)["topics"]
    for found in (info_topic["rate_hz"], stats_topic["rate_hz"]):
        assert found == (pytest.approx(expected) if has_rate else None)
    table = subprocess.run([BAGKIT, "info", str(bag)], capture_output=True, text=True, check=True)
    (row,) = [line.split() for line in table.stdout.splitlines() if line.split()[:1] == ["/a"]]
    assert (row[-1] == "-") != has_rate
