"""compare's count columns say what they count: statuses on an event topic, messages elsewhere
(counted here with rosbags, independently of bagkit's reader)."""

from __future__ import annotations

import json
import subprocess
import sys
from pathlib import Path

from rosbags.highlevel import AnyReader

BAGKIT = str(Path(sys.executable).with_name("bagkit"))
FIXTURES = Path(__file__).resolve().parents[2] / "fixtures"
GOLDEN, CANDIDATE = FIXTURES / "faults" / "golden", FIXTURES / "nominal" / "golden"


def _counts(bag: Path) -> tuple[int, int, int]:
    """/alerts messages, their statuses, /imu/data messages."""
    with AnyReader([bag]) as reader:
        alerts = [c for c in reader.connections if c.topic == "/alerts"]
        decoded = [reader.deserialize(raw, c.msgtype) for c, _, raw in reader.messages(alerts)]
        imu = [c for c in reader.connections if c.topic == "/imu/data"]
        return len(decoded), sum(len(m.status) for m in decoded), sum(c.msgcount for c in imu)


def _compare(*extra: str) -> subprocess.CompletedProcess[str]:
    return subprocess.run(
        [BAGKIT, "compare", str(GOLDEN), str(CANDIDATE), *extra],
        capture_output=True,
        text=True,
        timeout=120,
        check=False,
        env={"COLUMNS": "80", "PATH": ""},
    )


def test_event_counts_are_labelled_statuses_and_others_messages() -> None:
    messages, statuses, imu = _counts(GOLDEN)
    assert messages < statuses  # the case where the two differ
    rows: dict[str, list[str]] = {}
    for line in _compare().stdout.splitlines():  # the table first, then the divergences
        if line.startswith("  /"):
            rows.setdefault(line.split()[0], line.split())
    assert rows["/alerts"][1:3] == ["statuses", str(statuses)]
    assert rows["/imu/data"][1:5] == ["msgs", "by", "stamp", str(imu)]
    topics = {t["topic"]: t for t in json.loads(_compare("--format", "json").stdout)["topics"]}
    assert (topics["/alerts"]["counted"], topics["/alerts"]["golden_count"]) == (
        "statuses",
        statuses,
    )
    assert (topics["/imu/data"]["counted"], topics["/imu/data"]["golden_count"]) == (
        "messages",
        imu,
    )
