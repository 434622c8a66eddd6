"""``bagkit convert``: MCAP, SQLite3 and ROS 1 inputs into MCAP or SQLite3 bags, read back by
independent readers (the ``mcap`` package, rosbags, sqlite3)."""

from __future__ import annotations

import json
import sqlite3
from pathlib import Path
from typing import Any

import pytest
import yaml
from mcap.reader import make_reader
from mcap_ros2.decoder import DecoderFactory
from rosbags.highlevel import AnyReader
from rosbags.typesys import Stores, get_typestore
from surgery_samples import key, mcap_messages, rosbags_messages, run, run_here, write_mixed_bag

from tests.bag.ros1_samples import SAMPLE, ros1_messages, write_ros1_bag


@pytest.fixture(scope="module")
def mixed(tmp_path_factory: pytest.TempPathFactory) -> Path:
    return write_mixed_bag(tmp_path_factory.mktemp("convert") / "mixed", 1500)


@pytest.fixture(scope="module")
def ros1(tmp_path_factory: pytest.TempPathFactory) -> Path:
    path = tmp_path_factory.mktemp("convert_ros1") / "old.bag"
    return write_ros1_bag(path, 400, compression="lz4", chunk_threshold=8192)


def _convert(*args: str | Path) -> dict[str, object]:
    result = run_here("convert", *map(str, args), "--format", "json")
    assert result.returncode == 0, result.stderr
    report: dict[str, object] = json.loads(result.stdout)
    return report


def _mcap_files(bag: Path) -> list[Path]:
    return sorted(bag.glob("*.mcap"))


def _schemas(file: Path) -> dict[str, str]:
    with open(file, "rb") as f:
        summary = make_reader(f).get_summary()
    assert summary is not None
    return {s.name: s.data.decode() for s in summary.schemas.values()}


def _chunk_compressions(file: Path) -> set[str]:
    with open(file, "rb") as f:
        summary = make_reader(f).get_summary()
    assert summary is not None
    return {c.compression for c in summary.chunk_indexes}


def test_mcap_to_db3_and_back_keeps_messages_definitions_and_qos(
    mixed: Path, tmp_path: Path
) -> None:
    original = sorted(mcap_messages(_mcap_files(mixed)), key=key)
    db3 = tmp_path / "as_db3"
    _convert(mixed, "-o", db3, "--storage", "sqlite3")
    (database,) = db3.glob("*.db3")
    with sqlite3.connect(database) as db:
        counts = dict(
            db.execute(
                "SELECT t.name, COUNT(*) FROM messages m JOIN topics t ON t.id = m.topic_id "
                "GROUP BY t.name"
            )
        )
        definitions = dict(
            db.execute("SELECT topic_type, encoded_message_definition FROM message_definitions")
        )
        qos = dict(db.execute("SELECT name, offered_qos_profiles FROM topics"))
    expected_counts: dict[str, int] = {}
    for topic, _, _ in original:
        expected_counts[topic] = expected_counts.get(topic, 0) + 1
    assert counts == expected_counts
    schemas = _schemas(_mcap_files(mixed)[0])
    assert definitions == schemas
    assert all("transient_local" in text and "best_effort" in text for text in qos.values())
    assert sorted(rosbags_messages(db3), key=key) == original
    back = tmp_path / "back"
    _convert(db3, "-o", back)
    assert sorted(mcap_messages(_mcap_files(back)), key=key) == original
    assert _schemas(_mcap_files(back)[0]) == schemas
    with open(_mcap_files(back)[0], "rb") as f:
        summary = make_reader(f).get_summary()
    assert summary is not None
    for channel in summary.channels.values():
        assert "transient_local" in channel.metadata["offered_qos_profiles"]


def test_the_summary_line_agrees_count_and_noun(mixed: Path, tmp_path: Path) -> None:
    out = tmp_path / "one"
    result = run_here("convert", str(mixed), "-o", str(out))
    assert result.returncode == 0, result.stderr
    assert len(_mcap_files(out)) == 1
    count = len(mcap_messages(_mcap_files(out)))
    assert result.stdout.strip().startswith(f"wrote {out}: {count:,} messages ("), result.stdout
    assert ", 1 file, " in result.stdout, result.stdout


@pytest.mark.parametrize(("compression", "stored"), [("lz4", "lz4"), ("none", "")])
def test_recompression(mixed: Path, tmp_path: Path, compression: str, stored: str) -> None:
    out = tmp_path / "recompressed"
    _convert(mixed, "-o", out, "--compression", compression)
    assert {_chunk_compressions(f) == {stored} for f in _mcap_files(out)} == {True}
    expected = sorted(mcap_messages(_mcap_files(mixed)), key=key)
    assert sorted(mcap_messages(_mcap_files(out)), key=key) == expected


def test_ros1_to_mcap_decodes_as_ros2_in_the_mcap_reader(ros1: Path, tmp_path: Path) -> None:
    out = tmp_path / "ros2"
    report = _convert(ros1, "-o", out)
    assert report["problems"] == []
    (file,) = _mcap_files(out)
    decoded: dict[str, list[tuple[int, Any]]] = {}
    with open(file, "rb") as f:
        reader = make_reader(f, decoder_factories=[DecoderFactory()])
        summary = reader.get_summary()
        assert summary is not None
        types = {c.topic: summary.schemas[c.schema_id].name for c in summary.channels.values()}
        status_qos = next(
            c.metadata["offered_qos_profiles"]
            for c in summary.channels.values()
            if c.topic == "/status"
        )
        for _, channel, message, value in reader.iter_decoded_messages(log_time_order=True):
            decoded.setdefault(channel.topic, []).append((message.log_time, value))
    assert types == {
        "/imu": "sensor_msgs/msg/Imu",
        "/status": "std_msgs/msg/String",
        "/sample": SAMPLE,
    }
    assert "transient_local" in status_qos
    imu = ros1_messages(ros1, "/imu")
    assert [t for t, _ in decoded["/imu"]] == [t for t, _ in imu]
    for (_, ros2), (_, ros1_msg) in zip(decoded["/imu"], imu, strict=True):
        assert ros2.header.stamp.sec == ros1_msg.header.stamp.sec
        assert ros2.linear_acceleration.z == ros1_msg.linear_acceleration.z
    for (_, ros2), (_, ros1_msg) in zip(
        decoded["/sample"], ros1_messages(ros1, "/sample"), strict=True
    ):
        assert ros2.exposure.sec == ros1_msg.exposure.sec
        assert list(ros2.labels) == ros1_msg.labels
        assert bytes(ros2.blob) == ros1_msg.blob.tobytes()
    jazzy = get_typestore(Stores.ROS2_JAZZY)
    with AnyReader([out]) as reader:
        (imu_connection,) = [c for c in reader.connections if c.topic == "/imu"]
        assert imu_connection.digest == jazzy.hash_rihs01("sensor_msgs/msg/Imu")
        assert sum(1 for _ in reader.messages()) == sum(len(v) for v in decoded.values())


def test_ros1_and_mcap_merged_into_sqlite3_with_zstd(
    mixed: Path, ros1: Path, tmp_path: Path
) -> None:
    out = tmp_path / "merged"
    report = _convert(ros1, mixed, "-o", out, "--storage", "sqlite3", "--compression", "zstd")
    metadata = yaml.safe_load((out / "metadata.yaml").read_text())["rosbag2_bagfile_information"]
    assert (metadata["compression_format"], metadata["compression_mode"]) == ("zstd", "message")
    with AnyReader([out]) as reader:
        times = [t for _, t, _ in reader.messages()]
        topics = {c.topic for c in reader.connections}
    assert topics == {"/imu", "/status", "/sample", "/imu/data", "/text", "/temperature"}
    assert times == sorted(times)
    assert len(times) == report["message_count"] == 400 + 8 + 40 + len(rosbags_messages(mixed))


def test_selection_is_filters(mixed: Path, tmp_path: Path) -> None:
    selection = ["--topics", "/imu/data", "/text", "--start", "2", "--end", "9"]
    _convert(mixed, "-o", tmp_path / "converted", "--storage", "sqlite3", *selection)
    result = run_here("filter", str(mixed), "-o", str(tmp_path / "filtered"), *selection)
    assert result.returncode == 0, result.stderr
    converted = rosbags_messages(tmp_path / "converted")
    assert converted and converted == rosbags_messages(tmp_path / "filtered")
    where = ["--topics", "/imu/data", "--where", "linear_acceleration.x > 0.5"]
    _convert(mixed, "-o", tmp_path / "where_db3", "--storage", "sqlite3", *where)
    result = run_here("filter", str(mixed), "-o", str(tmp_path / "where_mcap"), *where)
    assert result.returncode == 0, result.stderr
    kept = rosbags_messages(tmp_path / "where_db3")
    assert 0 < len(kept) < 1500
    assert kept == rosbags_messages(tmp_path / "where_mcap")


def test_db3_into_mcap_selection_is_filters(mixed: Path, tmp_path: Path) -> None:
    """A db3 into MCAP goes by the rows' chunks: the same messages as ``filter`` of the MCAP
    bag that the db3 was converted from, with topic, window and ``--where``."""
    db3 = tmp_path / "db3"
    _convert(mixed, "-o", db3, "--storage", "sqlite3")
    selection = ["--topics", "/imu/data", "/text", "--start", "2", "--end", "9"]
    selection += ["--where", "linear_acceleration.x > 0.5"]
    _convert(db3, "-o", tmp_path / "converted", *selection)
    result = run_here("filter", str(mixed), "-o", str(tmp_path / "filtered"), *selection)
    assert result.returncode == 0, result.stderr
    converted = mcap_messages(_mcap_files(tmp_path / "converted"))
    expected = mcap_messages(_mcap_files(tmp_path / "filtered"))
    assert {m[0] for m in converted} == {"/imu/data", "/text"}
    assert sorted(converted, key=key) == sorted(expected, key=key)
    assert [m[1] for m in converted] == sorted(m[1] for m in converted)


def test_ros2_bag_convert_options_file(mixed: Path, tmp_path: Path) -> None:
    options = tmp_path / "out.yaml"
    options.write_text(
        yaml.safe_dump(
            {
                "output_bags": [
                    {
                        "uri": str(tmp_path / "imu_only"),
                        "storage_id": "mcap",
                        "topics": ["/imu/data"],
                    },
                    {
                        "uri": str(tmp_path / "rest"),
                        "storage_id": "sqlite3",
                        "all_topics": True,
                        "exclude_topics": ["/imu/data"],
                        "compression_mode": "file",
                        "compression_format": "zstd",
                        "max_bagfile_size": 0,
                        "include_hidden_topics": False,
                    },
                ]
            }
        )
    )
    result = run("convert", str(mixed), "--output-options", str(options))
    assert result.returncode == 0, result.stderr
    everything = rosbags_messages(mixed)
    assert rosbags_messages(tmp_path / "imu_only") == [m for m in everything if m[0] == "/imu/data"]
    assert list((tmp_path / "rest").glob("*.db3.zstd"))
    assert rosbags_messages(tmp_path / "rest") == [m for m in everything if m[0] != "/imu/data"]


@pytest.mark.parametrize(
    ("args", "says"),
    [
        (["--storage", "sqlite3", "--compression", "lz4"], "--compression lz4: rosbag2 "),
        (["--storage", "rosbag1"], "mcap or sqlite3"),
        (["--output-options", "OPTIONS"], "topic_types"),
        (["--topics", "/nope"], "/nope"),
    ],
)
def test_bad_requests_are_one_error_line(
    mixed: Path, tmp_path: Path, args: list[str], says: str
) -> None:
    options = tmp_path / "options.yaml"
    options.write_text(yaml.safe_dump({"output_bags": [{"uri": "x", "topic_types": ["a/msg/B"]}]}))
    args = [str(options) if a == "OPTIONS" else a for a in args]
    output = [] if "--output-options" in args else ["-o", str(tmp_path / "out")]
    result = run_here("convert", str(mixed), *output, *args)
    assert result.returncode == 2, result.stdout
    lines = result.stderr.strip().splitlines()
    assert len(lines) == 1 and lines[0].startswith("error:") and says in lines[0], result.stderr
    assert not (tmp_path / "out").exists()


@pytest.mark.parametrize("storage", ["mcap", "sqlite3", "rosbag1"])
@pytest.mark.parametrize("command", ["convert", "recover", "filter"])
def test_a_bag_without_topics_is_said_so(tmp_path: Path, storage: str, command: str) -> None:
    # Not "no topic is selected": the user selected nothing, the bag has nothing.
    from rosbags.rosbag1 import Writer as Ros1Writer
    from rosbags.rosbag2 import StoragePlugin, Writer

    bag = tmp_path / ("empty.bag" if storage == "rosbag1" else "empty")
    if storage == "rosbag1":
        with Ros1Writer(bag):
            pass
    else:
        with Writer(bag, version=9, storage_plugin=StoragePlugin[storage.upper()]):
            pass
    result = run_here(command, str(bag), "-o", str(tmp_path / "out"))
    assert result.returncode == 2, result.stdout
    lines = result.stderr.strip().splitlines()
    assert lines == [f"error: nothing to write: {bag} holds no topic"], result.stderr
    assert not (tmp_path / "out").exists()


@pytest.mark.parametrize("command", ["convert", "filter", "recover"])
@pytest.mark.parametrize("with_metadata", [True, False])
def test_message_compressed_mcap_is_written_decompressed(
    tmp_path: Path, command: str, with_metadata: bool
) -> None:
    # Its chunks hold zstd frames, not CDR: copied as stored, the output (which says it is
    # not compressed) would not decode.
    from rosbags.rosbag2 import CompressionFormat, CompressionMode, StoragePlugin, Writer

    store = get_typestore(Stores.ROS2_JAZZY)
    string = store.types["std_msgs/msg/String"]
    writer = Writer(tmp_path / "zipped", version=9, storage_plugin=StoragePlugin.MCAP)
    writer.set_compression(CompressionMode.MESSAGE, CompressionFormat.ZSTD)
    with writer:
        text = writer.add_connection("/text", "std_msgs/msg/String", typestore=store)
        for i in range(20):
            data = store.serialize_cdr(string(data=f"m{i}"), "std_msgs/msg/String")
            writer.write(text, 1_000 + i, bytes(data))
    if not with_metadata:
        (tmp_path / "zipped" / "metadata.yaml").unlink()
    result = run_here(command, str(tmp_path / "zipped"), "-o", str(tmp_path / "out"))
    assert result.returncode == 0, result.stderr
    with AnyReader([tmp_path / "out"], default_typestore=store) as reader:
        read = [reader.deserialize(d, c.msgtype).data for c, _, d in reader.messages()]
    assert read == [f"m{i}" for i in range(20)]


def test_a_stored_definition_naming_types_it_lacks_converts_without_a_type_hash(
    tmp_path: Path,
) -> None:
    """rosbag2's own test bags (talker.db3) store stub definitions that name types they do not
    define (``Parameter[] new_parameters``) and no topic hash: no RIHS01 can be computed. Both
    storages write the definition as stored, without a type hash (sqlite3 was refused)."""
    from rosbags.rosbag2 import Writer

    bag, stub = tmp_path / "stub", "Parameter[] new_parameters"
    payloads = [b"\x00\x01\x00\x00" + i.to_bytes(4, "little") for i in range(3)]
    with Writer(bag, version=9) as writer:
        events = writer.add_connection("/events", "pkg/msg/Event", msgdef=stub, rihs01="hash3")
        for i, data in enumerate(payloads):
            writer.write(events, 1_000 + i, data)
    (database,) = bag.glob("*.db3")
    with sqlite3.connect(database) as db:
        db.execute("UPDATE topics SET type_description_hash = ''")
    db.close()
    metadata = bag / "metadata.yaml"
    metadata.write_text(metadata.read_text().replace("hash3", "''"))
    _convert(bag, "-o", tmp_path / "as_db3", "--storage", "sqlite3")
    (written,) = (tmp_path / "as_db3").glob("*.db3")
    with sqlite3.connect(written) as db:
        definitions = list(db.execute("SELECT * FROM message_definitions"))
        hashes = list(db.execute("SELECT type_description_hash FROM topics"))
        stored = [bytes(d) for (d,) in db.execute("SELECT data FROM messages ORDER BY timestamp")]
    db.close()
    assert [row[1:] for row in definitions] == [("pkg/msg/Event", "ros2msg", stub, "")]
    assert hashes == [("",)]
    assert stored == payloads
    _convert(bag, "-o", tmp_path / "as_mcap")
    (file,) = _mcap_files(tmp_path / "as_mcap")
    assert _schemas(file) == {"pkg/msg/Event": stub}
    with open(file, "rb") as f:
        summary = make_reader(f).get_summary()
    assert summary is not None
    assert [set(c.metadata) for c in summary.channels.values()] == [{"offered_qos_profiles"}]


def test_split_by_duration_within_a_chunk(tmp_path: Path) -> None:
    """A bag whose messages fit in one chunk, rewritten (not copied as stored: another
    compression), is split by -d as ros2 bag splits it: no file spans the duration (found
    converting a small rosbags bag with -d 1: one file of 1.9 s)."""
    bag = tmp_path / "in"
    write_mixed_bag(bag, 300, compression="none", chunk_size=1 << 20)
    before = rosbags_messages(bag)
    span = max(t for _, t, _ in before) - min(t for _, t, _ in before)
    out = tmp_path / "out"
    result = run_here("convert", str(bag), "-o", str(out), "-d", str(span / 3e9))
    assert result.returncode == 0, result.stderr
    files = _mcap_files(out)
    assert len(files) >= 3
    for file in files:
        times = [t for _, t, _ in mcap_messages([file])]
        assert max(times) - min(times) < span / 3
    assert rosbags_messages(out) == before


@pytest.mark.parametrize("split", ["-d", "-b"])
def test_a_chunk_larger_than_the_split_is_opened(tmp_path: Path, split: str) -> None:
    """A chunk in OUT's compression that alone spans the duration (or outgrows the size) is
    opened and split, not copied as stored into one file (found converting a rosbags bag of
    one 20 s chunk with -d 7: one file of 20 s)."""
    bag = tmp_path / "in"
    write_mixed_bag(bag, 300, compression="none", chunk_size=1 << 20)
    before = rosbags_messages(bag)
    span = max(t for _, t, _ in before) - min(t for _, t, _ in before)
    limit = str(span / 3e9) if split == "-d" else "20KiB"
    out = tmp_path / "out"
    result = run("convert", str(bag), "-o", str(out), "--compression", "none", split, limit)
    assert result.returncode == 0, result.stderr
    files = _mcap_files(out)
    assert len(files) >= 3
    for file in files:
        times = [t for _, t, _ in mcap_messages([file])]
        if split == "-d":
            assert max(times) - min(times) < span / 3
        else:
            assert file.stat().st_size < (20 << 10) + (20 << 10)  # within a chunk, as ros2 bag
    assert rosbags_messages(out) == before


@pytest.mark.parametrize("source", ["mcap", "sqlite3"])
def test_custom_data_is_kept_into_each_storage(tmp_path: Path, source: str) -> None:
    """metadata.yaml's custom_data of a bag rosbags wrote, in both outputs' metadata.yaml and
    in the MCAP output's rosbag2 record."""
    from rosbags.rosbag2 import StoragePlugin, Writer

    jazzy = get_typestore(Stores.ROS2_JAZZY)
    bag = tmp_path / "in"
    writer = Writer(bag, version=9, storage_plugin=StoragePlugin[source.upper()])
    writer.set_custom_data("site", "lab-3")
    with writer:
        text = writer.add_connection("/s", "std_msgs/msg/String", typestore=jazzy)
        message = jazzy.types["std_msgs/msg/String"]("hi")
        writer.write(text, 10**9, jazzy.serialize_cdr(message, "std_msgs/msg/String"))
    for storage in ("mcap", "sqlite3"):
        out = tmp_path / storage
        _convert(bag, "-o", out, "--storage", storage)
        metadata = yaml.safe_load((out / "metadata.yaml").read_text())
        assert metadata["rosbag2_bagfile_information"]["custom_data"] == {"site": "lab-3"}
    (file,) = _mcap_files(tmp_path / "mcap")
    with open(file, "rb") as f:
        (record,) = make_reader(f).iter_metadata()
    assert yaml.safe_load(record.metadata["serialized_metadata"])["custom_data"] == {
        "site": "lab-3"
    }


def test_a_where_over_time_into_sqlite3(tmp_path: Path) -> None:
    """``--where 'TOPIC: gap > ...'`` (a condition over time) into a SQLite3 bag, written
    message by message: the two messages around each silence (it was an internal error)."""
    bag = tmp_path / "in"
    write_mixed_bag(bag, 300, step_ns=10_000_000)
    before = [m for m in rosbags_messages(bag) if m[0] == "/temperature"]  # one every 0.5 s
    out = tmp_path / "out"
    when = "/temperature: gap > 400ms"
    result = run("convert", str(bag), "-o", str(out), "--storage", "sqlite3", "--where", when)
    assert result.returncode == 0, result.stderr
    got = [m for m in rosbags_messages(out) if m[0] == "/temperature"]
    assert got == before
