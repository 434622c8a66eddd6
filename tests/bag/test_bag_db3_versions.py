"""SQLite3 bags in each metadata.yaml version 4 to 9 (and without one), the older versions
made from rosbags' version 8 output by taking out the keys each version added; read back
against rosbags' reader."""

from __future__ import annotations

from pathlib import Path

import pytest
import yaml
from rosbags.rosbag2 import Reader, Writer
from rosbags.typesys import Stores, get_typestore

from bagkit.bag import BagReader

STORE = get_typestore(Stores.ROS2_JAZZY)
T0 = 1_690_000_000_000_000_000
# The keys rosbag2 added in each version (rosbag2_storage's metadata_io).
ADDED = {
    5: ("files",),
    6: ("custom_data",),
    7: ("type_description_hash",),
    8: ("ros_distro",),
}


def db3_bag(path: Path, version: int) -> Path:
    with Writer(path, version=9 if version == 9 else 8) as writer:
        temp = writer.add_connection("/temp", "sensor_msgs/msg/Temperature", typestore=STORE)
        text = writer.add_connection("/text", "std_msgs/msg/String", typestore=STORE)
        t = STORE.types
        for i in range(40):
            msg = t["sensor_msgs/msg/Temperature"](
                header=t["std_msgs/msg/Header"](
                    stamp=t["builtin_interfaces/msg/Time"](sec=i, nanosec=0), frame_id="t"
                ),
                temperature=20.0 + i / 4,
                variance=0.1,
            )
            writer.write(temp, T0 + i * 10**7, bytes(STORE.serialize_cdr(msg, msg.__msgtype__)))
            if i % 4 == 0:
                string = t["std_msgs/msg/String"](data=f"#{i}")
                writer.write(
                    text, T0 + i * 10**7 + 1, bytes(STORE.serialize_cdr(string, string.__msgtype__))
                )
    metadata_path = path / "metadata.yaml"
    document = yaml.safe_load(metadata_path.read_text())
    info = document["rosbag2_bagfile_information"]
    for added, keys in ADDED.items():
        if version < added:
            for key in keys:
                info.pop(key, None)
                for topic in info["topics_with_message_count"]:
                    topic["topic_metadata"].pop(key, None)
    info["version"] = version
    metadata_path.write_text(yaml.safe_dump(document))
    return path


@pytest.mark.parametrize("version", [4, 5, 6, 7, 8, 9, None])
def test_each_metadata_version(tmp_path: Path, version: int | None) -> None:
    bag = db3_bag(tmp_path / "bag", version or 9)
    with Reader(bag) as reader:
        expected = [(c.topic, t, bytes(d)) for c, t, d in reader.messages()]
        types = {c.topic: c.msgtype for c in reader.connections}
    if version is None:
        (bag / "metadata.yaml").unlink()
    with BagReader(bag) as got:
        assert {name: topic.type for name, topic in got.topics.items()} == types
        assert [(m.topic, m.log_time, m.data) for m in got.messages()] == expected
        assert got.problems == []
        assert sum(got.topic_counts.values()) == len(expected) == 50
        if version is not None and version >= 7:
            assert got.topics["/temp"].type_description_hash.startswith("RIHS01_")
