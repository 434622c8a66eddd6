"""Split bags: by size and by duration, listed in metadata.yaml, read back as one bag."""

from __future__ import annotations

from collections.abc import Callable
from pathlib import Path

import yaml
from bag_samples import TYPESTORE
from mcap.reader import make_reader
from rosbags.highlevel import AnyReader

from bagkit.bag import BagReader


def _metadata(bag_path: Path) -> dict:
    return yaml.safe_load((bag_path / "metadata.yaml").read_text())["rosbag2_bagfile_information"]


def test_split_by_size_lists_every_file_and_reads_as_one_bag(
    write_sample_bag: Callable[..., Path],
) -> None:
    bag_path = write_sample_bag(
        n_imu=600, max_bag_size=40_000, chunk_size=8_000, compression="none"
    )
    info = _metadata(bag_path)
    names = [f"sample_{i}.mcap" for i in range(len(info["files"]))]
    assert len(names) >= 3
    assert info["relative_file_paths"] == names
    assert sorted(p.name for p in bag_path.glob("*.mcap")) == sorted(names)
    per_file = []
    for name in names:
        with open(bag_path / name, "rb") as f:
            summary = make_reader(f).get_summary()
        assert summary is not None and summary.statistics is not None
        per_file.append(summary.statistics.message_count)
    assert [f["message_count"] for f in info["files"]] == per_file
    assert sum(per_file) == info["message_count"] == 660
    # Files close near the size limit: one chunk (8 kB uncompressed) of slack at most.
    for name in names[:-1]:
        assert (bag_path / name).stat().st_size < 40_000 + 8_000 + 4_000

    with BagReader(bag_path) as bag:
        assert bag.files == [bag_path / n for n in names]
        assert bag.topic_counts == {"/imu/data": 600, "/text": 60}
        messages = list(bag.messages())
    assert [m.sequence for m in messages if m.topic == "/imu/data"] == list(range(600))
    log_times = [m.log_time for m in messages]
    assert log_times == sorted(log_times)

    with AnyReader([bag_path], default_typestore=TYPESTORE) as reader:
        assert sum(1 for _ in reader.messages()) == 660


def test_split_by_duration(write_sample_bag: Callable[..., Path]) -> None:
    # 100 Hz for 3 s with 1 s files: 3 files of 100 Imu messages each.
    bag_path = write_sample_bag(n_imu=300, max_bag_duration_ns=1_000_000_000)
    info = _metadata(bag_path)
    assert [f["path"] for f in info["files"]] == ["sample_0.mcap", "sample_1.mcap", "sample_2.mcap"]
    assert [f["message_count"] for f in info["files"]] == [110, 110, 110]
    for f in info["files"]:
        assert f["duration"]["nanoseconds"] < 1_000_000_000
    with BagReader(bag_path) as bag:
        assert bag.message_count == 330
        assert [m.sequence for m in bag.messages(topics=["/imu/data"])] == list(range(300))


def test_directory_without_metadata_reads_files_in_natural_order(
    write_sample_bag: Callable[..., Path],
) -> None:
    bag_path = write_sample_bag(
        n_imu=1200, max_bag_size=20_000, chunk_size=4_000, compression="none"
    )
    (bag_path / "metadata.yaml").unlink()
    files = sorted(bag_path.glob("*.mcap"), key=lambda p: int(p.stem.split("_")[-1]))
    assert len(files) > 10  # sample_10 must come after sample_9
    with BagReader(bag_path) as bag:
        assert bag.files == files
        assert [m.sequence for m in bag.messages(topics=["/imu/data"])] == list(range(1200))


def test_file_listed_in_metadata_but_missing_is_a_problem(
    write_sample_bag: Callable[..., Path],
) -> None:
    bag_path = write_sample_bag(
        n_imu=600, max_bag_size=40_000, chunk_size=8_000, compression="none"
    )
    info = _metadata(bag_path)
    last = info["relative_file_paths"][-1]
    (bag_path / last).unlink()
    kept = sum(f["message_count"] for f in info["files"][:-1])
    with BagReader(bag_path) as bag:
        assert bag.message_count == kept
        assert bag.problems == [f"{last}: listed in metadata.yaml but missing"]


def test_relative_paths_prefixed_with_the_bag_name(write_sample_bag: Callable[..., Path]) -> None:
    # Early rosbag2 versions wrote relative_file_paths as "<bag>/<bag>_0.db3".
    bag_path = write_sample_bag(n_imu=50)
    document = yaml.safe_load((bag_path / "metadata.yaml").read_text())
    info = document["rosbag2_bagfile_information"]
    info["relative_file_paths"] = [f"sample/{name}" for name in info["relative_file_paths"]]
    (bag_path / "metadata.yaml").write_text(yaml.safe_dump(document))
    with BagReader(bag_path) as bag:
        assert bag.files == [bag_path / "sample_0.mcap"]
        assert bag.message_count == 55
        assert bag.problems == []
