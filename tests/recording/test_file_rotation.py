"""Circular recording and the free-space guard of BagWriter: real files, a simulated disk."""

from __future__ import annotations

import os
from pathlib import Path
from types import SimpleNamespace

import pytest
import yaml

from bagkit.bag import BagReader, BagWriteError, BagWriter, TopicInfo, file_rotation
from bagkit.bag.errors import BagError
from bagkit.bag.file_rotation import FileRotation, FreeSpace

PAYLOAD = bytes(1000)


def write(bag: BagWriter, start: int, count: int) -> None:
    for i in range(start, start + count):
        bag.write("/t", PAYLOAD, log_time=1_000_000 + i * 1000, sequence=i)


def metadata(path: Path) -> dict[str, object]:
    info = yaml.safe_load((path / "metadata.yaml").read_text())["rosbag2_bagfile_information"]
    assert isinstance(info, dict)
    return info


def test_free_space_sizes() -> None:
    assert FreeSpace.parse("2GiB").bytes == 2 << 30
    assert FreeSpace.parse("500MB").bytes == 500_000_000
    assert FreeSpace.parse("1000").bytes == 1000
    assert FreeSpace.parse("5%").fraction == pytest.approx(0.05)
    for bad in ("", "2 parsecs", "100%", "-1G", "0%"):
        with pytest.raises(BagError, match=r"^min_free_space "):
            FreeSpace.parse(bad)


def test_circular_bag_keeps_the_newest_files_and_lists_only_them(tmp_path: Path) -> None:
    path = tmp_path / "circle"
    bag = BagWriter(
        path,
        compression="none",
        max_bag_size=20_000,
        chunk_size=4_000,
        rotation=FileRotation(max_files=2),
    ).open()
    bag.add_topic(TopicInfo("/t", "std_msgs/msg/String"), definition="string data\n")
    write(bag, 0, 200)
    bag.close()
    files = sorted(p.name for p in path.glob("*.mcap"))
    info = metadata(path)
    assert info["relative_file_paths"] == sorted(files, key=lambda n: int(n[7:-5]))
    assert len(files) == 2
    with BagReader(path) as reader:
        sequences = [m.sequence for m in reader.messages()]
    # The newest messages, none missing up to the last one written.
    assert sequences == list(range(sequences[0], 200))
    assert info["message_count"] == len(sequences)
    (topic,) = info["topics_with_message_count"]
    assert topic["message_count"] == len(sequences)


def test_free_space_floor_deletes_oldest_when_circular_else_stops(
    tmp_path: Path, monkeypatch: pytest.MonkeyPatch
) -> None:
    free = {"bytes": 10**9}

    def statvfs(_path: object) -> SimpleNamespace:
        return SimpleNamespace(f_bavail=free["bytes"], f_frsize=1, f_blocks=10**12)

    monkeypatch.setattr(file_rotation.os, "statvfs", statvfs)
    floor = FreeSpace.parse("1MB")
    circular = BagWriter(
        tmp_path / "circular",
        compression="none",
        max_bag_size=20_000,
        chunk_size=4_000,
        rotation=FileRotation(max_files=10, min_free=floor),
    ).open()
    circular.add_topic(TopicInfo("/t", "std_msgs/msg/String"), definition="string data\n")
    write(circular, 0, 100)
    circular.flush()
    before = len(circular.files)
    assert before > 2
    free["bytes"] = 10  # the disk fills up: the oldest file goes at each chunk until it is over
    deleted: list[int] = []

    def unlink_then_free(path: Path, missing_ok: bool = False) -> None:
        os.remove(path)
        deleted.append(1)
        if len(deleted) == 2:
            free["bytes"] = 10**9

    monkeypatch.setattr(Path, "unlink", unlink_then_free)
    write(circular, 100, 10)
    circular.flush()
    assert len(deleted) == 2
    circular.close()
    assert len(metadata(tmp_path / "circular")["relative_file_paths"]) == before - 2
    free["bytes"] = 10
    plain = BagWriter(
        tmp_path / "plain",
        compression="none",
        chunk_size=4_000,
        rotation=FileRotation(min_free=floor),
    ).open()
    plain.add_topic(TopicInfo("/t", "std_msgs/msg/String"), definition="string data\n")
    attempted = 0
    with pytest.raises(BagWriteError, match="less than 1MB free: stopped") as failed:
        for i in range(10):
            attempted += 1
            write(plain, i, 1)
    # Stopped at the first chunk: every message of it is counted lost, no more.
    assert failed.value.messages_lost == attempted
    plain.close()  # what was written (nothing here) stays readable
    with BagReader(tmp_path / "plain", allow_empty=True) as reader:
        assert reader.message_count == 0
