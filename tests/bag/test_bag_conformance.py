"""The conformance corpus: small bags written by rosbags' writers (rosbag2 MCAP and SQLite3,
zstd file and message compression of both, a Humble SQLite3 bag without stored definitions,
a ROS 1 bag), each run through every offline read command and ``convert``, with the values
compared with rosbags' own reading of the same bag. Writers rosbags does not have (mcap_ros2,
``mcap``'s writer, ros2idl and ``ACTION:`` texts) are in test_bag_other_writers.py; ``play``
of these bags needs DDS (tests/ros)."""

from __future__ import annotations

import json
import sqlite3
from pathlib import Path
from typing import Any

import numpy as np
import pandas as pd
import pytest
from bagkit_runs import bagkit_in_process
from rosbags.highlevel import AnyReader
from rosbags.rosbag1 import Writer as Ros1Writer
from rosbags.rosbag2 import StoragePlugin, Writer
from rosbags.rosbag2.enums import CompressionFormat, CompressionMode
from rosbags.typesys import Stores, get_typestore

from bagkit import read_dataframe

IMU = "sensor_msgs/msg/Imu"
TEMPERATURE = "sensor_msgs/msg/Temperature"
COUNT = 24  # /imu at 10 Hz; /temp every other /imu message
STORES = {
    "jazzy": get_typestore(Stores.ROS2_JAZZY),
    "humble": get_typestore(Stores.ROS2_HUMBLE),
    "ros1": get_typestore(Stores.ROS1_NOETIC),
}
# name: (storage, compression mode, type store)
CORPUS = {
    "rosbags-mcap": (StoragePlugin.MCAP, None, "jazzy"),
    "rosbags-db3": (StoragePlugin.SQLITE3, None, "jazzy"),
    "mcap-zstd-file": (StoragePlugin.MCAP, CompressionMode.FILE, "jazzy"),
    "mcap-zstd-message": (StoragePlugin.MCAP, CompressionMode.MESSAGE, "jazzy"),
    "db3-zstd-file": (StoragePlugin.SQLITE3, CompressionMode.FILE, "jazzy"),
    "db3-zstd-message": (StoragePlugin.SQLITE3, CompressionMode.MESSAGE, "jazzy"),
    "db3-humble-no-definitions": (StoragePlugin.SQLITE3, None, "humble"),
    "ros1.bag": (None, None, "ros1"),
}


def _messages(store: str, i: int) -> tuple[Any, Any]:
    types = STORES[store].types
    stamp = types["builtin_interfaces/msg/Time"](i, 5)
    # ROS 1 headers carry a sequence number first.
    header = types["std_msgs/msg/Header"](*((i,) if store == "ros1" else ()), stamp, "f")
    covariance = np.arange(9, dtype=np.float64) * i
    vector = types["geometry_msgs/msg/Vector3"]
    imu = types[IMU](
        header,
        types["geometry_msgs/msg/Quaternion"](0.0, 0.0, 0.0, 1.0),
        covariance,
        vector(0.1 * i, 0.0, 0.0),
        covariance,
        vector(1.0, 2.0, 9.81 + 0.25 * i),
        covariance,
    )
    return imu, types[TEMPERATURE](header, 20.0 + i, 0.0)


def _write(path: Path, storage: StoragePlugin | None, mode: Any, store: str) -> None:
    typestore = STORES[store]
    serialize = typestore.serialize_ros1 if storage is None else typestore.serialize_cdr
    writer: Any = (
        Ros1Writer(path) if storage is None else Writer(path, version=9, storage_plugin=storage)
    )
    if mode is not None:
        writer.set_compression(mode, CompressionFormat.ZSTD)
    with writer:
        imu = writer.add_connection("/imu", IMU, typestore=typestore)
        temp = writer.add_connection("/temp", TEMPERATURE, typestore=typestore)
        for i in range(COUNT):
            imu_msg, temp_msg = _messages(store, i)
            writer.write(imu, (i + 1) * 10**8, serialize(imu_msg, IMU))
            if i % 2 == 0:
                writer.write(temp, (i + 1) * 10**8 + 1, serialize(temp_msg, TEMPERATURE))
    if store == "humble":  # as Foxy to Humble record: no definitions, the distro named
        (db3,) = path.glob("*.db3")
        with sqlite3.connect(db3) as db:
            db.execute("DELETE FROM message_definitions")
        metadata = path / "metadata.yaml"
        text = metadata.read_text()
        metadata.write_text(text.replace("ros_distro: rosbags", "ros_distro: humble"))


@pytest.fixture(scope="module")
def corpus(tmp_path_factory: pytest.TempPathFactory) -> Path:
    root = tmp_path_factory.mktemp("corpus")
    for name, (storage, mode, store) in CORPUS.items():
        _write(root / name, storage, mode, store)
    return root


def rosbags_values(bag: Path, store: str) -> list[tuple[str, int, float]]:
    """(topic, log time, linear_acceleration.z or temperature) as rosbags reads the bag."""
    values = []
    with AnyReader([bag], default_typestore=STORES[store]) as reader:
        for connection, log_time, raw in reader.messages():
            message = reader.deserialize(raw, connection.msgtype)
            value = (
                message.linear_acceleration.z if connection.topic == "/imu" else message.temperature
            )
            values.append((connection.topic, log_time, value))
    return values


def ok(*args: str | Path) -> str:
    done = bagkit_in_process(list(args))
    assert done.returncode == 0, (args, done.stderr)
    assert "Traceback" not in done.stderr
    return done.stdout


def imu_values(bag: Path) -> list[tuple[int, float]]:
    lines = ok("echo", bag, "/imu", "--format", "json").splitlines()
    records = [json.loads(line) for line in lines if line]
    return [(r["log_time"], r["data"]["linear_acceleration"]["z"]) for r in records]


@pytest.mark.parametrize("name", list(CORPUS))
def test_every_command_on_every_bag(corpus: Path, tmp_path: Path, name: str) -> None:
    bag = corpus / name
    store = CORPUS[name][2]
    expected = rosbags_values(bag, store)
    imu = [(t, z) for topic, t, z in expected if topic == "/imu"]
    zs = np.array([z for _, z in imu])
    counts = {"/imu": COUNT, "/temp": COUNT // 2}

    info = json.loads(ok("info", bag, "--format", "json"))
    assert {t["topic"]: t["count"] for t in info["topics"]} == counts
    assert (info["start_ns"], info["end_ns"]) == (expected[0][1], expected[-1][1])
    assert "salvaged" not in ok("info", "-v", bag)
    assert imu_values(bag) == imu

    stats = json.loads(ok("stats", "summary", bag, "-t", "/imu", "--format", "json"))
    fields = {f["field"]: f for f in stats["topics"][0]["fields"]}
    assert fields["linear_acceleration.z"]["count"] == COUNT
    assert fields["linear_acceleration.z"]["mean"] == pytest.approx(zs.mean())

    table = tmp_path / "imu.parquet"
    ok("export", bag, "-t", "/imu", "-o", table)
    assert pd.read_parquet(table)["linear_acceleration.z"].tolist() == zs.tolist()
    frame = read_dataframe(bag, "/imu")
    assert frame["linear_acceleration.z"].tolist() == zs.tolist()
    assert frame.index.asi8.tolist() == [t for t, _ in imu]

    plot = tmp_path / "plot.png"
    ok("plot", bag, "/imu:linear_acceleration.z", "-o", plot)
    assert plot.read_bytes()[:4] == b"\x89PNG"
    threshold = float(np.median(zs))
    found = json.loads(
        ok("find", bag, "--when", f"/imu: linear_acceleration.z > {threshold}", "--format", "json")
    )
    assert sum(e["count"] for e in found) == int((zs > threshold).sum())

    filtered = tmp_path / "filtered"
    ok("filter", bag, "-o", filtered, "--topics", "/imu")
    assert imu_values(filtered) == imu
    merged = tmp_path / "merged"
    ok("merge", bag, filtered, "-o", merged)
    assert sorted(imu_values(merged)) == sorted(imu * 2)
    recovered = tmp_path / "recovered"
    ok("recover", bag, "-o", recovered)
    assert imu_values(recovered) == imu
    assert "healthy" in ok("doctor", "--deep", bag)
    ok("compare", bag, recovered)

    # convert to each storage; rosbags reads the output (stored definitions, not a type store).
    for storage in ("mcap", "sqlite3"):
        converted = tmp_path / f"converted-{storage}"
        ok("convert", bag, "-o", converted, "--storage", storage)
        assert rosbags_values(converted, "jazzy") == expected
        ok("doctor", converted)


def test_catalog_and_find_over_the_corpus(corpus: Path, tmp_path: Path) -> None:
    catalog = tmp_path / "catalog.parquet"
    ok("catalog", corpus, "-o", catalog)
    rows = pd.read_parquet(catalog)
    counts = {
        (Path(p).name, t): c
        for p, t, c in zip(rows["path"], rows["topic"], rows["count"], strict=True)
    }
    assert counts == {
        (name, topic): count
        for name in CORPUS
        for topic, count in (("/imu", COUNT), ("/temp", COUNT // 2))
    }
    bags = [corpus / name for name in CORPUS]
    found = json.loads(ok("find", *bags, "--when", "/temp: temperature >= 40", "--format", "json"))
    # temperature = 20 + i for even i < COUNT: i in 20, 22
    assert {Path(e["bag"]).name: e["count"] for e in found} == dict.fromkeys(CORPUS, 2)
