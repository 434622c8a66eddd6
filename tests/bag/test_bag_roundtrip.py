"""Writer -> reader round trips, checked with bagkit, rosbags and the mcap library."""

from __future__ import annotations

import random
from collections.abc import Callable
from pathlib import Path

import pytest
import yaml
from bag_samples import IMU, QOS_YAML, STRING, TYPESTORE, deserialize, imu_cdr, string_cdr
from mcap.reader import make_reader
from mcap_ros2.decoder import DecoderFactory
from rosbags.highlevel import AnyReader

from bagkit.bag import (
    BagExistsError,
    BagReader,
    BagWriter,
    TopicInfo,
    message_definition,
    type_description_hash,
)


def test_round_trip_keeps_every_message(write_sample_bag: Callable[..., Path]) -> None:
    bag_path = write_sample_bag(n_imu=300)
    with BagReader(bag_path) as bag:
        assert bag.files == [bag_path / "sample_0.mcap"]
        assert bag.topic_counts == {"/imu/data": 300, "/text": 30}
        assert bag.message_count == 330
        assert bag.topics["/imu/data"].type == IMU
        assert bag.topics["/imu/data"].offered_qos_profiles == QOS_YAML
        assert bag.topics["/imu/data"].type_description_hash == type_description_hash(IMU)
        assert bag.definitions[IMU] == message_definition(IMU)
        assert bag.start_ns == 1_700_000_000_000_000_000
        assert bag.end_ns == 1_700_000_000_000_000_000 + 299 * 10_000_000
        messages = list(bag.messages())
        assert bag.problems == []
    assert len(messages) == 330
    log_times = [m.log_time for m in messages]
    assert log_times == sorted(log_times)
    imu = [m for m in messages if m.topic == "/imu/data"]
    for i, message in enumerate(imu):
        assert message.data == imu_cdr(i)
        assert message.sequence == i
        assert message.publish_time == message.log_time - 1000
    text = [deserialize(m.data, STRING).data for m in messages if m.topic == "/text"]
    assert text == [f"message {i}" for i in range(0, 300, 10)]


def test_filters_by_topic_and_time(write_sample_bag: Callable[..., Path]) -> None:
    bag_path = write_sample_bag(n_imu=100)
    start = 1_700_000_000_000_000_000 + 20 * 10_000_000
    end = 1_700_000_000_000_000_000 + 50 * 10_000_000
    with BagReader(bag_path) as bag:
        selected = list(bag.messages(topics=["/imu/data"], start_ns=start, end_ns=end))
    assert [m.sequence for m in selected] == list(range(20, 50))


@pytest.mark.parametrize("compression", ["zstd", "lz4", "none"])
def test_rosbags_and_mcap_read_every_message(
    write_sample_bag: Callable[..., Path], compression: str
) -> None:
    bag_path = write_sample_bag(n_imu=200, compression=compression, chunk_size=4096)
    with AnyReader([bag_path], default_typestore=TYPESTORE) as reader:
        counts = {c.topic: c.msgcount for c in reader.connections}
        decoded = [reader.deserialize(raw, c.msgtype) for c, _, raw in reader.messages()]
    assert counts == {"/imu/data": 200, "/text": 20}
    assert len(decoded) == 220
    accel_x = [m.linear_acceleration.x for m in decoded if hasattr(m, "linear_acceleration")]
    assert accel_x == pytest.approx([0.01 * i for i in range(200)])

    with open(bag_path / "sample_0.mcap", "rb") as f:
        reader = make_reader(f, decoder_factories=[DecoderFactory()])
        header = reader.get_header()
        summary = reader.get_summary()
        decoded_mcap = [m for _, _, _, m in reader.iter_decoded_messages()]
    assert header.profile == "ros2"
    assert header.library.startswith("bagkit")
    assert summary is not None and summary.statistics is not None
    assert summary.statistics.message_count == 220
    assert len(summary.chunk_indexes) > 1
    assert {c.compression for c in summary.chunk_indexes} == {
        "" if compression == "none" else compression
    }
    assert {s.encoding for s in summary.schemas.values()} == {"ros2msg"}
    channel = next(c for c in summary.channels.values() if c.topic == "/imu/data")
    assert channel.message_encoding == "cdr"
    assert channel.metadata == {
        "offered_qos_profiles": QOS_YAML,
        "topic_type_hash": type_description_hash(IMU),
    }
    assert len(decoded_mcap) == 220
    frame_ids = [m.header.frame_id for m in decoded_mcap if hasattr(m, "linear_acceleration")]
    assert frame_ids == ["imu" + "x" * (i % 3) for i in range(200)]


def test_metadata_yaml_is_rosbag2_version_9(write_sample_bag: Callable[..., Path]) -> None:
    bag_path = write_sample_bag(n_imu=50)
    info = yaml.safe_load((bag_path / "metadata.yaml").read_text())["rosbag2_bagfile_information"]
    assert list(info) == [
        "version",
        "storage_identifier",
        "duration",
        "starting_time",
        "message_count",
        "topics_with_message_count",
        "compression_format",
        "compression_mode",
        "relative_file_paths",
        "files",
        "custom_data",
        "ros_distro",
    ]
    first = 1_700_000_000_000_000_000
    last = first + 49 * 10_000_000
    assert info["version"] == 9
    assert info["storage_identifier"] == "mcap"
    assert info["starting_time"] == {"nanoseconds_since_epoch": first}
    assert info["duration"] == {"nanoseconds": last - first}
    assert info["message_count"] == 55
    topics = {t["topic_metadata"]["name"]: t for t in info["topics_with_message_count"]}
    assert topics["/imu/data"]["message_count"] == 50
    assert topics["/text"]["message_count"] == 5
    assert topics["/imu/data"]["topic_metadata"] == {
        "name": "/imu/data",
        "type": IMU,
        "serialization_format": "cdr",
        # rosbag2 Jazzy writes and reads version 9 profiles as a YAML sequence (a string there
        # fails its metadata decoding), as rosbags' version 9 writer does.
        "offered_qos_profiles": yaml.safe_load(QOS_YAML),
        "type_description_hash": type_description_hash(IMU),
    }
    assert info["relative_file_paths"] == ["sample_0.mcap"]
    assert info["files"] == [
        {
            "path": "sample_0.mcap",
            "starting_time": {"nanoseconds_since_epoch": first},
            "duration": {"nanoseconds": last - first},
            "message_count": 55,
        }
    ]
    assert info["custom_data"] == {"lost./imu/data": "0"}
    assert info["ros_distro"] == "jazzy"
    assert info["compression_format"] == ""

    # The same metadata is embedded in the MCAP file, as rosbag2 does.
    with open(bag_path / "sample_0.mcap", "rb") as f:
        records = list(make_reader(f).iter_metadata())
    assert [r.name for r in records] == ["rosbag2"]
    embedded = yaml.safe_load(records[0].metadata["serialized_metadata"])
    assert embedded["message_count"] == 55
    assert embedded["topics_with_message_count"] == info["topics_with_message_count"]


def test_definition_has_dependencies_as_rosbag2_writes_them() -> None:
    text = message_definition(IMU)
    separator = "\n" + "=" * 80 + "\n"
    sections = text.split(separator)
    assert sections[0].startswith("# This is a message to hold data from an IMU")
    names = [s.splitlines()[0] for s in sections[1:]]
    assert sorted(names) == sorted(
        [
            "MSG: std_msgs/Header",
            "MSG: builtin_interfaces/Time",
            "MSG: geometry_msgs/Quaternion",
            "MSG: geometry_msgs/Vector3",
        ]
    )
    assert message_definition("sensor_msgs/Imu") == text
    assert type_description_hash(IMU).startswith("RIHS01_")


def test_existing_output_is_never_overwritten(tmp_path: Path) -> None:
    target = tmp_path / "bag"
    target.mkdir()
    (target / "keep.txt").write_text("precious")
    with pytest.raises(BagExistsError):
        BagWriter(target).open()
    assert (target / "keep.txt").read_text() == "precious"


def test_unknown_type_without_definition_is_a_clear_error(tmp_path: Path) -> None:
    from bagkit.bag import UnknownMessageTypeError

    with BagWriter(tmp_path / "bag") as bag:
        with pytest.raises(UnknownMessageTypeError, match="not_a_pkg/msg/Nope"):
            bag.add_topic(TopicInfo("/x", "not_a_pkg/msg/Nope"))
        bag.add_topic(TopicInfo("/x", "not_a_pkg/msg/Nope"), definition="int32 a\n")
        bag.write("/x", b"\x00\x01\x00\x00\x05\x00\x00\x00", log_time=5)
    with BagReader(tmp_path / "bag") as reader:
        assert reader.definitions == {"not_a_pkg/msg/Nope": "int32 a\n"}
        assert reader.topic_counts == {"/x": 1}


def test_topic_filter_skips_chunks_without_the_topic(tmp_path: Path) -> None:
    with BagWriter(tmp_path / "bag", chunk_size=2_000) as bag:
        bag.add_topic(TopicInfo("/a", STRING))
        bag.add_topic(TopicInfo("/b", STRING))
        for i in range(400):
            topic = "/a" if i < 200 or i >= 300 else "/b"
            bag.write(topic, string_cdr(f"{topic} {i}"), log_time=i)
    with BagReader(tmp_path / "bag") as reader:
        everything = list(reader.messages())
        only_b = list(reader.messages(topics=["/b"]))
        b_chunks = list(reader.chunks(topics=["/b"]))
    assert only_b == [m for m in everything if m.topic == "/b"]
    assert [m.log_time for m in only_b] == list(range(200, 300))
    assert sum(len(c.message_index["/b"]) for c in b_chunks) == 100
    assert all(set(c.message_index) == {"/b"} for c in b_chunks)


def test_messages_built_by_the_readers_are_ordinary_frozen_messages() -> None:
    import dataclasses

    from bagkit.bag.messages import BagMessage, make_message

    fast = make_message("/t", b"\x01", 5, 4, 3)
    assert fast == BagMessage("/t", b"\x01", 5, 4, 3)
    assert hash(fast) == hash(BagMessage("/t", b"\x01", 5, 4, 3))
    with pytest.raises(dataclasses.FrozenInstanceError):
        fast.log_time = 6  # type: ignore[misc]


def test_writing_to_an_unknown_topic_or_a_closed_bag_is_an_error(tmp_path: Path) -> None:
    from bagkit.bag import BagError

    bag = BagWriter(tmp_path / "bag").open()
    bag.add_topic(TopicInfo("/a", STRING))
    with pytest.raises(BagError, match="not added"):
        bag.write("/b", string_cdr("x"), log_time=1)
    bag.add_topic(TopicInfo("/a", STRING))  # same topic, same type: nothing to do
    with pytest.raises(BagError, match="already added with type"):
        bag.add_topic(TopicInfo("/a", IMU))
    bag.close()
    bag.close()
    with pytest.raises(BagError, match="closed"):
        bag.write("/a", string_cdr("x"), log_time=1)
    with BagReader(tmp_path / "bag", allow_empty=True) as reader:
        assert reader.topic_counts == {"/a": 0}


def test_crcs_validate_with_the_mcap_library(write_sample_bag: Callable[..., Path]) -> None:
    from mcap.records import Footer, Message
    from mcap.stream_reader import StreamReader

    bag_path = write_sample_bag(n_imu=100, chunk_size=3_000)
    with open(bag_path / "sample_0.mcap", "rb") as f:
        records = list(StreamReader(f, validate_crcs=True).records)
    assert sum(isinstance(r, Message) for r in records) == 110
    assert isinstance(records[-1], Footer) and records[-1].summary_crc != 0


def test_service_event_definition_is_the_generated_event_message() -> None:
    import sys

    srv = (Path(sys.prefix) / "share/rcl_interfaces/srv/GetParameters.srv").read_text()
    request, response = srv.split("---\n")
    text = message_definition("rcl_interfaces/srv/GetParameters_Event")
    assert text.startswith(
        "service_msgs/ServiceEventInfo info\n"
        "rcl_interfaces/GetParameters_Request[<=1] request\n"
        "rcl_interfaces/GetParameters_Response[<=1] response\n"
    )
    assert f"\nMSG: rcl_interfaces/GetParameters_Request\n{request}" in text
    assert f"\nMSG: rcl_interfaces/GetParameters_Response\n{response}" in text
    assert "\nMSG: rcl_interfaces/ParameterValue\n" in text
    assert type_description_hash("rcl_interfaces/srv/GetParameters_Event").startswith("RIHS01_")


@pytest.mark.parametrize("options", [{}, {"max_bag_size": 30_000, "compression": "none"}])
def test_write_batch_writes_the_same_files_as_one_write_per_message(
    tmp_path: Path, options: dict[str, int | str]
) -> None:
    # Batches of uneven sizes that cross chunk and file boundaries, two topics interleaved.
    rng = random.Random(3)
    messages: list[tuple[str, bytes, int, int]] = []
    for i in range(900):
        topic = "/imu/data" if i % 5 else "/text"
        data = imu_cdr(i) if topic == "/imu/data" else string_cdr(f"m{i}" * rng.randint(0, 40))
        messages.append((topic, data, 1_000_000 + i * 1000, i))
    batches: list[list[tuple[str, bytes, int, int]]] = []
    for topic, *rest in messages:
        if not batches or batches[-1][0][0] != topic or rng.random() < 0.2:
            batches.append([])
        batches[-1].append((topic, *rest))

    for name in ("single", "batch"):
        # The same bag name: the file names are in the bytes (the rosbag2 metadata record).
        with BagWriter(
            tmp_path / name / "bag", chunk_size=8_000, chunk_interval_s=3600, **options
        ) as bag:
            bag.add_topic(TopicInfo("/imu/data", IMU))
            bag.add_topic(TopicInfo("/text", STRING))
            for batch in batches:
                if name == "single":
                    for topic, data, log_time, sequence in batch:
                        bag.write(
                            topic,
                            data,
                            log_time=log_time,
                            publish_time=-sequence % 7,
                            sequence=sequence,
                        )
                else:
                    bag.write_batch(
                        batch[0][0],
                        [data for _t, data, _l, _s in batch],
                        log_times=[log_time for _t, _d, log_time, _s in batch],
                        publish_times=[-sequence % 7 for *_, sequence in batch],
                        sequences=[sequence for *_, sequence in batch],
                    )

    single = sorted((tmp_path / "single" / "bag").glob("*.mcap"))
    batch = sorted((tmp_path / "batch" / "bag").glob("*.mcap"))
    assert len(single) == 1 if not options else len(single) >= 3
    assert [p.name for p in single] == [p.name for p in batch]
    for single_file, batch_file in zip(single, batch, strict=True):
        assert single_file.read_bytes() == batch_file.read_bytes()
    with BagReader(tmp_path / "batch" / "bag") as bag:
        assert [(m.topic, m.data, m.log_time, m.sequence) for m in bag.messages()] == messages


def test_write_batch_checks_lengths_before_writing(tmp_path: Path) -> None:
    with BagWriter(tmp_path / "bag") as bag:
        bag.add_topic(TopicInfo("/a", STRING))
        with pytest.raises(ValueError, match="differ in length"):
            bag.write_batch("/a", [string_cdr("x"), string_cdr("y")], log_times=[1])
        bag.write_batch("/a", [string_cdr("z")], log_times=[2])
    with BagReader(tmp_path / "bag") as reader:
        assert [m.log_time for m in reader.messages()] == [2]


@pytest.mark.parametrize("compression", ["zstd", "lz4", "none"])
def test_large_payloads_between_small_ones_read_back_everywhere(
    tmp_path: Path, compression: str
) -> None:
    # Chunks of a few records each, some larger than a chunk; every fourth payload is a buffer
    # that the caller overwrites after the call.
    from mcap.records import Chunk, Message
    from mcap.stream_reader import StreamReader

    rng = random.Random(5)
    sizes = [rng.choice([0, 30, 900, 65_536, 300_000, 500_000]) for _ in range(60)]
    letters = bytes(b"abc "[i % 4] for i in range(256))
    texts = [rng.randbytes(size).translate(letters).decode() for size in sizes]
    reused = bytearray()
    with BagWriter(
        tmp_path / "bag", compression=compression, chunk_size=400_000, chunk_interval_s=3600
    ) as bag:
        bag.add_topic(TopicInfo("/text", STRING))
        for i, text in enumerate(texts):
            if i % 4 == 3:
                reused[:] = string_cdr(text)
                bag.write("/text", reused, log_time=i, sequence=i)
                reused[:] = b"overwritten after the write"
            else:
                bag.write_batch("/text", [string_cdr(text)], log_times=[i], sequences=[i])

    with BagReader(tmp_path / "bag") as reader:
        assert [deserialize(m.data, STRING).data for m in reader.messages()] == texts
        assert reader.problems == []
    with AnyReader([tmp_path / "bag"], default_typestore=TYPESTORE) as reader:
        decoded = [reader.deserialize(raw, c.msgtype).data for c, _, raw in reader.messages()]
    assert decoded == texts
    with open(tmp_path / "bag" / "bag_0.mcap", "rb") as f:
        records = list(StreamReader(f, validate_crcs=True).records)
        f.seek(0)
        chunks = [r for r in StreamReader(f, emit_chunks=True).records if isinstance(r, Chunk)]
    assert [deserialize(r.data, STRING).data for r in records if isinstance(r, Message)] == texts
    assert len(chunks) >= 5
    assert {c.compression for c in chunks} == {"" if compression == "none" else compression}


def test_incompressible_images_are_stored_uncompressed_and_read_back_everywhere(
    tmp_path: Path,
) -> None:
    # Noise images between texts (each larger than a chunk, so each its own chunk): the images'
    # chunks are stored uncompressed in a zstd bag, the texts compressed; every reader agrees.
    import numpy as np

    image_type = "sensor_msgs/msg/CompressedImage"
    image = TYPESTORE.types[image_type]
    rng = np.random.default_rng(3)
    images = [rng.integers(0, 256, 1_200_000 + i, dtype=np.uint8) for i in range(4)]
    with BagWriter(tmp_path / "bag", chunk_interval_s=3600) as bag:
        bag.add_topic(TopicInfo("/camera", image_type))
        bag.add_topic(TopicInfo("/text", STRING))
        for i, data in enumerate(images):
            bag.write_batch("/text", [string_cdr("small " * 200_000)], log_times=[10 * i])
            header = TYPESTORE.types["std_msgs/msg/Header"](
                stamp=TYPESTORE.types["builtin_interfaces/msg/Time"](sec=i, nanosec=0),
                frame_id="camera",
            )
            cdr = bytes(
                TYPESTORE.serialize_cdr(image(header=header, format="jpeg", data=data), image_type)
            )
            bag.write_batch("/camera", [cdr], log_times=[10 * i + 1])

    with BagReader(tmp_path / "bag") as reader:
        got = [deserialize(m.data, image_type).data for m in reader.messages(topics=["/camera"])]
        assert reader.problems == []
        assert reader.compression == "none,zstd"  # as `bagkit info` shows it
    assert all(np.array_equal(a, b) for a, b in zip(got, images, strict=True))
    with AnyReader([tmp_path / "bag"], default_typestore=TYPESTORE) as reader:
        decoded = [
            reader.deserialize(raw, c.msgtype).data
            for c, _, raw in reader.messages()
            if c.topic == "/camera"
        ]
    assert all(np.array_equal(a, b) for a, b in zip(decoded, images, strict=True))
    with open(tmp_path / "bag" / "bag_0.mcap", "rb") as f:
        mcap = make_reader(f, validate_crcs=True)
        assert len(list(mcap.iter_messages())) == 8
        summary = mcap.get_summary()
    assert summary is not None
    assert {c.compression for c in summary.chunk_indexes} == {"", "zstd"}
