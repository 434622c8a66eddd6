"""``bagkit echo`` as a real subprocess: YAML and JSON parse to rosbags' values; it streams;
Ctrl-C and a closed pipe end it quietly; no ROS import."""

from __future__ import annotations

import json
import signal
import subprocess
import sys
from pathlib import Path
from typing import Any

import numpy as np
import pytest
import yaml
from bagkit_runs import bagkit_in_process
from oracle import raw_messages, same
from samples import JAZZY, SAMPLE_TYPES

import bagkit

BAGKIT = str(Path(sys.executable).with_name("bagkit"))
REPO = Path(__file__).resolve().parents[2]
GOLDEN = REPO / "fixtures" / "nominal" / "golden"


def _echo(*args: str | Path, check: bool = True) -> subprocess.CompletedProcess[str]:
    """``bagkit echo ARGS`` in this process (tests/bagkit_runs.py); the pipe into ``head`` is a
    real process."""
    result = bagkit_in_process(["echo", *args])
    if check:
        assert result.returncode == 0, result.stderr
    return result


def _matches(msg: Any, plain: Any, base: str | None = None) -> bool:
    """Whether the printed ``plain`` data is the rosbags message ``msg``, field by field."""
    if hasattr(msg, "__msgtype__"):
        names = [name for name, _ in JAZZY.fielddefs[msg.__msgtype__][1]]
        return list(plain) == names and all(
            _matches(getattr(msg, name), plain[name], _base(msg.__msgtype__, name))
            for name in names
        )
    if isinstance(msg, (list, np.ndarray)):
        return len(msg) == len(plain) and all(
            _matches(m, p, base) for m, p in zip(msg, plain, strict=True)
        )
    if base in ("byte", "char"):
        return int(msg) & 0xFF == plain
    if isinstance(msg, (bool, np.bool_)):
        return plain is bool(msg)
    return same(msg.item() if isinstance(msg, np.generic) else msg, plain)


def _base(typename: str, field: str) -> str | None:
    desc = dict(JAZZY.fielddefs[typename][1])[field]
    while desc[0] in (3, 4):  # array, sequence
        desc = desc[1][0]
    return desc[1][0] if desc[0] == 1 else None


def _oracle(bag: Path, topic: str) -> list[tuple[int, object]]:
    rows = [
        (t, JAZZY.deserialize_cdr(data, SAMPLE_TYPES[topic]))
        for name, t, _, data in raw_messages(bag)
        if name == topic
    ]
    return sorted(rows, key=lambda row: row[0])


@pytest.mark.parametrize("topic", sorted(SAMPLE_TYPES))
def test_json_lines_equal_rosbags(sample_bag: Path, topic: str) -> None:
    out = _echo(sample_bag, topic, "--format", "json", "-n", "40").stdout
    records = [json.loads(line) for line in out.splitlines()]
    expected = _oracle(sample_bag, topic)[:40]
    assert len(records) == 40
    for record, (log_time, msg) in zip(records, expected, strict=True):
        assert record["topic"] == topic and record["log_time"] == log_time
        assert _matches(msg, record["data"]), (topic, record["data"])


def test_yaml_documents_equal_rosbags_and_cut_long_sequences(sample_bag: Path) -> None:
    out = _echo(sample_bag, "/diagnostics", "-n", "25").stdout
    documents = [d for d in yaml.safe_load_all(out) if d is not None]
    assert len(documents) == 25 and out.startswith("# /diagnostics at 0.0")
    for document, (log_time, msg) in zip(
        documents, _oracle(sample_bag, "/diagnostics"), strict=False
    ):
        assert document["log_time"] == log_time
        assert _matches(msg, document["data"])
    image = yaml.safe_load_all(_echo(sample_bag, "/image", "-n", "30").stdout)
    cut = [d["data"]["data"] for d in image if d and len(d["data"]["data"]) > 128]
    assert cut and all(str(d[-1]).startswith("... (") for d in cut)


def test_fields_window_and_count_against_the_dataframe(sample_bag: Path) -> None:
    out = _echo(
        sample_bag,
        "/imu",
        "--format",
        "json",
        "--fields",
        "linear_acceleration.*",
        "--fields",
        "header.frame_id",
        "--start",
        "0.05",
        "--end",
        "0.15",
    ).stdout
    records = [json.loads(line) for line in out.splitlines()]
    frame = bagkit.read_arrow(
        sample_bag, "/imu", ["linear_acceleration.*", "header.frame_id"], start=0.05, end=0.15
    ).to_pylist()
    assert 0 < len(records) == len(frame)
    for record, row in zip(records, frame, strict=True):
        assert record["log_time"] == row["log_time"]
        assert (
            all(same(record["data"][k], row[k]) for k in record["data"])
            and len(record["data"]) == 4
        )


def test_bad_input_is_one_error_line(sample_bag: Path) -> None:
    result = _echo(sample_bag, "/nope", check=False)
    assert result.returncode == 2 and result.stderr.startswith(
        "error: topic /nope not in the bag (it has /diagnostics"
    )
    result = _echo(sample_bag, "/imu", "--fields", "accel", check=False)
    assert result.returncode == 2 and "no field accel (" in result.stderr
    assert "it has header.stamp.{sec,nanosec}" in result.stderr
    assert "Traceback" not in result.stderr


def test_streams_and_ends_quietly_on_a_closed_pipe_and_ctrl_c(sample_bag: Path) -> None:
    # The process blocks on the full pipe with most of the bag unread: the first message came
    # out before the rest was decoded.
    proc = subprocess.Popen(
        [BAGKIT, "echo", sample_bag, "/image", "--full-length"],
        stdout=subprocess.PIPE,
        stderr=subprocess.PIPE,
        start_new_session=True,
        # As from a shell: a test runner's worker may ignore SIGINT, and children inherit that.
        preexec_fn=lambda: signal.signal(signal.SIGINT, signal.default_int_handler),  # noqa: PLW1509
    )
    assert proc.stdout is not None and proc.stderr is not None
    assert proc.stdout.readline().startswith(b"# /image at 0.0")
    assert proc.poll() is None
    proc.send_signal(signal.SIGINT)
    assert proc.wait(timeout=30) == 130
    assert proc.stderr.read() == b""
    proc.stdout.close()
    proc.stderr.close()
    # | head -1
    pipeline = subprocess.run(
        f"'{BAGKIT}' echo '{sample_bag}' /image --full-length | head -1",
        shell=True,
        capture_output=True,
        text=True,
        timeout=60,
        check=False,
    )
    assert pipeline.stdout.startswith("# /image at") and pipeline.stderr == ""


def test_echo_imports_no_ros(tmp_path: Path) -> None:
    code = (
        "import atexit, sys\n"
        f"sys.argv = ['bagkit', 'echo', {str(GOLDEN)!r}, '/imu/data', '-n', '1']\n"
        "heavy = ('rclpy', 'pandas', 'pyarrow')\n"
        "loaded = lambda: sorted(m for m in sys.modules if m.split('.')[0] in heavy)\n"
        "atexit.register(lambda: sys.stderr.write(repr(loaded())))\n"
        "from bagkit.cli.launch import run\nrun()\n"
    )
    result = subprocess.run(
        [sys.executable, "-c", code], capture_output=True, text=True, timeout=60, check=False
    )
    assert result.returncode == 0 and "log_time" in result.stdout
    assert result.stderr == "[]"


def test_an_empty_message_is_an_empty_mapping(tmp_path: Path) -> None:
    from bagkit.bag import BagWriter, TopicInfo

    empty = "std_msgs/msg/Empty"
    data = bytes(
        JAZZY.serialize_cdr(JAZZY.types[empty](structure_needs_at_least_one_member=0), empty)
    )
    with BagWriter(tmp_path / "empty") as bag:
        bag.add_topic(TopicInfo("/tick", empty))
        for i in range(3):
            bag.write("/tick", data, log_time=1_000 + i, publish_time=1_000 + i)
    records = [
        json.loads(line)
        for line in _echo(tmp_path / "empty", "/tick", "--format", "json").stdout.splitlines()
    ]
    assert [r["data"] for r in records] == [{}, {}, {}]
    assert "structure_needs" not in _echo(tmp_path / "empty", "/tick").stdout
