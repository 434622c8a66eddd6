"""summarize() against numpy on bags written by rosbags, fast path against general path."""

from __future__ import annotations

import shutil
from collections.abc import Iterable
from pathlib import Path

import numpy as np
import pytest
from rosbags.rosbag2 import StoragePlugin, Writer
from rosbags.typesys import get_types_from_msg
from rosbags.typesys.store import Typestore
from rosbags_oracle import (
    T0,
    TYPESTORE,
    TopicData,
    diagnostics_data,
    flag_data,
    imu_data,
    scan_data,
    write_bag,
)

from bagkit.bag import BagNotFoundError
from bagkit.stats import (
    NothingToSummarizeError,
    StatsError,
    Summary,
    TopicStats,
    UnknownTopicError,
    summarize,
)
from bagkit.stats import accumulate as accumulate_module

RTOL = 1e-9


@pytest.fixture
def rng() -> np.random.Generator:
    return np.random.default_rng(20261122)


def _check_topic(stats: TopicStats, data: TopicData, mask: np.ndarray | None = None) -> None:
    """Every reported field against numpy on the values the generator wrote."""
    assert stats.type == data.type
    assert {f.field for f in stats.fields} == set(data.values)
    for f in stats.fields:
        values = data.expected(f.field)
        if mask is not None:
            values = values[mask]
        finite = values[~np.isnan(values)]
        assert f.count == len(finite), f.field
        assert f.nan_count == int(np.isnan(values).sum()), f.field
        if not len(finite):
            assert f.min is None and f.mean is None and f.std is None
            continue
        assert f.min == finite.min() and f.max == finite.max(), f.field
        assert f.mean == pytest.approx(finite.mean(), rel=RTOL, abs=1e-12), f.field
        if len(finite) > 1:
            assert f.std == pytest.approx(finite.std(ddof=1), rel=RTOL, abs=1e-12), f.field
        else:
            assert f.std is None


@pytest.fixture(scope="module")
def topics() -> dict[str, TopicData]:
    rng = np.random.default_rng(5)
    # 4000 Imu messages fill more than one 1 MiB chunk of rosbags' writer.
    return {
        "/imu/data": imu_data(rng, 4000),
        "/scan": scan_data(rng, 60),
        "/diagnostics": diagnostics_data(rng, 30),
        "/flag": flag_data(20),
    }


@pytest.fixture(scope="module")
def bag(tmp_path_factory: pytest.TempPathFactory, topics: dict[str, TopicData]) -> Path:
    """Written once per module: the tests only read it."""
    return write_bag(tmp_path_factory.mktemp("stats") / "bag", topics)


def test_every_field_matches_numpy(bag: Path, topics: dict[str, TopicData]) -> None:
    result = summarize([bag])
    assert [t.topic for t in result.topics] == sorted(topics)
    for stats in result.topics:
        data = topics[stats.topic]
        assert stats.count == len(data.messages)
        _check_topic(stats, data)
    times = [t for data in topics.values() for t, _ in data.messages]
    assert (result.start_ns, result.end_ns) == (min(times), max(times))
    assert result.skipped == {} and result.problems == ()


def test_rate_is_from_first_to_last_message(bag: Path, topics: dict[str, TopicData]) -> None:
    result = summarize([bag], topics=["/imu/data"])
    (imu,) = result.topics
    times = [t for t, _ in topics["/imu/data"].messages]
    assert imu.rate_hz == pytest.approx((len(times) - 1) / ((times[-1] - times[0]) / 1e9))


def test_fast_path_is_taken_and_agrees_with_general_path(
    bag: Path, monkeypatch: pytest.MonkeyPatch
) -> None:
    decoded_one_by_one: list[str] = []
    general = accumulate_module.TopicAccumulator.add_payloads

    def counting(self: accumulate_module.TopicAccumulator, payloads: Iterable[bytes]) -> None:
        payloads = list(payloads)
        decoded_one_by_one.extend(self.topic for _ in payloads)
        general(self, payloads)

    monkeypatch.setattr(accumulate_module.TopicAccumulator, "add_payloads", counting)
    fast = summarize([bag])
    # Only the type with sequences of messages goes through the general decoder.
    assert set(decoded_one_by_one) == {"/diagnostics"}

    decoded_one_by_one.clear()
    monkeypatch.setattr(accumulate_module, "ROW_BATCH", 100)  # many batches to merge
    slow = summarize([bag], bulk=False)
    assert set(decoded_one_by_one) == {"/imu/data", "/scan", "/diagnostics", "/flag"}
    assert len(fast.topics) == len(slow.topics)
    for a, b in zip(fast.topics, slow.topics, strict=True):
        assert (a.topic, a.count, a.rate_hz) == (b.topic, b.count, b.rate_hz)
        for fa, fb in zip(a.fields, b.fields, strict=True):
            assert (fa.field, fa.count, fa.nan_count, fa.min, fa.max) == (
                fb.field,
                fb.count,
                fb.nan_count,
                fb.min,
                fb.max,
            )
            for x, y in ((fa.mean, fb.mean), (fa.std, fb.std)):
                assert (x is None and y is None) or x == pytest.approx(y, rel=RTOL, abs=1e-12)


def test_time_window_selects_messages(bag: Path, topics: dict[str, TopicData]) -> None:
    start, end = T0 + 2_000_000_000, T0 + 9_000_000_000
    result = summarize([bag], start_ns=start, end_ns=end)
    assert start <= result.start_ns and result.end_ns < end
    for stats in result.topics:
        data = topics[stats.topic]
        inside = np.array([start <= t < end for t, _ in data.messages])
        assert stats.count == int(inside.sum())
        if stats.topic in ("/imu/data", "/flag"):  # one value per message: mask by message
            _check_topic(stats, data, mask=inside)


def test_topic_and_field_selection(bag: Path, topics: dict[str, TopicData]) -> None:
    result = summarize(
        [bag],
        topics=["/imu/data", "/scan"],
        fields=["linear_acceleration.?", "ranges[]", "*_covariance[4]"],
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
        _check_topic(stats, pooled[stats.topic])
    assert result.end_ns == third["/imu/data"].messages[-1][0]


def test_dataframe_has_a_row_per_field(bag: Path) -> None:
    result = summarize([bag], topics=["/imu/data"])
    frame = result.to_dataframe()
    assert len(frame) == len(result.topics[0].fields)
    row = frame.set_index("field").loc["linear_acceleration.z"]
    field = next(f for f in result.topics[0].fields if f.field == "linear_acceleration.z")
    assert (row["count"], row["mean"], row["std"]) == (field.count, field.mean, field.std)


def test_json_document_has_the_documented_keys(bag: Path) -> None:
    document = summarize([bag]).to_dict()
    assert list(document) == ["bags", "start_ns", "end_ns", "duration_s", "topics"]
    topic = document["topics"][0]
    assert list(topic) == ["topic", "type", "count", "rate_hz", "fields"]
    assert list(topic["fields"][0]) == ["field", "count", "nan_count", "min", "max", "mean", "std"]


def test_bad_input_raises_readable_errors(bag: Path, tmp_path: Path) -> None:
    with pytest.raises(UnknownTopicError, match="/nope"):
        summarize([bag], topics=["/nope"])
    with pytest.raises(BagNotFoundError):
        summarize([tmp_path / "missing"])
    with pytest.raises(NothingToSummarizeError, match="no messages"):
        summarize([bag], start_ns=T0 + 10**15)
    with pytest.raises(NothingToSummarizeError, match="--fields"):
        summarize([bag], fields=["no_such_field"])


def test_empty_bag_is_a_clear_error(tmp_path: Path) -> None:
    empty = write_bag(tmp_path / "empty", {"/imu/data": TopicData("sensor_msgs/msg/Imu")})
    with pytest.raises(NothingToSummarizeError, match="no messages"):
        summarize([empty])


def test_result_is_a_summary(bag: Path) -> None:
    assert isinstance(summarize([bag]), Summary)


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
    _check_topic(imu, data, mask=np.arange(len(data.messages)) < imu.count)


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
    _check_topic(imu, data)
