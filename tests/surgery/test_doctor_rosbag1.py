"""``bagkit doctor`` of ROS 1 bags written by rosbags: each chunk walked record by record
against the bag's index (chunk infos, index data, connections), every message decoded with
``--deep``; a damaged index is one problem line, a bag without a readable index one error."""

from __future__ import annotations

import json
import struct
import subprocess
from pathlib import Path

import pytest
from bagkit_runs import bagkit_in_process
from rosbags.rosbag1 import Reader
from rosbags.rosbag1.reader import Header, RecordType

from tests.bag.ros1_samples import write_ros1_bag


def _doctor(*args: str | Path) -> subprocess.CompletedProcess[str]:
    """``bagkit doctor ARGS`` in this process (tests/bagkit_runs.py)."""
    return bagkit_in_process(["doctor", *args])


def _first_index_entry(path: Path) -> tuple[int, int]:
    """(byte of the first index-data entry's offset field, its chunk's position)."""
    with Reader(path) as reader:
        chunk = reader.chunk_infos[0].pos
    with path.open("rb") as f:
        f.seek(chunk)
        Header.read(f, RecordType.CHUNK)
        (size,) = struct.unpack("<I", f.read(4))
        f.seek(size, 1)
        Header.read(f, RecordType.IDXDATA)
        f.read(4)  # the entries' length
        return f.tell() + 8, chunk  # sec, nsec, then the offset


@pytest.mark.parametrize("compression", ["none", "lz4", "bz2"])
def test_rosbags_bags_are_healthy_and_decode(tmp_path: Path, compression: str) -> None:
    bag = write_ros1_bag(tmp_path / "ok.bag", 120, compression=compression, chunk_threshold=4096)
    with Reader(bag) as reader:
        count = reader.message_count
    done = _doctor("--deep", bag)
    assert done.returncode == 0, done.stdout + done.stderr
    assert done.stdout.strip().endswith(f"healthy ({count} messages in 1 file, all decoded)")


def test_an_index_entry_at_no_message_is_a_problem(tmp_path: Path) -> None:
    bag = write_ros1_bag(tmp_path / "bad.bag", 120, chunk_threshold=4096)
    where, chunk = _first_index_entry(bag)
    data = bytearray(bag.read_bytes())
    (offset,) = struct.unpack_from("<I", data, where)
    struct.pack_into("<I", data, where, offset + 1)
    bag.write_bytes(bytes(data))
    done = _doctor(bag, "--format", "json")
    assert done.returncode == 1, done.stdout + done.stderr
    problems = [p["problem"] for p in json.loads(done.stdout)["problems"]]
    assert len(problems) == 1, problems
    assert problems[0].startswith(f"chunk at byte {chunk}: holds "), problems
    assert "(1 at no message)" in problems[0]


def test_a_bag_without_a_readable_index_is_one_error(tmp_path: Path) -> None:
    bag = write_ros1_bag(tmp_path / "cut.bag", 120, chunk_threshold=4096)
    bag.write_bytes(bag.read_bytes()[:-200])
    done = _doctor(bag)
    assert done.returncode == 2, done.stdout + done.stderr
    (line,) = done.stderr.strip().splitlines()
    assert line.startswith("error: ") and "index" in line
