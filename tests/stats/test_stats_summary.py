"""summarize() against numpy on bags written by rosbags: selection, pooling, salvage, errors."""

from __future__ import annotations

import shutil
from pathlib import Path

import numpy as np
import pytest
from rosbags.rosbag2 import StoragePlugin, Writer
from rosbags.typesys import get_types_from_msg
from rosbags.typesys.store import Typestore
from rosbags_oracle import (
    RTOL,
    T0,
    TYPESTORE,
    RawTopic,
    TopicData,
    check_topic,
    flag_data,
    imu_data,
    scan_data,
    write_bag,
)

from bagkit.bag import BagError, BagNotFoundError
from bagkit.selection.errors import UnknownFieldError
from bagkit.selection.query import Query
from bagkit.stats import (
    NothingToSummarizeError,
    StatsError,
    UnknownTopicError,
    summarize,
)


@pytest.fixture
def rng() -> np.random.Generator:
    return np.random.default_rng(20261122)


def test_every_field_matches_numpy(bag: Path, topics: dict[str, TopicData]) -> None:
    result = summarize([bag])
    assert [t.topic for t in result.topics] == sorted(topics)
    for stats in result.topics:
        data = topics[stats.topic]
        assert stats.count == len(data.messages)
        check_topic(stats, data)
    times = [t for data in topics.values() for t, _ in data.messages]
    assert (result.start_ns, result.end_ns) == (min(times), max(times))
    assert result.skipped == {} and result.problems == ()


def test_rate_is_from_first_to_last_message(bag: Path, topics: dict[str, TopicData]) -> None:
    result = summarize([bag], Query.create("/imu/data"))
    (imu,) = result.topics
    times = [t for t, _ in topics["/imu/data"].messages]
    assert imu.rate_hz == pytest.approx((len(times) - 1) / ((times[-1] - times[0]) / 1e9))


def test_time_window_selects_messages(bag: Path, topics: dict[str, TopicData]) -> None:
    start, end = T0 + 2_000_000_000, T0 + 9_000_000_000
    result = summarize([bag], Query.create(start=f"{start}ns", end=f"{end}ns"))
    assert result.start_ns is not None and result.end_ns is not None
    assert start <= result.start_ns and result.end_ns < end
    relative = summarize([bag], Query.create(start="2", end=f"{(end - T0) / 1e9}"))
    assert relative == result
    for stats in result.topics:
        data = topics[stats.topic]
        inside = np.array([start <= t < end for t, _ in data.messages])
        assert stats.count == int(inside.sum())
        if stats.topic in ("/imu/data", "/flag"):  # one value per message: mask by message
            check_topic(stats, data, mask=inside)


def test_topic_and_field_selection(bag: Path, topics: dict[str, TopicData]) -> None:
    result = summarize(
        [bag],
        Query.create(
            ["/imu/data", "/scan"], ["linear_acceleration.?", "ranges[]", "*_covariance[4]"]
        ),
    )
    fields = {t.topic: [f.field for f in t.fields] for t in result.topics}
    assert fields == {
        "/imu/data": [
            "orientation_covariance[4]",
            "angular_velocity_covariance[4]",
            "linear_acceleration.x",
            "linear_acceleration.y",
            "linear_acceleration.z",
            "linear_acceleration_covariance[4]",
        ],
        "/scan": ["ranges[]"],
    }
    imu = result.topics[0]
    x = next(f for f in imu.fields if f.field == "linear_acceleration.x")
    values = topics["/imu/data"].expected("linear_acceleration.x")
    assert x.nan_count == int(np.isnan(values).sum()) > 0
    assert x.mean == pytest.approx(np.nanmean(values), rel=RTOL)


def test_several_bags_and_split_files_are_pooled(tmp_path: Path, rng: np.random.Generator) -> None:
    first = {"/imu/data": imu_data(rng, 300), "/scan": scan_data(rng, 10)}
    later = T0 + 3_600_000_000_000
    second = {"/imu/data": imu_data(rng, 200, t0=later), "/scan": scan_data(rng, 5, t0=later)}
    third = {"/imu/data": imu_data(rng, 100, t0=2 * later)}
    bag_a = write_bag(tmp_path / "a", first, compressed=False)
    bag_b = write_bag(tmp_path / "b", second)
    bag_c = write_bag(tmp_path / "c", third)
    # A split bag without metadata.yaml: two storage files of one recording.
    split = tmp_path / "split"
    split.mkdir()
    shutil.copy(next(bag_b.glob("*.mcap")), split / "split_0.mcap")
    shutil.copy(next(bag_c.glob("*.mcap")), split / "split_1.mcap")

    result = summarize([bag_a, split])
    assert result.bags == (str(bag_a), str(split))
    pooled = {
        topic: TopicData(
            data.type,
            data.messages + second[topic].messages + third.get(topic, TopicData("")).messages,
            {
                path: v
                + second[topic].values[path]
                + third.get(topic, TopicData("")).values.get(path, [])
                for path, v in data.values.items()
            },
        )
        for topic, data in first.items()
    }
    for stats in result.topics:
        assert stats.count == len(pooled[stats.topic].messages)
        check_topic(stats, pooled[stats.topic])
    assert result.end_ns == third["/imu/data"].messages[-1][0]


def test_bad_input_raises_readable_errors(bag: Path, tmp_path: Path) -> None:
    with pytest.raises(UnknownTopicError, match="/nope"):
        summarize([bag], Query.create("/nope"))
    with pytest.raises(BagNotFoundError):
        summarize([tmp_path / "missing"])
    outside = summarize([bag], Query.create(start=f"{T0 + 10**15}ns"))
    assert outside.topics == () and outside.start_ns is None
    assert len(outside.problems) == 1 and "holds no message" in outside.problems[0]
    with pytest.raises(UnknownFieldError, match="no topic has a numeric field no_such_field"):
        summarize([bag], Query.create(fields=["no_such_field"]))
    with pytest.raises(UnknownFieldError, match=r"did you mean linear_acceleration.z,"):
        summarize([bag], Query.create("/imu/data", ["linear_acceleration.zz"]))


def test_an_unreadable_bag_among_others_is_reported_the_rest_summarized(
    bag: Path, tmp_path: Path
) -> None:
    # As the same command on a cluster does (docs/fleet.md): the choice of running in this
    # process or on Dask is the command's, not a change of outcome.
    broken = tmp_path / "broken.mcap"
    broken.write_bytes(b"\x89MCAP0\r\n" + bytes(40))
    alone = summarize([bag])
    pooled = summarize([bag, broken])
    assert pooled.topics == alone.topics
    assert [p.split(": not read: ")[0] for p in pooled.problems] == [str(broken)]
    with pytest.raises(BagError):
        summarize([broken])
    with pytest.raises(BagError):
        summarize([broken, broken])


def test_empty_bag_is_a_clear_error(tmp_path: Path) -> None:
    empty = write_bag(tmp_path / "empty", {"/imu/data": TopicData("sensor_msgs/msg/Imu")})
    with pytest.raises(NothingToSummarizeError, match="no messages"):
        summarize([empty])


def test_crashed_recording_is_salvaged(tmp_path: Path, rng: np.random.Generator) -> None:
    """A file cut short (no summary, a torn chunk): the intact chunks are summarized."""
    data = imu_data(rng, 10_000)
    bag = write_bag(tmp_path / "crashed", {"/imu/data": data}, compressed=False)
    (file,) = bag.glob("*.mcap")
    content = file.read_bytes()
    file.write_bytes(content[: int(len(content) * 0.6)])

    result = summarize([bag])
    (imu,) = result.topics
    assert 0 < imu.count < len(data.messages)
    assert any("truncated" in problem for problem in result.problems), result.problems
    # Chunks hold consecutive messages: what survives is the first `count` of them.
    check_topic(imu, data, mask=np.arange(len(data.messages)) < imu.count)


def test_a_topic_with_two_types_across_bags_is_an_error(
    tmp_path: Path, rng: np.random.Generator
) -> None:
    imu = write_bag(tmp_path / "imu", {"/data": imu_data(rng, 5)})
    flag = write_bag(tmp_path / "flag", {"/data": flag_data(5)})
    with pytest.raises(StatsError, match="sensor_msgs/msg/Imu in one bag and std_msgs/msg/Bool"):
        summarize([imu, flag])


def test_progress_counts_up_to_the_messages_read(bag: Path, topics: dict[str, TopicData]) -> None:
    calls: list[tuple[int, int]] = []
    summarize([bag], progress=lambda done, total: calls.append((done, total)))
    total = sum(len(data.messages) for data in topics.values())
    assert len(calls) > 1 and {t for _, t in calls} == {total}
    done = [d for d, _ in calls]
    assert done == sorted(done) and done[-1] == total


def test_pooled_bags_must_define_a_type_the_same_way(tmp_path: Path) -> None:
    """Bags recorded with two versions of a message: pooling them would mix fields."""
    bags = []
    for name, text in (("v1", "float64 x\n"), ("v2", "float32 x\nfloat32 y\n")):
        store = Typestore()
        store.register(get_types_from_msg(text, "custom_msgs/msg/Thing"))
        thing = store.types["custom_msgs/msg/Thing"]
        path = tmp_path / name
        with Writer(path, version=9, storage_plugin=StoragePlugin.MCAP) as writer:
            connection = writer.add_connection("/thing", "custom_msgs/msg/Thing", typestore=store)
            fields = {f: 1.0 for f in ("x", "y") if f in text}
            writer.write(
                connection, T0, bytes(store.serialize_cdr(thing(**fields), thing.__msgtype__))
            )
        bags.append(path)
    assert summarize([bags[0]]).topics[0].fields[0].field == "x"
    with pytest.raises(StatsError, match=r"defined differently in .*v2"):
        summarize(bags)


@pytest.mark.parametrize("layout", ["unchunked", "lz4", "none"])
def test_other_mcap_writer_layouts(tmp_path: Path, layout: str) -> None:
    """Files from the mcap library: messages outside chunks, lz4 and uncompressed chunks."""
    from mcap.writer import CompressionType
    from mcap.writer import Writer as McapWriter

    from bagkit.bag import message_definition

    data = imu_data(np.random.default_rng(3), 500)
    path = tmp_path / f"{layout}.mcap"
    with open(path, "wb") as f:
        writer = McapWriter(
            f,
            use_chunking=layout != "unchunked",
            chunk_size=32 * 1024,
            compression=CompressionType.LZ4 if layout == "lz4" else CompressionType.NONE,
        )
        writer.start("ros2", "test")
        schema = writer.register_schema(
            data.type, "ros2msg", message_definition(data.type).encode()
        )
        channel = writer.register_channel("/imu/data", "cdr", schema)
        for log_time, msg in data.messages:
            payload = bytes(TYPESTORE.serialize_cdr(msg, data.type))
            writer.add_message(channel, log_time=log_time, data=payload, publish_time=log_time)
        writer.finish()
    (imu,) = summarize([path]).topics
    assert imu.count == len(data.messages)
    check_topic(imu, data)


def test_recursive_and_deep_types_are_skipped_the_others_summarized(tmp_path: Path) -> None:
    separator = "=" * 80 + "\n"
    chain = "".join(
        (f"{separator}MSG: deep/T{i}\n" if i else "") + f"deep/T{i + 1} next\nfloat64 v\n"
        for i in range(4999)
    )
    raw = {
        "/self": RawTopic("a/msg/Self", [(T0, b"\x00\x01\x00\x00")], "a/Self child\n"),
        "/kids": RawTopic("b/msg/Kids", [(T0, b"\x00\x01\x00\x00")], "b/Kids[] kids\n"),
        "/ping": RawTopic(
            "c/msg/Ping",
            [(T0, b"\x00\x01\x00\x00")],
            f"c/Pong pong\n{separator}MSG: c/Pong\nc/Ping[] ping\n",
        ),
        "/deep": RawTopic(
            "deep/msg/T0",
            [(T0, b"\x00\x01\x00\x00")],
            f"{chain}{separator}MSG: deep/T4999\nint8 end\n",
        ),
    }
    data = imu_data(np.random.default_rng(2), 50)
    bag = write_bag(tmp_path / "types", {"/imu/data": data}, raw=raw)

    result = summarize([bag])

    (imu,) = result.topics
    check_topic(imu, data)
    assert result.skipped == {
        "/deep": "definition of deep/msg/T0 cannot be used "
        "(deep/msg/T0 nests types more than 100 deep)",
        "/kids": "definition of b/msg/Kids cannot be used "
        "(b/msg/Kids is recursive (b/msg/Kids -> b/msg/Kids))",
        "/ping": "definition of c/msg/Ping cannot be used "
        "(c/msg/Ping is recursive (c/msg/Ping -> c/msg/Pong -> c/msg/Ping))",
        "/self": "definition of a/msg/Self cannot be used "
        "(a/msg/Self is recursive (a/msg/Self -> a/msg/Self))",
    }
