"""``bagkit filter`` and ``bagkit merge``: outputs equal to the selection rosbags makes.

Most runs are in the test's process (``run_here``); one per behaviour is a real ``bagkit``
process (``run``): a filter, a merge, and a refusal of each.
"""

from __future__ import annotations

import json
import re
import subprocess
from pathlib import Path

import pytest
import yaml
from bagkit_runs import bagkit_in_process
from mcap.reader import make_reader
from rosbags.highlevel import AnyReader
from surgery_samples import (
    IMU,
    QOS,
    START,
    STRING,
    TEMPERATURE,
    chunk_records,
    imu_cdr,
    key,
    mcap_messages,
    rosbags_messages,
    run,
    string_cdr,
    temperature_cdr,
    write_mixed_bag,
)

from bagkit.bag import BagWriter, TopicInfo
from bagkit.surgery import Selection, filter_bag
from bagkit.surgery.errors import SurgeryError
from bagkit.surgery.options import OutputOptions
from bagkit.surgery.output import OutputBag
from bagkit.surgery.sqlite3_output import Sqlite3OutputBag


def run_here(*args: str, cwd: Path | None = None) -> subprocess.CompletedProcess[str]:
    return bagkit_in_process(list(args), cwd or Path.cwd())


@pytest.fixture(scope="module")
def mixed(tmp_path_factory: pytest.TempPathFactory) -> Path:
    return write_mixed_bag(tmp_path_factory.mktemp("in") / "mixed")


def _expected(bag: Path, keep: object) -> list[tuple[str, int, bytes]]:
    return [m for m in rosbags_messages(bag) if keep(m)]  # type: ignore[operator]


CASES = [
    (["--topics", "/imu/data"], lambda m: m[0] == "/imu/data"),
    (["--topics", "/text,/temperature"], lambda m: m[0] in ("/text", "/temperature")),
    (["--topics", "/text", "--topics", "/imu/data"], lambda m: m[0] in ("/text", "/imu/data")),
    (["--topics", "/text", "/imu/data"], lambda m: m[0] in ("/text", "/imu/data")),
    (["--exclude-topics", "/imu/data", "/text"], lambda m: m[0] == "/temperature"),
    (["-e", "^/te"], lambda m: m[0].startswith("/te")),
    (["--exclude-topics", "/imu/data"], lambda m: m[0] != "/imu/data"),
    (["--exclude-regex", "t.xt|temp"], lambda m: not re.search("t.xt|temp", m[0])),
    (
        # Every topic of the mixed bag is transient-local: the latched state is tested apart.
        ["--start", f"{START + 5 * 10**9}ns", "--end", f"{START + 12 * 10**9}ns", "--no-latched"],
        lambda m: START + 5_000_000_000 <= m[1] < START + 12_000_000_000,
    ),
    (
        ["--topics", "/text", "--start", str((START + 3_000_000_000) / 1e9), "--no-latched"],
        lambda m: m[0] == "/text" and m[1] >= START + 3_000_000_000,
    ),
]


@pytest.mark.parametrize(("args", "keep"), CASES)
def test_filter_equals_rosbags_selection(
    mixed: Path, tmp_path: Path, args: list[str], keep: object
) -> None:
    out = tmp_path / "out"
    result = run_here("filter", str(mixed), "-o", str(out), *args, "--format", "json")
    assert result.returncode == 0, result.stderr
    expected = _expected(mixed, keep)
    assert expected  # the case selects something
    assert rosbags_messages(out) == expected
    assert mcap_messages(sorted(out.glob("*.mcap"))) == expected
    assert json.loads(result.stdout)["message_count"] == len(expected)


def test_several_topics_before_the_bag(mixed: Path, tmp_path: Path) -> None:
    out = tmp_path / "out"
    result = run("filter", "--topics", "/text", "/temperature", str(mixed), "-o", str(out))
    assert result.returncode == 0, result.stderr
    expected = _expected(mixed, lambda m: m[0] in ("/text", "/temperature"))
    assert mcap_messages(sorted(out.glob("*.mcap"))) == expected


@pytest.mark.parametrize("compression", ["none", "lz4", "zstd"])
def test_compression_and_split(mixed: Path, tmp_path: Path, compression: str) -> None:
    out = tmp_path / "out"
    size = 40_000
    result = run_here(
        "filter", str(mixed), "-o", str(out), "--compression", compression,
        "--max-bag-size", str(size), "--exclude-topics", "/temperature",
    )  # fmt: skip
    assert result.returncode == 0, result.stderr
    files = sorted(out.glob("*.mcap"), key=lambda p: int(p.stem.rsplit("_", 1)[1]))
    assert len(files) > 3
    expected = _expected(mixed, lambda m: m[0] != "/temperature")
    assert mcap_messages(files) == expected
    assert rosbags_messages(out) == expected
    metadata = yaml.safe_load((out / "metadata.yaml").read_text())["rosbag2_bagfile_information"]
    assert metadata["version"] == 9
    assert metadata["relative_file_paths"] == [f.name for f in files]
    assert metadata["message_count"] == len(expected)
    assert [f["message_count"] for f in metadata["files"]] == [
        len(mcap_messages([f])) for f in files
    ]
    for file in files[:-1]:
        # Split within one chunk of the limit, as ros2 bag does.
        assert file.stat().st_size < size + (20 << 10)
        with open(file, "rb") as f:
            summary = make_reader(f).get_summary()
            assert summary is not None
            assert {c.compression for c in summary.chunk_indexes} == {
                "" if compression == "none" else compression
            }


def test_split_by_duration(mixed: Path, tmp_path: Path) -> None:
    out = tmp_path / "out"
    result = run_here("filter", str(mixed), "-o", str(out), "-d", "4")
    assert result.returncode == 0, result.stderr
    files = sorted(out.glob("*.mcap"), key=lambda p: int(p.stem.rsplit("_", 1)[1]))
    assert len(files) >= 5  # 20 s of messages, split at chunk boundaries
    for file in files:
        times = [t for _, t, _ in mcap_messages([file])]
        assert max(times) - min(times) < 4_000_000_000
    assert rosbags_messages(out) == rosbags_messages(mixed)


def test_definitions_and_qos_carried_over(mixed: Path, tmp_path: Path) -> None:
    out = tmp_path / "out"
    filter_bag(mixed, out, Selection.create(["/text", "/imu/data"]))
    with AnyReader([mixed]) as original, AnyReader([out]) as copied:
        before = {c.topic: c for c in original.connections}
        after = {c.topic: c for c in copied.connections}
        assert set(after) == {"/text", "/imu/data"}
        for topic, connection in after.items():
            assert connection.msgtype == before[topic].msgtype
            assert connection.msgdef == before[topic].msgdef
            assert connection.digest == before[topic].digest
            assert connection.ext.offered_qos_profiles == before[topic].ext.offered_qos_profiles
    metadata = yaml.safe_load((out / "metadata.yaml").read_text())["rosbag2_bagfile_information"]
    qos = {
        t["topic_metadata"]["name"]: t["topic_metadata"]["offered_qos_profiles"]
        for t in metadata["topics_with_message_count"]
    }
    assert qos == {"/text": yaml.safe_load(QOS), "/imu/data": yaml.safe_load(QOS)}


def test_chunk_copied_as_stored(tmp_path: Path) -> None:
    """Every chunk of an unfiltered copy, and /imu/data-only chunks of a topic filter, are
    the input's Chunk records byte for byte."""

    bag = tmp_path / "alone"
    with BagWriter(bag, chunk_size=8 << 10) as writer:
        writer.add_topic(TopicInfo("/imu/data", IMU, offered_qos_profiles=QOS))
        writer.add_topic(TopicInfo("/text", STRING, offered_qos_profiles=QOS))
        for i in range(300):  # IMU alone: its own chunks
            writer.write("/imu/data", imu_cdr(i), log_time=START + i)
        writer.flush()
        for i in range(300, 400):  # then mixed chunks (no two messages at one time: a chunk
            # that ends where the next begins is merged, not copied, to keep ties in order)
            writer.write("/imu/data", imu_cdr(i), log_time=START + 2 * i)
            writer.write("/text", string_cdr(str(i)), log_time=START + 2 * i + 1)
    source_chunks = chunk_records(next(bag.glob("*.mcap")))
    copy = tmp_path / "copy"
    assert run_here("filter", str(bag), "-o", str(copy)).returncode == 0
    assert chunk_records(next(copy.glob("*.mcap"))) == source_chunks
    imu = tmp_path / "imu"
    assert run_here("filter", str(bag), "-o", str(imu), "--topics", "/imu/data").returncode == 0
    copied = chunk_records(next(imu.glob("*.mcap")))
    imu_only = [c for c in source_chunks if c in copied]
    assert len(imu_only) >= 3  # the IMU-only chunks, not rebuilt
    assert not any(c in copied for c in source_chunks[-2:])  # mixed chunks are rebuilt
    assert rosbags_messages(imu) == [m for m in rosbags_messages(bag) if m[0] == "/imu/data"]
    # Recompressing is asked for: nothing is copied as stored.
    lz4 = tmp_path / "lz4"
    assert run_here("filter", str(bag), "-o", str(lz4), "--compression", "lz4").returncode == 0
    assert not set(chunk_records(next(lz4.glob("*.mcap")))) & set(source_chunks)
    assert rosbags_messages(lz4) == rosbags_messages(bag)


def test_merge_interleaved_equals_sorted_union(tmp_path: Path) -> None:
    a = write_mixed_bag(tmp_path / "a", 600)
    b = write_mixed_bag(tmp_path / "b", 500, offset_ns=3_333_333, step_ns=13_000_000)
    out = tmp_path / "merged"
    result = run_here("merge", str(a), str(b), "-o", str(out), "--format", "json")
    assert result.returncode == 0, result.stderr
    union = sorted(rosbags_messages(a) + rosbags_messages(b), key=key)
    merged = mcap_messages(sorted(out.glob("*.mcap")))
    assert merged == union
    assert sorted(rosbags_messages(out), key=key) == union
    # Stored in log-time order, as mcap merge writes it.
    with AnyReader([out]) as reader:
        times = [t for _, t, _ in reader.messages()]
    assert times == sorted(times)
    assert json.loads(result.stdout)["message_count"] == len(union)


def test_merge_of_consecutive_bags_copies_their_chunks(tmp_path: Path) -> None:
    a = write_mixed_bag(tmp_path / "a", 500)
    b = write_mixed_bag(tmp_path / "b", 500, offset_ns=10_000_000_000)
    out = tmp_path / "merged"
    assert run("merge", str(b), str(a), "-o", str(out)).returncode == 0
    stored = chunk_records(next(a.glob("*.mcap"))) + chunk_records(next(b.glob("*.mcap")))
    assert chunk_records(next(out.glob("*.mcap"))) == stored
    assert rosbags_messages(out) == rosbags_messages(a) + rosbags_messages(b)


def test_merge_refuses_a_topic_with_two_types(tmp_path: Path) -> None:

    a, b = tmp_path / "a", tmp_path / "b"
    with BagWriter(a) as writer:
        writer.add_topic(TopicInfo("/x", STRING))
        writer.write("/x", string_cdr("x"), log_time=START)
    with BagWriter(b) as writer:
        writer.add_topic(TopicInfo("/x", TEMPERATURE))
        writer.write("/x", temperature_cdr(1), log_time=START)
    result = run("merge", str(a), str(b), "-o", str(tmp_path / "out"))
    assert result.returncode == 2
    assert result.stderr.startswith("error: /x has type std_msgs/msg/String in one input")
    assert len(result.stderr.splitlines()) == 1
    assert sorted(p.name for p in tmp_path.iterdir()) == ["a", "b"]


def test_output_is_never_half_written_nor_overwritten(mixed: Path, tmp_path: Path) -> None:
    out = tmp_path / "out"
    out.mkdir()
    (out / "keep.txt").write_text("mine")
    result = run("filter", str(mixed), "-o", str(out))
    assert result.returncode == 2
    assert result.stderr == f"error: {out} already exists (use --force to replace it)\n"
    assert [p.name for p in out.iterdir()] == ["keep.txt"]
    for bad in (["--compression", "brotli"], ["--topics", "/nothing"], ["-e", "[a"]):
        result = run_here("filter", str(mixed), "-o", str(tmp_path / "new"), *bad)
        assert result.returncode == 2, bad
        assert result.stderr.startswith("error: ") and len(result.stderr.splitlines()) == 1
        assert "Traceback" not in result.stderr
    assert sorted(p.name for p in tmp_path.iterdir()) == ["out"]  # no partial output left
    result = run_here("filter", str(mixed), "-o", str(out), "--force")
    assert result.returncode == 2
    assert result.stderr.startswith(f"error: {out} is not a bag directory (it holds keep.txt)")
    assert [p.name for p in out.iterdir()] == ["keep.txt"]
    (out / "keep.txt").unlink()
    for _ in range(2):  # an empty directory, then the bag written there, are replaced
        result = run_here("filter", str(mixed), "-o", str(out), "--force", "--topics", "/text")
        assert result.returncode == 0, result.stderr
        assert {m[0] for m in rosbags_messages(out)} == {"/text"}
    result = run_here("filter", str(mixed), "-o", str(mixed / "inside"))
    assert result.returncode == 2
    assert "overlap" in result.stderr


def test_force_replaces_bags_only_and_never_the_working_directory(
    mixed: Path, tmp_path: Path
) -> None:
    here = tmp_path / "here"  # the working directory, holding only bag-like files
    here.mkdir()
    (here / "notes.mcap").write_text("mine")
    other = tmp_path / "other"
    other.mkdir()
    (other / "notes.txt").write_text("mine")
    for name in ["", ".", "..", str(here), str(tmp_path), "../other"]:
        result = run_here("filter", str(mixed), "-o", name, "--force", cwd=here)
        assert result.returncode == 2, name
        assert result.stderr.startswith("error: ") and len(result.stderr.splitlines()) == 1
    assert (here / "notes.mcap").read_text() == (other / "notes.txt").read_text() == "mine"
    assert sorted(p.name for p in tmp_path.iterdir()) == ["here", "other"]  # nothing partial


def test_output_errors_name_the_options_fields(tmp_path: Path) -> None:
    """The library names OutputOptions' fields; the CLI (above) names their flags."""
    taken = tmp_path / "taken"
    taken.mkdir()
    with pytest.raises(SurgeryError) as raised:
        OutputBag(taken)
    assert raised.value.field == "output.force"
    asks = [
        (OutputOptions(), "output.force"),
        (OutputOptions(force=True, compression="lz4"), "output.compression"),
        (OutputOptions(force=True, max_bag_size=1 << 20), "output.max_bag_size, "),
    ]
    for options, field in asks:
        with pytest.raises(SurgeryError) as raised:
            Sqlite3OutputBag(taken, options)
        assert (raised.value.field or "").startswith(field), options
    assert [p.name for p in tmp_path.iterdir()] == ["taken"]
