"""``bagkit record`` as a subprocess: signals, SIGKILL, split bags, a full disk, bad options."""

from __future__ import annotations

import json
import os
import re
import resource
import signal
import subprocess
import time
from pathlib import Path
from typing import Any

import fastdds_files
import pytest
from rclpy.duration import Duration
from rclpy.node import Node
from rclpy.qos import QoSProfile, ReliabilityPolicy
from rclpy.serialization import deserialize_message
from std_msgs.msg import String
from waiting import wait_for

from bagkit.bag import BagReader
from bagkit.recording.write_loop import FLUSH_PERIOD_S

pytestmark = pytest.mark.ros


STARTUP_TIMEOUT_S = 20.0


def record(processes: object, *args: str, **kwargs: object) -> subprocess.Popen[bytes]:
    return processes.start(  # type: ignore[attr-defined, no-any-return]
        ["bagkit", "record", *args],
        stdout=subprocess.PIPE,
        stderr=subprocess.PIPE,
        **kwargs,
    )


def report_json(stdout: bytes) -> dict[str, Any]:
    """The JSON report; Fast DDS may print its own log lines to stdout before it."""
    text = stdout.decode()
    start = 0 if text.startswith("{") else text.index("\n{") + 1
    report: dict[str, Any] = json.loads(text[start:])
    return report


def texts(bag: Path, topic: str) -> list[str]:
    with BagReader(bag) as reader:
        return [deserialize_message(m.data, String).data for m in reader.messages(topics=[topic])]


def test_sigint_finishes_the_bag(node: Node, processes: object, tmp_path: Path) -> None:
    publisher = node.create_publisher(String, "/cli/chatter", 100)
    bag = tmp_path / "interrupted"
    proc = record(processes, "/cli/chatter", "-o", str(bag), "--format", "json")
    wait_for(lambda: publisher.get_subscription_count() > 0, STARTUP_TIMEOUT_S)
    published = [f"chatter {i}" for i in range(150)]
    for text in published:
        publisher.publish(String(data=text))
        time.sleep(0.005)
    assert publisher.wait_for_all_acked(Duration(seconds=10))  # in the recorder
    proc.send_signal(signal.SIGINT)
    stdout, stderr = proc.communicate(timeout=20)
    assert proc.returncode == 130, stderr.decode()
    report = report_json(stdout)
    assert report["messages"] == 150
    assert report["lost"] == 0
    assert (bag / "metadata.yaml").is_file()
    assert texts(bag, "/cli/chatter") == published
    with BagReader(bag) as reader:
        assert reader.problems == []
        assert reader.message_count == 150


def test_sigkill_keeps_all_but_the_last_second(
    node: Node, processes: object, tmp_path: Path
) -> None:
    publisher = node.create_publisher(String, "/cli/killed", 100)
    bag = tmp_path / "killed"
    proc = record(processes, "/cli/killed", "-o", str(bag))
    wait_for(lambda: publisher.get_subscription_count() > 0, STARTUP_TIMEOUT_S)
    sent: list[tuple[float, str]] = []
    start = time.monotonic()
    # For 4 s, and until over 150 messages went out more than two flush periods ago: a loaded
    # machine oversleeps each 10 ms, and would otherwise send too few to tell.
    while (
        time.monotonic() - start < 4.0
        or len(sent) <= 150
        or sent[150][0] > (time.monotonic() - 2 * FLUSH_PERIOD_S)
    ):
        text = f"killed {len(sent)}"
        publisher.publish(String(data=text))
        sent.append((time.monotonic(), text))
        time.sleep(0.01)
    killed_at = time.monotonic()
    os.killpg(proc.pid, signal.SIGKILL)
    proc.wait(timeout=10)
    assert not (bag / "metadata.yaml").exists()
    recorded = texts(bag, "/cli/killed")
    # The writer closes a chunk every FLUSH_PERIOD_S of its own time; a message also spends time
    # in DDS and in the hand-off before that clock sees it (over 1 s in all on a loaded CI run).
    older = [text for at, text in sent if at < killed_at - 2 * FLUSH_PERIOD_S]
    assert len(older) > 150
    assert recorded[: len(older)] == older
    assert recorded == [text for _, text in sent][: len(recorded)]


def test_split_bag_reads_back_as_one(node: Node, processes: object, tmp_path: Path) -> None:
    publisher = node.create_publisher(String, "/cli/split", 100)
    bag = tmp_path / "split"
    proc = record(
        processes,
        "-e",
        "^/cli/split$",
        "-o",
        str(bag),
        "--max-bag-duration",
        "1",
        "--format",
        "json",
    )
    wait_for(lambda: publisher.get_subscription_count() > 0, STARTUP_TIMEOUT_S)
    published = []
    start = time.monotonic()
    while time.monotonic() - start < 3.5:
        published.append(f"split {len(published)}")
        publisher.publish(String(data=published[-1]))
        time.sleep(0.01)
    assert publisher.wait_for_all_acked(Duration(seconds=10))  # in the recorder
    proc.send_signal(signal.SIGTERM)
    stdout, stderr = proc.communicate(timeout=20)
    assert proc.returncode == 143, stderr.decode()
    assert report_json(stdout)["messages"] == len(published)
    files = sorted(bag.glob("*.mcap"))
    assert [f.name for f in files] == [f"split_{i}.mcap" for i in range(len(files))]
    assert len(files) >= 3
    with BagReader(bag) as reader:
        log_times = [m.log_time for m in reader.messages()]
        assert reader.message_count == len(published)
    assert log_times == sorted(log_times)
    assert texts(bag, "/cli/split") == published


def test_full_disk_stops_with_one_line_and_keeps_what_was_written(
    node: Node, processes: object, tmp_path: Path
) -> None:
    publisher = node.create_publisher(String, "/cli/big", 100)
    bag = tmp_path / "full"
    proc = record(
        processes,
        "/cli/big",
        "-o",
        str(bag),
        "--compression-mode",
        "none",
        "--format",
        "json",
    )
    wait_for(lambda: publisher.get_subscription_count() > 0, STARTUP_TIMEOUT_S)
    # A file size limit makes writes fail (EFBIG) as a full disk does (ENOSPC). Set once the
    # middleware is up: its shared-memory segments are files too. Python ignores SIGXFSZ.
    # About 400 kB/s, one chunk per second: the first chunk fits under the limit, the second
    # or third does not.
    resource.prlimit(proc.pid, resource.RLIMIT_FSIZE, (700_000, 700_000))
    payload = "x" * 20_000
    for i in range(80):
        if proc.poll() is not None:
            break
        publisher.publish(String(data=f"{i:04d}{payload}"))
        time.sleep(0.05)
    stdout, stderr = proc.communicate(timeout=20)
    assert proc.returncode == 1
    lines = stderr.decode().strip().splitlines()
    assert lines[-1].startswith("error: cannot write") and "File too large" in lines[-1]
    assert sum(line.startswith("error") for line in lines) == 1
    report = report_json(stdout)
    topic = report["topics"][0]
    assert topic["write_failed"] > 0
    recorded = texts(bag, "/cli/big")
    assert len(recorded) == topic["messages"] > 5
    assert [int(t[:4]) for t in recorded] == list(range(len(recorded)))


def lost_in_error_line(stderr: bytes) -> int:
    """The lost count of the one ``error:`` line (``... (N messages lost)``)."""
    (line,) = [x for x in stderr.decode().splitlines() if x.startswith("error")]
    match = re.search(r"\(([\d,]+) messages? lost\)$", line)
    assert match, line
    return int(match.group(1).replace(",", ""))


@pytest.mark.parametrize(
    "case",
    [
        (700_000, 20_000, 10),  # ten messages make it to disk, a later chunk does not
        # Not even the first chunk fits, nor does metadata.yaml. The 40th message fills the
        # chunk (1 MiB; 39 do not), so writing fails only once every message was taken: with
        # larger ones it failed mid-burst, and the messages published after the recorder
        # stopped taking were never received, so never counted.
        (1_500, 26_500, 0),
    ],
)
def test_full_disk_loss_is_exact_in_the_error_line_the_report_and_the_bag(
    node: Node, processes: object, tmp_path: Path, case: tuple[int, int, int]
) -> None:
    limit, size, flushed_first = case
    reliable = QoSProfile(depth=1000, reliability=ReliabilityPolicy.RELIABLE)
    publisher = node.create_publisher(String, "/cli/exact", reliable)
    bag = tmp_path / "exact"
    proc = record(
        processes, "/cli/exact", "-o", str(bag), "--compression-mode", "none", "--format", "json"
    )
    wait_for(lambda: publisher.get_subscription_count() > 0, STARTUP_TIMEOUT_S)
    resource.prlimit(proc.pid, resource.RLIMIT_FSIZE, (limit, limit))
    published: list[str] = []

    def burst(count: int) -> None:
        for _ in range(count):
            published.append(f"{len(published):04d}" + os.urandom(size // 2).hex())
            publisher.publish(String(data=published[-1]))
        # Everything is in the recorder before its writer closes the chunk (after >= 0.5 s, or
        # at 1 MiB): a message published after a failure stopped it is not taken, nor counted.
        assert publisher.wait_for_all_acked(Duration(seconds=10))

    if flushed_first:
        burst(flushed_first)
        time.sleep(2.0)  # the writer flushes them: idle for half a second
    burst(40)
    stdout, stderr = proc.communicate(timeout=30)
    assert proc.returncode == 1, stderr.decode()
    report = report_json(stdout)
    with BagReader(bag, allow_empty=True) as reader:
        recorded = [
            deserialize_message(m.data, String).data for m in reader.messages(["/cli/exact"])
        ]
    assert recorded == published[: len(recorded)]
    assert len(recorded) >= flushed_first
    (topic,) = report["topics"]
    assert topic["messages"] == report["messages"] == len(recorded)
    assert topic["write_failed"] == report["lost"] == len(published) - len(recorded) > 0
    assert lost_in_error_line(stderr) == report["lost"]
    assert not (bag / "metadata.yaml.partial").exists()


def test_full_disk_at_start_exits_1_and_leaves_nothing(processes: object, tmp_path: Path) -> None:
    bag = tmp_path / "nothing"
    proc = record(
        processes,
        "-a",
        "-o",
        str(bag),
        # Room for the probe of tempfile (4 bytes), not for an MCAP header.
        preexec_fn=lambda: resource.setrlimit(resource.RLIMIT_FSIZE, (8, 8)),
    )
    _, stderr = proc.communicate(timeout=30)
    assert proc.returncode == 1, stderr.decode()
    (line,) = stderr.decode().strip().splitlines()
    assert line.startswith("error: cannot write") and "File too large" in line
    assert not bag.exists()


@pytest.mark.parametrize(
    ("args", "message"),
    [
        ([], "nothing to record"),
        (["-e", "("], "--regex '(' is not a valid regular expression"),
        (["-a", "--qos-profile-overrides-path", "/nonexistent.yaml"], "cannot read QoS overrides"),
    ],
)
def test_bad_options_exit_2_with_one_line(
    processes: object, tmp_path: Path, args: list[str], message: str
) -> None:
    proc = record(processes, "-o", str(tmp_path / "never"), *args)
    _, stderr = proc.communicate(timeout=20)
    assert proc.returncode == 2
    (line,) = stderr.decode().strip().splitlines()
    assert line.startswith("error: ") and message in line
    assert not (tmp_path / "never").exists()


def test_default_output_name_in_the_current_directory(processes: object, tmp_path: Path) -> None:
    # /cli/nothing never appears: --duration would not start; Ctrl-C finishes the bag, and the
    # named topic that never appeared is the error it ends with (exit 2, as a misspelt name).
    proc = record(processes, "/cli/nothing", cwd=tmp_path)
    wait_for(lambda: any(tmp_path.iterdir()), STARTUP_TIMEOUT_S)
    proc.send_signal(signal.SIGINT)
    _, stderr = proc.communicate(timeout=30)
    assert proc.returncode == 2, stderr.decode()
    assert "error: topic /cli/nothing never appeared on the graph" in stderr.decode()
    (bag,) = tmp_path.iterdir()
    assert re.fullmatch(r"rosbag2_\d{4}_\d{2}_\d{2}-\d{2}_\d{2}_\d{2}", bag.name)
    assert (bag / "metadata.yaml").is_file()
    assert (bag / f"{bag.name}_0.mcap").is_file()


def test_existing_or_unwritable_output_exits_2(processes: object, tmp_path: Path) -> None:
    existing = tmp_path / "existing"
    existing.mkdir()
    (existing / "keep.txt").write_text("mine")
    a_file = tmp_path / "a_file"
    a_file.write_text("")
    for output, message in ((existing, "already exists"), (a_file / "bag", "cannot create")):
        proc = record(processes, "-a", "-o", str(output))
        _, stderr = proc.communicate(timeout=20)
        assert proc.returncode == 2
        (line,) = stderr.decode().strip().splitlines()
        assert message in line
    assert (existing / "keep.txt").read_text() == "mine"


@pytest.mark.parametrize("user_profile", [False, True])
def test_record_gives_itself_a_large_receive_queue_unless_the_user_has_a_profile(
    node: Node, processes: object, tmp_path: Path, user_profile: bool
) -> None:
    # Fast DDS sizes a port file by its descriptors: 52 KB for the default 512, 1.3 MB for
    # bagkit's 65536. This test's own process has the default; both map each other's port.
    env = fastdds_files.environment(tmp_path, user_profile=user_profile)
    publisher = node.create_publisher(String, "/cli/queue", 100)
    bag = tmp_path / "queue"
    fastdds_files.remove_stale_ports()
    proc = record(processes, "/cli/queue", "-o", str(bag), "--format", "json", env=env)
    wait_for(lambda: publisher.get_subscription_count() > 0, STARTUP_TIMEOUT_S)
    for i in range(20):
        publisher.publish(String(data=f"q{i}"))
    assert publisher.wait_for_all_acked(Duration(seconds=10))  # in the recorder
    ports = fastdds_files.listened_port_sizes(proc.pid)
    proc.send_signal(signal.SIGINT)
    stdout, stderr = proc.communicate(timeout=20)
    assert proc.returncode == 130, stderr.decode()
    assert report_json(stdout)["messages"] == 20
    assert ports, "the recorder maps no shared-memory port"
    large = [size for size in ports.values() if size > 1_000_000]
    assert bool(large) is not user_profile, ports
