"""``bagkit info``: table, JSON, salvaged bags and bad input; in this process
(tests/bagkit_runs.py), as a subprocess where the process is the point (its imports, the table
as a terminal of 80 columns gets it)."""

from __future__ import annotations

import json
import os
import sqlite3
import subprocess
import sys
from pathlib import Path

import pytest
from bagkit_runs import bagkit_in_process
from mcap.reader import make_reader
from ros2_messages import STRING, TYPESTORE, qos_yaml

from bagkit.bag import BagWriter, TopicInfo

BAGKIT = str(Path(sys.executable).with_name("bagkit"))
QOS = qos_yaml(depth=5, reliability="best_effort", durability="transient_local")
START = 1_763_850_000_000_000_000


def _run(*args: str) -> subprocess.CompletedProcess[str]:
    return bagkit_in_process(["info", *args], env={"COLUMNS": "200"})


@pytest.fixture
def two_topic_bag(tmp_path: Path) -> Path:
    """/fast: 201 messages at 20 Hz over 10 s; /slow: 11 at 1 Hz; two files."""
    path = tmp_path / "drive"
    with BagWriter(path, max_bag_duration_ns=6_000_000_000) as bag:
        bag.add_topic(TopicInfo("/fast", STRING, offered_qos_profiles=QOS))
        bag.add_topic(TopicInfo("/slow", STRING))
        for i in range(201):
            data = bytes(TYPESTORE.serialize_cdr(TYPESTORE.types[STRING](data=f"{i}"), STRING))
            bag.write("/fast", data, log_time=START + i * 50_000_000)
            if i % 20 == 0:
                bag.write("/slow", data, log_time=START + i * 50_000_000 + 1)
    return path


def test_info_imports_no_numpy_sqlite_or_command_modules(two_topic_bag: Path) -> None:
    """What keeps `bagkit info` within 0.15 s of `python -c pass` (benchmarks/bench_startup)."""
    done = subprocess.run(
        [sys.executable, "-X", "importtime", BAGKIT, "info", str(two_topic_bag)],
        capture_output=True,
        text=True,
        timeout=60,
        check=False,
    )
    assert done.returncode == 0, done.stderr
    imported = {line.split("|")[-1].strip() for line in done.stderr.splitlines()}
    assert "bagkit.bag.info" in imported  # the check sees what ran
    assert not imported & {"numpy", "sqlite3", "pandas", "dask", "rosbags", "bagkit.cli.stats"}
    assert "/fast" in done.stdout


def test_json_reports_the_bag(two_topic_bag: Path) -> None:
    result = _run(str(two_topic_bag), "--format", "json")
    assert result.returncode == 0, result.stderr
    info = json.loads(result.stdout)
    files = [str(two_topic_bag / "drive_0.mcap"), str(two_topic_bag / "drive_1.mcap")]
    assert info["files"] == files
    assert info["path"] == str(two_topic_bag)
    assert info["storage"] == "mcap"
    assert info["size_bytes"] == sum(Path(f).stat().st_size for f in files)
    assert info["start_ns"] == START
    assert info["end_ns"] == START + 200 * 50_000_000 + 1
    assert info["duration_s"] == pytest.approx(10.000000001)
    assert info["message_count"] == 212
    topics = {t["topic"]: t for t in info["topics"]}
    assert topics["/fast"] == {
        "topic": "/fast",
        "type": STRING,
        "count": 201,
        # 200 intervals of 50 ms between the first and the last message.
        "rate_hz": pytest.approx(200 / (200 * 0.05), rel=1e-9),
        "serialization_format": "cdr",
        "offered_qos_profiles": QOS,
    }
    assert topics["/slow"]["count"] == 11
    assert topics["/slow"]["rate_hz"] == pytest.approx(10 / (200 * 0.05), rel=1e-9)
    assert info["compression"] == "zstd"
    assert info["compression_ratio"] > 1.0
    assert info["summary"] is True
    assert info["problems"] == []


def test_table_is_for_people(two_topic_bag: Path) -> None:
    result = _run(str(two_topic_bag))
    assert result.returncode == 0, result.stderr
    out = result.stdout
    assert "drive_0.mcap" in out and "drive_1.mcap" in out
    assert "212" in out
    assert "10.000000001s" in out
    assert "best_effort, transient_local, keep_last(5)" not in out
    assert "20.00 Hz" in out
    verbose = _run(str(two_topic_bag), "-v").stdout
    assert "/fast: cdr, best_effort, transient_local, keep_last(5)" in verbose


def test_rate_is_the_one_stats_summary_reports(tmp_path: Path) -> None:
    """info and stats summary: (count - 1) / (last - first), "-" with one message."""
    path = tmp_path / "rates"
    data = bytes(TYPESTORE.serialize_cdr(TYPESTORE.types[STRING](data="x"), STRING))
    with BagWriter(path) as bag:
        bag.add_topic(TopicInfo("/ten_hz", STRING))
        bag.add_topic(TopicInfo("/once", STRING))
        for i in range(31):  # 10 Hz with jitter, over a bag longer than the topic
            bag.write("/ten_hz", data, log_time=START + i * 100_000_000 + (i % 3) * 1_000_000)
        bag.write("/once", data, log_time=START + 5_000_000_000)
    info = {t["topic"]: t for t in json.loads(_run(str(path), "--format", "json").stdout)["topics"]}
    stats = bagkit_in_process(["stats", "summary", path, "--format", "json"])
    assert stats.returncode == 0, stats.stderr
    by_stats = {t["topic"]: t["rate_hz"] for t in json.loads(stats.stdout)["topics"]}
    last = 30 * 100_000_000 + (30 % 3) * 1_000_000
    assert info["/ten_hz"]["rate_hz"] == by_stats["/ten_hz"] == pytest.approx(30 / (last / 1e9))
    assert info["/once"]["rate_hz"] is None and by_stats["/once"] is None
    table = _run(str(path)).stdout
    once = next(line for line in table.splitlines() if "/once" in line)
    assert once.split()[-1] == "-"


def test_info_options_of_ros2_bag(two_topic_bag: Path, tmp_path: Path) -> None:
    names = _run("-t", str(two_topic_bag))
    assert names.returncode == 0, names.stderr
    assert names.stdout.splitlines() == ["/fast", "/slow"]
    assert _run("--topic-name", str(two_topic_bag)).stdout == names.stdout
    assert _run("-s", "mcap", str(two_topic_bag)).returncode == 0
    wrong = _run("-s", "sqlite3", str(two_topic_bag))
    assert wrong.returncode == 2
    assert wrong.stderr.strip() == f"error: {two_topic_bag} is a mcap bag, not sqlite3"
    unknown = _run("--storage", "hdf5", str(two_topic_bag))
    assert unknown.returncode == 2 and "hdf5" in unknown.stderr
    for help_flag in ("-h", "--help"):
        helped = _run(help_flag)
        assert helped.returncode == 0 and "--topic-name" in helped.stdout
    # --format has no short form: -f is --fields wherever it exists.
    assert _run("-f", "json", str(two_topic_bag)).returncode == 2


def test_table_fits_80_columns_with_topic_names_whole(tmp_path: Path) -> None:
    path = tmp_path / "narrow"
    names = [
        "/vehicle/front_left_camera/image_rect_color/compressed",
        "/perception/obstacle_tracker/tracked_objects",
        "/x",
    ]
    data = bytes(TYPESTORE.serialize_cdr(TYPESTORE.types[STRING](data="x"), STRING))
    with BagWriter(path) as bag:
        for name in names:
            bag.add_topic(TopicInfo(name, STRING, offered_qos_profiles=QOS))
            for i in range(3):
                bag.write(name, data, log_time=START + i * 10_000_000)
        long_json = json.dumps({f"/topic/{i}": {"messages": i, "gaps": 0} for i in range(30)})
        bag.custom_data["bagkit.record.loss"] = long_json
    env = {**os.environ, "COLUMNS": "80"}
    for extra in ([], ["-v"]):
        out = subprocess.run(
            [BAGKIT, "info", str(path), *extra],
            capture_output=True,
            text=True,
            timeout=60,
            check=True,
            env=env,
        ).stdout
        lines = out.splitlines()
        assert all(len(line) <= 80 for line in lines), out
        for name in names:
            assert any(name in line.split() for line in lines), (name, out)
        loss_lines = [line for line in lines if "bagkit.record.loss" in line]
        assert len(loss_lines) == 1
        # The long custom_data key does not push the other values into two lines each.
        (start,) = [line for line in lines if line.startswith("Start:")]
        assert start.endswith(f"({START // 10**9}.{START % 10**9:09d})"), out
    assert "JSON, 30 entries" in _run(str(path)).stdout


def test_salvaged_bag_is_reported_with_its_problem(two_topic_bag: Path, tmp_path: Path) -> None:
    crashed = tmp_path / "crashed"
    crashed.mkdir()
    data = (two_topic_bag / "drive_0.mcap").read_bytes()
    (crashed / "crashed_0.mcap").write_bytes(data[: len(data) // 2])
    result = _run(str(crashed), "--format", "json")
    assert result.returncode == 0, result.stderr
    info = json.loads(result.stdout)
    assert info["summary"] is False
    assert 0 < info["message_count"] < 212
    assert len(info["problems"]) == 1
    assert "crashed_0.mcap: truncated at byte" in info["problems"][0]
    assert "warning: crashed_0.mcap: truncated at byte" in result.stderr


@pytest.mark.parametrize(
    ("make", "message"),
    [
        (lambda p: p / "missing", "no such file"),
        (lambda p: (p / "notes.mcap").write_text("not a bag") and p / "notes.mcap", "not"),
        (lambda p: (p / "emptydir").mkdir() or p / "emptydir", "not a bag"),
    ],
)
def test_unusable_input_exits_2_with_one_line(tmp_path: Path, make: object, message: str) -> None:
    target = make(tmp_path)  # type: ignore[operator]
    result = _run(str(target))
    assert result.returncode == 2
    assert result.stdout == ""
    lines = result.stderr.strip().splitlines()
    assert len(lines) == 1, result.stderr
    assert lines[0].startswith("error:") and message in lines[0]
    assert "Traceback" not in result.stderr


def test_foreign_storage(tmp_path: Path) -> None:
    foreign = tmp_path / "foreign"
    foreign.mkdir()
    (foreign / "metadata.yaml").write_text(
        "rosbag2_bagfile_information:\n  version: 5\n  storage_identifier: hdf5\n"
        "  relative_file_paths: [foreign_0.h5]\n"
    )
    result = _run(str(foreign))
    assert result.returncode == 2
    assert "hdf5" in result.stderr and "not supported" in result.stderr


def test_empty_bag_lists_its_topics_with_count_0(interop_dir: Path) -> None:
    bag_dir = interop_dir / "ros2bag/test/resources/empty_bag"
    result = _run(str(bag_dir), "--format", "json")
    assert result.returncode == 0 and result.stderr == "", result.stderr
    info = json.loads(result.stdout)
    db = sqlite3.connect(f"file:{bag_dir / 'empty_bag_0.db3'}?mode=ro&immutable=1", uri=True)
    stored = dict(db.execute("SELECT name, type FROM topics"))
    db.close()
    assert {t["topic"]: (t["type"], t["count"]) for t in info["topics"]} == {
        name: (type_name, 0) for name, type_name in stored.items()
    }
    assert info["message_count"] == 0


def _storage_counts(bag_dir: Path) -> dict[str, int]:
    """Messages per topic as the storage files hold them (mcap library, or sqlite3)."""
    counts: dict[str, int] = {}
    for file in sorted(bag_dir.iterdir()):
        if file.suffix == ".mcap":
            with open(file, "rb") as f:
                for _, channel, _ in make_reader(f).iter_messages():
                    counts[channel.topic] = counts.get(channel.topic, 0) + 1
        elif file.suffix == ".db3":
            db = sqlite3.connect(f"file:{file}?mode=ro&immutable=1", uri=True)
            for (name,) in db.execute("SELECT name FROM topics"):
                counts.setdefault(name, 0)
            query = "SELECT t.name, COUNT(*) FROM messages m JOIN topics t ON m.topic_id = t.id"
            for name, count in db.execute(query + " GROUP BY t.name"):
                counts[name] += count
            db.close()
    return counts


def _storage_times(bag_dir: Path) -> dict[str, tuple[int, int]]:
    """First and last log time per topic as the storage files hold them."""
    times: dict[str, list[int]] = {}
    for file in sorted(bag_dir.iterdir()):
        if file.suffix == ".mcap":
            with open(file, "rb") as f:
                for _, channel, message in make_reader(f).iter_messages():
                    times.setdefault(channel.topic, []).append(message.log_time)
        elif file.suffix == ".db3":
            db = sqlite3.connect(f"file:{file}?mode=ro&immutable=1", uri=True)
            query = "SELECT t.name, m.timestamp FROM messages m JOIN topics t ON m.topic_id = t.id"
            for name, stamp in db.execute(query):
                times.setdefault(name, []).append(stamp)
            db.close()
    return {topic: (min(t), max(t)) for topic, t in times.items()}


@pytest.mark.parametrize(
    "relative",
    [
        "rosbag2_py/test/resources/mcap/wbag",  # Go-written, split in five files
        "rosbag2_py/test/resources/sqlite3/talker",
        "rosbag2_tests/resources/mcap/wrong_rmw_test",
    ],
)
def test_interop_bags(interop_dir: Path, relative: str) -> None:
    result = _run(str(interop_dir / relative), "--format", "json")
    assert result.returncode == 0, result.stderr
    info = json.loads(result.stdout)
    expected = _storage_counts(interop_dir / relative)
    assert sum(expected.values()) > 0
    counted = {t["topic"]: t["count"] for t in info["topics"]}
    assert {t: c for t, c in counted.items() if c or t in expected} == expected
    assert info["message_count"] == sum(expected.values())
    for topic in info["topics"]:
        first_last = _storage_times(interop_dir / relative).get(topic["topic"])
        # A rate needs three messages over a second at least (two 1.4 ms apart are no 732 Hz).
        if topic["count"] >= 3 and first_last and first_last[1] - first_last[0] >= 1e9:
            expected_rate = (topic["count"] - 1) / ((first_last[1] - first_last[0]) / 1e9)
            assert topic["rate_hz"] == pytest.approx(expected_rate, rel=1e-9)
        else:
            assert topic["rate_hz"] is None
    if "wrong_rmw" in relative:
        assert {t["serialization_format"] for t in info["topics"]} == {"wrong_format"}


def test_an_empty_bag_has_no_start_or_end(tmp_path: Path) -> None:
    """Topics and no message: no time to show (the epoch, 1970, would pass for a recording)."""
    with BagWriter(tmp_path / "empty") as bag:
        bag.add_topic(TopicInfo("/chatter", STRING))
    result = _run(str(tmp_path / "empty"))
    assert result.returncode == 0, result.stderr
    fields = dict(line.split(":", 1) for line in result.stdout.splitlines()[:8] if ":" in line)
    assert (fields["Start"].strip(), fields["End"].strip()) == ("-", "-")
    assert fields["Messages"].strip() == "0" and "1970" not in result.stdout
