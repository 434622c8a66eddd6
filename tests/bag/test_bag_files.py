"""bagkit.bag.bag_files: compressors, file entries and metadata totals, the rosbag2 record."""

from __future__ import annotations

import itertools
from pathlib import Path

import lz4.frame
import pytest
import yaml
import zstandard
from mcap.reader import make_reader

from bagkit.bag import BagError, BagWriter, TopicInfo
from bagkit.bag.bag_files import bag_metadata, compressor
from bagkit.bag.metadata import FileInformation

STRING = "std_msgs/msg/String"
# Without a size limit: each frame must declare its size, as the ``mcap`` package's reader needs.
DECOMPRESS = {
    "zstd": lambda data: zstandard.ZstdDecompressor().decompress(data),
    "lz4": lz4.frame.decompress,
    "": lambda data: data,
}


@pytest.mark.parametrize("compression", ["zstd", "lz4", "none"])
@pytest.mark.parametrize("cuts", [[], [13], [1, 5000, 9000]])
def test_compressors_round_trip_with_their_reference_decoders(
    compression: str, cuts: list[int]
) -> None:
    name, compress = compressor(compression)
    records = bytearray(b"some records " * 1000)
    bounds = [0, *cuts, len(records)]
    pieces = [bytes(records[a:b]) for a, b in itertools.pairwise(bounds)]
    assert name == ("" if compression == "none" else compression)
    assert DECOMPRESS[name](b"".join(compress(pieces))) == records
    if compression == "lz4":
        assert lz4.frame.get_frame_info(b"".join(compress(pieces)))["content_size"] == len(records)


def test_unknown_compression_is_a_bag_error() -> None:
    with pytest.raises(BagError, match="choose from zstd, lz4, none"):
        compressor("gzip")


def test_metadata_spans_the_files_with_messages() -> None:
    files = [
        FileInformation(path="b_0.mcap", starting_time=100, duration=50, message_count=3),
        FileInformation(path="b_1.mcap", starting_time=0, duration=0, message_count=0),
        FileInformation(path="b_2.mcap", starting_time=140, duration=60, message_count=2),
    ]
    topic = TopicInfo("/a", STRING)
    metadata = bag_metadata(files, [(topic, 5)], {"robot": "r2"})
    assert metadata.relative_file_paths == ["b_0.mcap", "b_1.mcap", "b_2.mcap"]
    # the empty file's time 0 does not pull the start back
    assert (metadata.starting_time, metadata.duration) == (100, 200 - 100)
    assert metadata.message_count == 5
    assert metadata.custom_data == {"robot": "r2"}


def test_each_file_carries_rosbag2_metadata_matching_its_metadata_yaml(tmp_path: Path) -> None:
    with BagWriter(tmp_path / "bag", max_bag_size=1) as bag:  # one message per file
        bag.add_topic(TopicInfo("/a", STRING))
        for i in range(3):
            bag.write("/a", b"\x00\x01\x00\x00\x02\x00\x00\x00x\x00", log_time=1_000 + i)
    on_disk = yaml.safe_load((tmp_path / "bag" / "metadata.yaml").read_text())
    info = on_disk["rosbag2_bagfile_information"]
    last = sorted((tmp_path / "bag").glob("*.mcap"))[-1]
    with open(last, "rb") as f:
        (record,) = [m for m in make_reader(f).iter_metadata() if m.name == "rosbag2"]
    embedded = yaml.safe_load(record.metadata["serialized_metadata"])
    # the last file's record is written with every file known, as metadata.yaml is
    assert embedded["message_count"] == info["message_count"] == 3
    assert embedded["relative_file_paths"] == info["relative_file_paths"]
    # a file before a split describes itself alone (linear, not quadratic, in the file count)
    for name in info["relative_file_paths"][:-1]:
        with open(tmp_path / "bag" / name, "rb") as f:
            (record,) = [m for m in make_reader(f).iter_metadata() if m.name == "rosbag2"]
        own = yaml.safe_load(record.metadata["serialized_metadata"])
        assert own["relative_file_paths"] == [name]
        assert own["message_count"] == 1
        assert [t["message_count"] for t in own["topics_with_message_count"]] == [1]


def test_split_files_grow_linearly_with_their_count(tmp_path: Path) -> None:
    """A bag split after every message: twice the messages, twice the bytes (not four times)."""
    sizes = []
    for count in (200, 400):
        with BagWriter(tmp_path / str(count), max_bag_size=1, compression="none") as bag:
            bag.add_topic(TopicInfo("/a", STRING))
            for i in range(count):
                bag.write("/a", b"\x00\x01\x00\x00\x02\x00\x00\x00x\x00", log_time=1_000 + i)
        files = list((tmp_path / str(count)).glob("*.mcap"))
        assert len(files) == count
        sizes.append(sum(f.stat().st_size for f in files))
    assert sizes[1] < 2.1 * sizes[0]
